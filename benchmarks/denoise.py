"""Benchmark: sparse-KSVD denoising (cssat) against scikit-learn and scikit-image denoisers.

1. **2-D**, 128 × 128 images on a 0–255 scale with white Gaussian noise σ = 10, 20, 30: scikit-image
   test images (camera, moon, astronaut in gray) and rendered satellites (the procedural TESS-like
   model; the Astra-like model; NASA's TESS mesh if ``../shared/models/tess.obj`` exists). Methods,
   all given the true σ unless said otherwise:

   * ``cssat sparse-KSVD``: :func:`cssat.sparse.ksvd_denoise`, KSVDSBox's demo defaults;
   * ``cssat sparse-KSVD σ̂``: the same with σ estimated from the noisy image;
   * ``sklearn DL``: scikit-learn's dictionary-learning denoising — ``MiniBatchDictionaryLearning``
     (100 atoms, 8 × 8 mean-removed patches, 10 epochs) and, for a like-for-like comparison of the
     dictionaries, the same coding rule as cssat: ``orthogonal_mp_gram`` to the error
     ``√p · 1.15 σ`` with at most p/2 atoms, patches averaged back;
   * scikit-image ``wavelet`` (BayesShrink, soft), ``TV`` (Chambolle, weight = σ), ``NLM``
     (5 × 5 patches, 13 × 13 window, h = 0.8 σ, fast mode).

2. **3-D**: a stack of 9 copies of one 64 × 64 image with different noise levels (σ = 10 … 30):
   3-D sparse-KSVD of the stack against 2-D sparse-KSVD of each slice.

PSNR in dB against the clean image (data range 255); times are medians of ``--repeats`` runs.

Run from the repository root::

    python benchmarks/denoise.py --threads 2 --repeats 3
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np
import torch
from _timing import median_time

SHARED_TESS = Path(__file__).resolve().parents[1].parent / "shared" / "models" / "tess.obj"


def psnr(x, ref):
    return float(10 * np.log10(255.0**2 / np.mean((np.asarray(x, float) - ref) ** 2)))


def test_images(size):
    from cssat.data import load_target
    from cssat.data.images import render_exposed
    from cssat.scene import get_model, load_mesh

    imgs = {name: 255 * load_target(name, size) for name in ("camera", "moon", "astronaut", "tess")}
    imgs["tess (render)"] = imgs.pop("tess")
    imgs["astra (render)"] = 255 * render_exposed(get_model("astra_like"), size)
    if SHARED_TESS.exists():
        imgs["TESS mesh (render)"] = 255 * render_exposed(load_mesh(str(SHARED_TESS)), size)
    return imgs


def sklearn_dl(noisy, sigma, seed=0):
    from sklearn.decomposition import MiniBatchDictionaryLearning
    from sklearn.linear_model import orthogonal_mp_gram

    from cssat.sparse import extract_patches, fold_patches

    x = torch.as_tensor(noisy)
    P = extract_patches(x, 8, 1).numpy()
    dc = P.mean(1, keepdims=True)
    P = P - dc
    dl = MiniBatchDictionaryLearning(n_components=100, alpha=1.0, batch_size=256, max_iter=10, random_state=seed)
    D = dl.fit(P / max(P.std(), 1e-12)).components_.T  # (64, 100), unit-norm atoms
    tol = 64 * (1.15 * sigma) ** 2
    codes = orthogonal_mp_gram(D.T @ D, D.T @ P.T, n_nonzero_coefs=32, tol=tol, norms_squared=(P * P).sum(1))
    clean = (D @ codes).T + dc
    return fold_patches(torch.as_tensor(clean), x.shape, 8, 1).numpy()


def methods():
    from skimage.restoration import denoise_nl_means, denoise_tv_chambolle, denoise_wavelet

    from cssat.sparse import ksvd_denoise

    return {
        "cssat sparse-KSVD": lambda y, s: ksvd_denoise(torch.as_tensor(y, dtype=torch.float32), s).double().numpy(),
        "cssat sparse-KSVD σ̂": lambda y, s: ksvd_denoise(torch.as_tensor(y, dtype=torch.float32)).double().numpy(),
        "sklearn DL": sklearn_dl,
        "wavelet": lambda y, s: 255 * denoise_wavelet(y / 255, sigma=s / 255, method="BayesShrink", mode="soft", rescale_sigma=True),
        "TV": lambda y, s: 255 * denoise_tv_chambolle(y / 255, weight=s / 255),
        "NLM": lambda y, s: 255 * denoise_nl_means(y / 255, h=0.8 * s / 255, sigma=s / 255, fast_mode=True, patch_size=5, patch_distance=6),
    }


def bench_2d(size, sigmas, repeats, rng):
    imgs = test_images(size)
    meth = methods()
    # warm-up (numba compilation, caches) outside the timings
    ksvd_warm = next(iter(imgs.values()))
    meth["cssat sparse-KSVD"](ksvd_warm + rng.normal(0, 20, ksvd_warm.shape), 20.0)
    rows, times = [], {k: [] for k in meth}
    for name, img in imgs.items():
        for s in sigmas:
            noisy = img + rng.normal(0, s, img.shape)
            row = {"image": name, "σ": s, "noisy": psnr(img, noisy)}
            for mname, fn in meth.items():
                t, _, out = median_time(lambda: fn(noisy, float(s)), repeats)
                row[mname] = psnr(img, out)
                times[mname].append(t)
            rows.append(row)
            print(f"{name:20s} σ={s:2d} " + " ".join(f"{k}={v:.2f}" for k, v in row.items() if k not in ("image", "σ")), flush=True)
    return rows, {k: statistics.median(v) for k, v in times.items()}


def bench_3d(size, repeats, rng):
    from cssat.data import load_target
    from cssat.sparse import ksvd_denoise

    sig = np.linspace(10, 30, 9)
    out = []
    for name in ("camera", "tess"):
        img = 255 * load_target(name, size)
        stack = np.stack([img + rng.normal(0, s, img.shape) for s in sig]).astype(np.float32)
        t3, _, d3 = median_time(lambda: ksvd_denoise(torch.as_tensor(stack)).numpy(), repeats)
        t2s, p2 = [], []
        for k in range(9):
            t2, _, d2 = median_time(lambda: ksvd_denoise(torch.as_tensor(stack[k])).numpy(), repeats)
            t2s.append(t2)
            p2.append(psnr(img, d2))
        p3 = [psnr(img, d3[k]) for k in range(9)]
        pn = [psnr(img, stack[k]) for k in range(9)]
        out.append((name, sig, pn, p2, p3, t3, sum(t2s)))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--skip-2d", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)

    if not args.skip_2d:
        rows, times = bench_2d(args.size, (10, 20, 30), args.repeats, rng)
        names = [k for k in rows[0] if k not in ("image", "σ")]
        print(f"\n### 2-D, {args.size}×{args.size}, PSNR (dB)\n")
        print("| image | σ | " + " | ".join(names) + " |")
        print("|---|---:|" + "---:|" * len(names))
        for r in rows:
            best = max(r[k] for k in names if k != "noisy")
            cells = [f"**{r[k]:.2f}**" if r[k] == best else f"{r[k]:.2f}" for k in names]
            print(f"| {r['image']} | {r['σ']} | " + " | ".join(cells) + " |")
        means = {k: statistics.mean(r[k] for r in rows) for k in names}
        print("| **mean** | | " + " | ".join(f"{means[k]:.2f}" for k in names) + " |")
        print("\nmedian seconds per image: " + ", ".join(f"{k} {v:.3f} s" for k, v in times.items()))
        ref = times["cssat sparse-KSVD"]
        print("time ratio to cssat sparse-KSVD: " + ", ".join(f"{k} {v / ref:.3f}×" for k, v in times.items()))

    print("\n### 3-D: 9 copies, 64×64, σ = 10…30\n")
    for name, sig, pn, p2, p3, t3, t2 in bench_3d(64, args.repeats, rng):
        print(f"{name}: 3-D {t3:.1f} s for the stack; 2-D {t2:.1f} s for its 9 slices")
        print("| slice σ | noisy | 2-D | 3-D | 3-D − 2-D |")
        print("|---:|---:|---:|---:|---:|")
        for s, a, b, c in zip(sig, pn, p2, p3):
            print(f"| {s:.1f} | {a:.2f} | {b:.2f} | {c:.2f} | {c - b:+.2f} |")
        print(f"3-D beats 2-D on {sum(c > b for b, c in zip(p2, p3))}/9 slices\n")


if __name__ == "__main__":
    main()
