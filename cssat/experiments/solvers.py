"""Solver comparison (``cssat experiment=solvers``): every reconstruction solver on Simulation 1's
target at several m, side by side with the paper's OMP + sparse-KSVD.

For each m one measurement ``y = noise(Φx)`` (the ``atmosphere`` and ``noise`` groups, seeded);
each entry of ``comparison.solvers`` (a ``solver`` group config, label → config) reconstructs
from it, and the labels listed in ``comparison.denoise`` are post-processed with the
``denoiser`` group. Writes ``comparison.csv`` (one row per m and solver: PSNR, SSIM, seconds),
flat metrics ``psnr_<label>_m<m>``, the images in ``arrays.npz`` and a figure: rows = m,
columns = solvers.

Headline metrics: ``psnr``/``ssim`` of the best solver at the last m of ``comparison.m``
(``best_solver``; the largest m by default).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("cssat")


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    """Run the comparison into ``out_dir``; return the metrics."""
    import torch

    from cssat.data import load_target
    from cssat.experiments.build import build_denoiser, build_measurement, build_solver
    from cssat.experiments.common import ConfigError, figure_file, require_int, run_settings, write_csv, write_npz
    from cssat.experiments.pipeline import phi_stats, reconstruct, scores
    from cssat.experiments.resources import check_memory
    from cssat.experiments.sim1 import memory_parts
    from cssat.plots import save_figure, solvers_figure

    dtype, device, seed, n, N, _ = run_settings(cfg, max_size=4096)
    ms = [require_int(v, "comparison.m", 1, N) for v in cfg.comparison.m]
    labels = list(cfg.comparison.solvers or {})
    if not ms or not labels:
        raise ConfigError("comparison: needs at least one m (comparison.m) and one solver (comparison.solvers)")
    post = list(cfg.comparison.get("denoise") or [])
    if not set(post) <= set(labels):
        raise ConfigError(f"comparison.denoise: expected labels from {labels}, got {post}")
    # validated at the smallest m, where the size-dependent settings (e.g. K <= m) bind
    solvers = {lab: build_solver(cfg.comparison.solvers[lab], min(ms), N, f"comparison.solvers.{lab}") for lab in labels}
    denoiser = build_denoiser(cfg.get("denoiser"))
    check_memory(memory_parts(n, max(ms), torch.finfo(dtype).bits // 8), cfg, "lower target.size or comparison.m")
    x = load_target(str(cfg.target.image), n)
    rows, images = [], {}
    metrics: dict[str, Any] = {"n": n, "n_pixels": N, "m_values": ms, "solvers": labels}
    for m in ms:
        meas, atm = build_measurement(cfg, m, N, seed, dtype, device, experiment="solvers")
        y = meas(torch.as_tensor(x, dtype=dtype, device=device).reshape(N))
        for label in labels:
            t = time.perf_counter()
            r = reconstruct(solvers[label], meas.operator, y, (n, n), denoiser=denoiser if label in post else None,
                            center=cfg.get("center", "auto"))
            sec = time.perf_counter() - t
            out = r.denoised if label in post else r.image
            row = {"m": m, "m_over_N": m / N, "solver": label, **scores(out, None, x), "seconds": sec,
                   "iterations": r.metrics.get("solver_iterations", r.metrics.get("omp_atoms"))}
            rows.append(row)
            images[f"{label}_m{m}"] = out
            metrics[f"psnr_{label}_m{m}"], metrics[f"seconds_{label}_m{m}"] = row["psnr"], sec
            log.info("solvers: m=%d %-10s PSNR %.2f dB, SSIM %.3f, %.1f s", m, label, row["psnr"], row["ssim"], sec)
        metrics.update(atm.describe(), **meas.describe(), **{f"{k}_m{m}": v for k, v in phi_stats(cfg, meas.operator, (n, n)).items()})
        del meas
    for m in ms:
        best = max((r for r in rows if r["m"] == m), key=lambda r: r["psnr"])
        metrics[f"best_m{m}"] = best["solver"]
    metrics.update(psnr=best["psnr"], ssim=best["ssim"], best_solver=best["solver"], m=ms[-1])

    write_csv(out_dir / "comparison.csv", rows)
    write_npz(out_dir / "arrays.npz", truth=x, **images)
    save_figure(solvers_figure(x, ms, labels, images, rows), figure_file(cfg, out_dir, "solvers"))
    return metrics
