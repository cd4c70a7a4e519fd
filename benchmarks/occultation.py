"""Benchmark: the Fresnel shadow of a satellite (issue 25, point 5).

1. **The ground shadow** of an ``N × N`` silhouette (default 256², the Astra-like model at 0.1 m,
   550 nm, GEO's range) at one wavelength: cssat's :func:`~cssat.occultation.shadow` (float64
   and float32) beside the same pixel-integrated kernel convolved by ``scipy.signal.fftconvolve``
   (complex128, ``mode="same"``) — the peer: same arithmetic, scipy's FFT. The two must agree
   (printed: the largest difference).
2. **A reconstruction** at the experiment's default (0.1 m pixels, 256², V = 8, 13 of 51
   telescopes of 0.5 m): the linear TV route, then the non-linear fit from it (``--recon``).

Times are medians of ``--repeats`` runs. Run from the repository root::

    python benchmarks/occultation.py --threads 2 --repeats 5 [--recon]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from _timing import median_time


def _silhouette(n: int, pixel: float) -> np.ndarray:
    from cssat.occultation import silhouette
    from cssat.scene import get_model

    return silhouette(get_model("astra_like", array_angle_deg=90.0), [0.3, 0.2, 0.93], pixel, n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--recon", action="store_true", help="also time a reconstruction (the experiment's default)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from scipy.signal import fftconvolve
    from threadpoolctl import threadpool_limits

    from cssat.occultation import shadow
    from cssat.occultation.fresnel import pixel_kernel

    n, pixel, lam, z = args.size, 0.1, 550e-9, 3.5786e7
    mask = _silhouette(n, pixel)
    m64 = torch.tensor(mask)
    m32 = m64.float()
    shadow(m64, pixel, lam, z)  # warm up (FFT plans)
    t64, _, I64 = median_time(lambda: shadow(m64, pixel, lam, z), args.repeats)
    t32, _, I32 = median_time(lambda: shadow(m32, pixel, lam, z), args.repeats)

    def scipy_shadow():
        k = pixel_kernel(n, pixel, lam, z)
        K = np.outer(k, k) / 2j
        with threadpool_limits(args.threads):
            f = fftconvolve(mask.astype(np.complex128), K, mode="full")[n - 1:2 * n - 1, n - 1:2 * n - 1]
        return np.abs(1 - f) ** 2

    ts, _, Is = median_time(scipy_shadow, args.repeats)
    print(f"shadow {n}x{n}, one wavelength, {args.threads} threads, median of {args.repeats}:")
    print(f"  cssat float64   {t64:.4f} s   (scipy fftconvolve {ts:.4f} s: ratio {ts / t64:.2f}x)")
    print(f"  cssat float32   {t32:.4f} s   ({ts / t32:.2f}x)")
    print(f"  max |cssat - scipy| = {float(np.abs(I64.numpy() - Is).max()):.2e} (float64), "
          f"{float(np.abs(I32.numpy() - Is).max()):.2e} (float32)")
    if args.recon:
        from hydra import compose, initialize_config_module

        from cssat.experiments import run_experiment

        with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
            cfg = compose(config_name="config", overrides=["experiment=occultation", f"threads={args.threads}"])
        import tempfile

        with tempfile.TemporaryDirectory() as d:
            met = run_experiment(cfg, d)
        print(f"reconstruction (experiment=occultation): linear {met['seconds_invert_linear']:.1f} s + non-linear "
              f"{met['seconds_invert']:.1f} s; IoU {met['iou']:.3f} (linear alone {met['iou_linear']:.3f})")


if __name__ == "__main__":
    main()
