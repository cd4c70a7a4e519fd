"""Solver comparison (``cssat experiment=solvers``): every reconstruction solver on Simulation 1's
target at several m, side by side with the paper's OMP + sparse-KSVD.

For each m one Gaussian Φ (seed) and one light curve ``y = Φx``; each entry of
``comparison.solvers`` reconstructs from them (a ``solver`` config, plus ``denoise: true`` to
post-process with the ``denoiser`` group). Writes ``comparison.csv`` (one row per m and solver:
PSNR, SSIM, seconds), flat metrics ``psnr_<solver>_m<m>``, the images in ``arrays.npz`` and a
figure: rows = m, columns = solvers, PSNR in each panel.
"""

from __future__ import annotations

import csv
import logging
import time
from pathlib import Path
from typing import Any


from cssat.experiments.common import (
    ConfigError,
    _atomic,
    require_int,
    run_settings,
    save_figure,
    write_npz,
)

log = logging.getLogger("cssat")


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    import torch

    from cssat.data import load_target
    from cssat.experiments.denoisers import apply_denoiser
    from cssat.experiments.sim1 import reconstruct
    from cssat.metrics import psnr, ssim
    from cssat.sparse import GaussianSensing

    dtype, device, seed, n, N, _ = run_settings(cfg, max_size=4096)
    ms = [require_int(v, "comparison.m", 1, N) for v in cfg.comparison.m]
    solvers = dict(cfg.comparison.solvers)
    if not ms or not solvers:
        raise ConfigError("comparison: needs at least one m and one solver")
    x = load_target(str(cfg.target.image), n)
    rows, images, metrics = [], {}, {"n": n, "n_pixels": N, "m_values": ms, "solvers": list(solvers)}
    for m in ms:
        phi = GaussianSensing(m, N, seed=seed, dtype=dtype, device=device)
        y = phi(torch.as_tensor(x, dtype=dtype, device=device).reshape(N))
        for label, scfg in solvers.items():
            t = time.perf_counter()
            x_raw, _, smet, _ = reconstruct(scfg, phi, y, n, seed)
            rec = x_raw.clamp(0, 1).double().cpu().numpy()
            if scfg.get("denoise", False):
                rec, _ = apply_denoiser(cfg.get("denoiser"), rec, seed=seed, dtype=dtype, device=device, clip=(0.0, 1.0))
            sec = time.perf_counter() - t
            row = {"m": m, "m_over_N": m / N, "solver": label, "psnr": psnr(rec, x, data_range=1.0),
                   "ssim": ssim(rec, x, data_range=1.0), "seconds": sec,
                   "iterations": smet.get("solver_iterations", smet.get("omp_atoms"))}
            rows.append(row)
            images[f"{label}_m{m}"] = rec
            metrics[f"psnr_{label}_m{m}"] = row["psnr"]
            metrics[f"seconds_{label}_m{m}"] = sec
            log.info("solvers: m=%d %-10s PSNR %.2f dB, SSIM %.3f, %.1f s", m, label, row["psnr"], row["ssim"], sec)
        del phi
    for m in ms:
        best = max((r for r in rows if r["m"] == m), key=lambda r: r["psnr"])
        metrics[f"best_m{m}"] = best["solver"]

    def w(tmp):
        with open(tmp, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)

    _atomic(out_dir / "comparison.csv", w)
    write_npz(out_dir / "arrays.npz", truth=x, **images)
    _figure(x, ms, list(solvers), images, rows, out_dir / "figures" / "solvers.png")
    return metrics


def _figure(x, ms, labels, images, rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(ms), len(labels) + 1, figsize=(2.4 * (len(labels) + 1), 2.6 * len(ms)), squeeze=False)
    for i, m in enumerate(ms):
        for j, label in enumerate(labels + ["truth"]):
            ax = axes[i, j]
            ax.set_xticks([])
            ax.set_yticks([])
            img = x if label == "truth" else images[f"{label}_m{m}"]
            ax.imshow(img, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            if label == "truth":
                ax.set_title("truth", fontsize=9)
            else:
                r = next(r for r in rows if r["m"] == m and r["solver"] == label)
                ax.set_title(f"{label}\n{r['psnr']:.2f} dB, {r['seconds']:.0f} s", fontsize=9)
            if j == 0:
                ax.set_ylabel(f"m = {m}", fontsize=9)
    fig.suptitle("Reconstruction solvers on Simulation 1's target", fontsize=10)
    save_figure(fig, path)
