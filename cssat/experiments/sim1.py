"""Simulation 1 (paper Fig. 8–9): proof of concept with a known sensing matrix.

A target image ``x (n × n)``, ``N = n²`` pixels, is measured as a light curve ``y = noise(Φx)``
(Eq. 12–15) through the ``atmosphere`` group's ``Φ (m, N)`` (the paper's i.i.d. ``N(0, 1/N)`` by
default) and the ``noise`` group (none by default); the ``solver`` group reconstructs it (the
paper's batch-OMP over ``ΦΨ`` with a 2-D DCT Ψ by default), the result is clipped to [0, 1] and
denoised by the ``denoiser`` group (2-D sparse K-SVD, Fig. 9's third column).

Headline metrics: ``psnr``/``ssim`` of the reconstruction, ``psnr_denoised``/``ssim_denoised``
of the denoised one.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("cssat")


def memory_parts(n: int, m: int, itemsize: int) -> dict[str, int]:
    """The large arrays of Simulation 1 (bytes): ``Φ``, ``ΦΨ`` and the OMP's Gram ``ΨᵀΦᵀΦΨ``."""
    N = n * n
    return {"Φ": m * N * itemsize, "ΦΨ": m * N * itemsize, "Gram": N * N * itemsize}


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    """Run Simulation 1 into ``out_dir``: ``arrays.npz``, ``figures/fig9_sim1.png``; return the metrics."""
    import torch

    from cssat.data import load_target
    from cssat.experiments.build import build_denoiser, build_measurement, build_solver
    from cssat.experiments.common import figure_file, run_settings, write_npz
    from cssat.experiments.pipeline import phi_stats, reconstruct, scores
    from cssat.experiments.resources import check_memory
    from cssat.plots import save_figure, sim1_figure

    dtype, device, seed, n, N, m = run_settings(cfg, max_size=4096)
    solver = build_solver(cfg.solver, m, N)
    denoiser = build_denoiser(cfg.get("denoiser"))
    est = check_memory(memory_parts(n, m, torch.finfo(dtype).bits // 8), cfg, "lower target.size or cs.m")
    x = load_target(str(cfg.target.image), n)

    t = time.perf_counter()
    meas, atm = build_measurement(cfg, m, N, seed, dtype, device, experiment="sim1")
    y = meas(torch.as_tensor(x, dtype=dtype, device=device).reshape(N))
    t_measure = time.perf_counter() - t

    stats = phi_stats(cfg, meas.operator, (n, n))
    r = reconstruct(solver, meas.operator, y, (n, n), denoiser=denoiser, center=cfg.get("center", "auto"))
    noise = meas.describe()
    del meas
    metrics: dict[str, Any] = {
        **scores(r.image, r.denoised, x),
        "m": m, "n": n, "n_pixels": N, "measurement_ratio": m / N,
        **atm.describe(), **noise, **stats,
        "seed": seed, "dtype": str(cfg.get("dtype", "float32")), "device": str(device), "target": str(cfg.target.image),
        "peak_memory_estimate_gb": est / 2**30,
        "seconds_measure": t_measure,
        **r.metrics,
    }
    write_npz(out_dir / "arrays.npz", truth=x, y=y, reconstruction=r.image, reconstruction_unclipped=r.raw,
              denoised=r.denoised, **r.arrays)
    save_figure(sim1_figure(y.cpu().numpy(), r.image, r.denoised, x, metrics), figure_file(cfg, out_dir, "fig9_sim1"))
    log.info(
        "sim1: PSNR %.2f dB (denoised %.2f dB, %s), SSIM %.3f, m=%d (%.0f%% of N=%d), %s, %.1f s",
        metrics["psnr"], metrics["psnr_denoised"], metrics["denoiser"], metrics["ssim"], m, 100 * m / N, N,
        f"K={metrics['omp_atoms']}" if "omp_atoms" in metrics else f"{metrics['solver']} {metrics.get('solver_iterations')} it.",
        t_measure + sum(v for k, v in r.metrics.items() if k.startswith("seconds_")),
    )
    return metrics
