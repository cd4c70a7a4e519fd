"""Benchmark: 2-D patch extraction and the noise estimate, cssat against its peers.

1. **Patches** of a 128 × 128 float32 image, 8 × 8, at steps 1 and 2 (the sparse-KSVD denoiser's
   training and coding blocks): cssat's ``extract_patches`` (``Tensor.unfold``, a strided view), the
   flat-index gather it used before (kept for 3-D cubes), and scikit-learn's
   ``extract_patches_2d`` (step 1 only). Every method must give the same array (checked).
2. **Noise estimate** σ̂ of white noise (σ = 0.1) on the camera image at 128²: cssat's Haar MAD
   estimate (:func:`cssat.sparse.estimate_sigma`) against scikit-image's ``estimate_sigma``
   (Daubechies-2 MAD): time, and each estimate's error.

Times are medians of ``--repeats`` runs (µs). Run from the repository root::

    python benchmarks/patches.py --threads 2 --repeats 200
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from _timing import median_time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=200)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from skimage import data
    from skimage.restoration import estimate_sigma as sk_sigma
    from skimage.transform import resize
    from sklearn.feature_extraction.image import extract_patches_2d

    from cssat.sparse import estimate_sigma, extract_patches
    from cssat.sparse.patches import _index

    img = resize(data.camera() / 255.0, (128, 128), anti_aliasing=True).astype(np.float32)
    x = torch.from_numpy(img)
    print(f"patches of a 128² float32 image, 8×8 (median of {args.repeats}, µs)")
    print(f"{'step':>4} {'unfold (cssat)':>15} {'index gather':>13} {'sklearn':>9} {'gather/unfold':>14}")
    for step in (1, 2):
        t_new, _, a = median_time(lambda: extract_patches(x, 8, step), args.repeats)
        idx = _index((128, 128), 8, step, x.device)
        t_old, _, b = median_time(lambda: x.reshape(-1)[_index((128, 128), 8, step, x.device)], args.repeats)
        assert torch.equal(a, b), "unfold and the index gather differ"
        sk = "—"
        if step == 1:
            t_sk, _, c = median_time(lambda: extract_patches_2d(img, (8, 8)), max(10, args.repeats // 10))
            assert np.array_equal(c.reshape(len(c), -1), a.numpy()), "scikit-learn's patches differ"
            sk = f"{t_sk * 1e6:9.0f}"
        del idx
        print(f"{step:>4} {t_new * 1e6:15.0f} {t_old * 1e6:13.0f} {sk:>9} {t_old / t_new:14.2f}")

    rng = np.random.default_rng(0)
    noisy = img.astype(np.float64) + 0.1 * rng.standard_normal(img.shape)
    t_c, _, s_c = median_time(lambda: estimate_sigma(noisy), args.repeats)
    t_s, _, s_s = median_time(lambda: sk_sigma(noisy), args.repeats)
    print(f"\nnoise estimate, σ = 0.1 (median of {args.repeats}, µs): cssat Haar {t_c * 1e6:.0f} "
          f"(σ̂ {s_c:.5f}), scikit-image db2 {t_s * 1e6:.0f} (σ̂ {s_s:.5f}); ratio {t_s / t_c:.2f}")


if __name__ == "__main__":
    main()
