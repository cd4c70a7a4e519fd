"""Simulation 2 (paper Fig. 10–11): the full-rank reference-satellite approach.

The target (the rendered TESS-like model, ``n × n``) is measured as ``y = Φx`` with an unknown
Gaussian ``Φ (m, N)``. ``N = n²`` reference images of the Astra-like model under random Sun and
view directions, with white noise (``X_ref (N, N)``, images as columns), are measured through the
same ``Φ``: ``Y_ref = Φ X_ref`` (Eq. 22). ``Φ̂ = Y_ref X_ref⁻¹`` (Eq. 24, one LU solve); the image
is reconstructed by batch-OMP over ``Φ̂Ψ`` (Eq. 5/6) and denoised (2-D sparse K-SVD by default).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any


from cssat.experiments.common import (
    ConfigError,
    require_int,
    run_settings,
    save_figure,
    torch_dtype,
    write_npz,
)

log = logging.getLogger("cssat")


def peak_memory(n: int, m: int, itemsize: int, ref_itemsize: int) -> tuple[int, dict[str, int]]:
    """Estimated peak bytes of Simulation 2 at ``N = n²`` pixels and ``m`` measurements.

    In the reference stage (``ref_itemsize``) these live together: ``Φ`` (m N), ``Y_ref`` (m N),
    ``X_ref`` (N²) and its LU factor (N²), then ``Φ̂`` (m N) in place of ``X_ref``. In the
    reconstruction (``itemsize``): ``Φ̂Ψ`` (m N) and the OMP's Gram (N²).
    """
    N = n * n
    parts = {
        "Φ": m * N * ref_itemsize,
        "Y_ref": m * N * ref_itemsize,
        "X_ref": N * N * ref_itemsize,
        "LU": N * N * ref_itemsize,
    }
    at_lu = sum(parts.values()) + N * N * 4  # + the float32 renders while X_ref is built
    at_solve = 2 * m * N * ref_itemsize + N * N * ref_itemsize + m * N * ref_itemsize
    later = m * N * ref_itemsize + m * N * itemsize + N * N * itemsize
    return int(max(at_lu, at_solve, later) * 1.2), parts


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    import torch

    from cssat.data import load_target
    from cssat.experiments.denoisers import apply_denoiser, scores
    from cssat.experiments.refsets import check_memory, peak_rss_bytes, reference_set
    from cssat.experiments.sim1 import check_solver, reconstruct
    from cssat.reference import estimate_sensing_full_rank, relative_error
    from cssat.sparse import GaussianSensing

    dtype, device, seed, n, N, m = run_settings(cfg, max_size=1024)
    n_ref = cfg.reference.get("n")
    n_ref = N if n_ref is None else require_int(n_ref, "reference.n", N, N)
    ref_seed = cfg.reference.get("seed")
    ref_seed = seed + 1000 if ref_seed is None else require_int(ref_seed, "reference.seed", 0)
    check_solver(cfg.solver, m, N)
    ref_dtype = torch_dtype(cfg.reference.get("dtype", "float64"), field="reference.dtype")
    itemsize = torch.finfo(dtype).bits // 8
    est, parts = peak_memory(n, m, itemsize, torch.finfo(ref_dtype).bits // 8)
    check_memory(est, parts, cfg, "lower target.size or cs.m, or use dtype=float32 / reference.dtype=float32")
    x = load_target(str(cfg.target.image), n)
    timings: dict[str, float] = {}

    t = time.perf_counter()
    # Φ is drawn in float32 (the same Φ as Simulation 1's for this seed) and held exactly in
    # reference.dtype, in which Y_ref = Φ X_ref and the solve are computed
    phi = GaussianSensing(m, N, seed=seed, dtype=torch.float32, device=device).matrix().to(ref_dtype)
    y = (phi @ torch.as_tensor(x, dtype=ref_dtype, device=device).reshape(N)).to(dtype)
    timings["seconds_measure"] = time.perf_counter() - t

    t = time.perf_counter()
    refs, cached = reference_set(cfg, n, n_ref, ref_seed)  # (N, n, n) float32
    timings["seconds_references"] = time.perf_counter() - t
    t = time.perf_counter()
    Xt = refs.reshape(n_ref, N).to(dtype=ref_dtype, device=device)  # X_refᵀ: reference k is row k
    del refs
    Y_ref = phi @ Xt.T  # Eq. 22, (m, N)
    timings["seconds_reference_light_curves"] = time.perf_counter() - t

    t = time.perf_counter()
    try:
        phi_hat, rcond = estimate_sensing_full_rank(Xt.T, Y_ref, return_rcond=True)  # Eq. 24
    except ValueError as err:
        raise ConfigError(f"reference: {err}") from err
    del Xt, Y_ref
    timings["seconds_estimate"] = time.perf_counter() - t
    phi_err = relative_error(phi_hat, phi)
    del phi

    t = time.perf_counter()
    phi_hat = phi_hat.to(dtype)
    x_raw, gamma, solver_metrics, _ = reconstruct(cfg.solver, phi_hat, y, n, seed)  # Eq. 5/6, or l1/tv/pnp
    del phi_hat
    rec = x_raw.clamp(0.0, 1.0).double().cpu().numpy()
    timings["seconds_solver"] = time.perf_counter() - t

    den, den_metrics = apply_denoiser(cfg.get("denoiser"), rec, seed=seed, dtype=dtype, device=device, clip=(0.0, 1.0))
    timings["seconds_denoise"] = den_metrics.pop("seconds_denoise")

    metrics: dict[str, Any] = {
        **scores(rec, den, x),
        "phi_relative_error": phi_err,
        "x_ref_rcond": rcond,
        "reference_dtype": str(cfg.reference.get("dtype", "float64")),
        "m": m,
        "n": n,
        "n_pixels": N,
        "reference_n": n_ref,
        "reference_noise": float(cfg.reference.get("noise", 0.0)),
        "reference_cached": cached,
        **solver_metrics,
        "seed": seed,
        "dtype": str(cfg.get("dtype", "float32")),
        "device": str(device),
        "peak_memory_estimate_gb": est / 2**30,
        "peak_rss_gb": peak_rss_bytes() / 2**30,
        **den_metrics,
        **timings,
    }
    metrics["psnr_gain_denoised"] = metrics["psnr_denoised"] - metrics["psnr"]
    write_npz(out_dir / "arrays.npz", truth=x, y=y, reconstruction=rec, denoised=den,
              **({"coefficients": gamma} if gamma is not None else {}))
    _figure(x, rec, den, metrics, out_dir / "figures" / "fig11_sim2.png")
    log.info(
        "sim2: ‖Φ̂−Φ‖/‖Φ‖ = %.2e, PSNR %.2f dB, denoised %.2f dB (%+.2f), peak RSS %.1f GB",
        phi_err, metrics["psnr"], metrics["psnr_denoised"], metrics["psnr_gain_denoised"], metrics["peak_rss_gb"],
    )
    return metrics


def _figure(truth, rec, den, metrics, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(9.5, 3.6))
    panels = [
        (truth, f"truth ({metrics['n']}×{metrics['n']})"),
        (rec, f"reconstruction\nPSNR {metrics['psnr']:.2f} dB"),
        (den, f"denoised ({metrics['denoiser']})\nPSNR {metrics['psnr_denoised']:.2f} dB ({metrics['psnr_gain_denoised']:+.2f})"),
    ]
    for ax, (img, title) in zip(axes, panels):
        ax.imshow(img, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(
        f"Simulation 2: full-rank Φ̂ (N = {metrics['reference_n']}, ‖Φ̂−Φ‖/‖Φ‖ = {metrics['phi_relative_error']:.1e}), "
        f"m = {metrics['m']}, solver {metrics['solver']}"
        + (f", K = {metrics['solver_n_nonzero_coefs']}" if metrics["solver"] == "omp" else ""),
        fontsize=9,
    )
    save_figure(fig, path)
