"""Where light-curve imaging can work (``cssat experiment=realism``): reconstruction quality over
the object's angular size and its brightness, through a physical atmosphere and photometric noise.

At ``n × n`` (64²) the target is measured with ``m`` samples (0.8 N) through the ``atmosphere``
group's model (the multi-layer phase screens by default) for each angular size in
``realism.angular_size_arcsec`` (the image's side; an object of ``realism.object_size_m`` at the
range that gives it: 10 m is 0.058″ at GEO), with the ``noise`` group's photometric noise for each
V magnitude in ``realism.magnitudes``; every solver of ``realism.solvers`` reconstructs it from the
centred system (:func:`cssat.physics.centered`). The paper's Gaussian Φ under the same noise is the
reference row. Writes ``realism.csv`` (one row per solver × size × magnitude, and the paper's row),
``figures/realism_<solver>.png`` (PSNR maps), ``figures/realism_rank.png`` (Φ's effective rank and
scintillation index against the angular size).

Headline metrics: ``psnr``/``ssim`` of the best solver at the largest size and the brightest
magnitude (the most favourable cell); ``psnr_<solver>_a<i>_v<j>`` for every cell;
``psnr_flux_only``, the PSNR of the flat image that knowing only the total flux gives — a cell
at or below it holds no information about the image.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

log = logging.getLogger("cssat")


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    """Run the realism maps into ``out_dir``; return the metrics."""
    import torch

    from cssat.data import load_target
    from cssat.experiments.build import build, build_solver
    from cssat.experiments.common import figure_file, require_float, run_settings, write_csv
    from cssat.experiments.resources import check_memory
    from cssat.experiments.sim1 import memory_parts
    from cssat.physics import GaussianAtmosphere, Measurement, sensing_stats
    from cssat.plots import realism_figures, save_figure

    dtype, device, seed, n, N, m = run_settings(cfg, max_size=256)
    r = cfg.realism
    sizes = [require_float(a, "realism.angular_size_arcsec", lo=1e-6) for a in r.angular_size_arcsec]
    mags = [require_float(v, "realism.magnitudes", lo=-30, hi=40) for v in r.magnitudes]
    size_m = require_float(r.object_size_m, "realism.object_size_m", lo=1e-3)
    solvers = {lab: build_solver(node, m, N, f"realism.solvers.{lab}") for lab, node in r.solvers.items()}
    build(cfg.atmosphere, "atmosphere")
    noise = build(cfg.noise, "noise")
    if getattr(noise, "magnitude", 0.0) is None:
        from cssat.experiments.common import ConfigError

        raise ConfigError("noise.magnitude: the realism maps set the magnitude themselves; use noise=photometric")
    check_memory(memory_parts(n, m, 8), cfg, "lower target.size or cs.m")  # Φ in float64
    x = torch.as_tensor(load_target(str(cfg.target.image), n), dtype=torch.float64).reshape(N)
    center = cfg.get("center", "auto")  # the physical Φ: centred unless center=false
    rows: list[dict[str, Any]] = []
    stats: list[dict[str, Any]] = []
    columns = [("paper", None)] + [(f"a{i}", a) for i, a in enumerate(sizes)]
    for col, arcsec in columns:
        if arcsec is None:
            atm = GaussianAtmosphere()
        else:
            node = cfg.atmosphere.copy()
            node.object_size_m, node.range_km = size_m, size_m / (arcsec * 4.84813681109536e-6) / 1e3
            atm = build(node, "atmosphere")
        phi = atm.operator(m, N, seed=seed, dtype=torch.float64)
        st = {"column": col, "angular_size_arcsec": arcsec, **sensing_stats(phi.matrix(), (n, n))}
        stats.append(st)
        log.info("realism: %s: Φ mean %.3g, scintillation index %s, effective rank %d (of its fluctuations %d)", col,
                 st["phi_mean"], st["phi_scintillation_index"], st["phi_effective_rank"], st["phi_effective_rank_centered"])
        for j, mag in enumerate(mags):
            if hasattr(noise, "magnitude"):
                noise.magnitude = mag
            y = Measurement(phi, noise, seed=seed + 1 + 7919 * j)(x)
            for lab, solver in solvers.items():
                rows.append(_cell(solver, lab, phi, y, x, n, dtype, center=center if arcsec is not None else False)
                            | {"column": col, "angular_size_arcsec": arcsec, "magnitude": mag, 
                               "snr": noise.snr(mag) if hasattr(noise, "snr") else float("inf"),
                               "phi_effective_rank_centered": st["phi_effective_rank_centered"]})
                log.info("realism: %s V=%.1f %s: PSNR %.2f dB", col, mag, lab, rows[-1]["psnr"])

    write_csv(out_dir / "realism.csv", rows)
    import numpy as np

    from cssat.metrics import psnr

    truth = x.reshape(n, n).numpy()
    flux_only = psnr(truth, np.full_like(truth, truth.mean()), data_range=1.0)  # what the total flux alone gives
    metrics: dict[str, Any] = {"m": m, "n": n, "n_pixels": N, "seed": seed, "solvers": list(solvers), "psnr_flux_only": flux_only,
                               "angular_size_arcsec": sizes, "magnitudes": mags, **atm.describe(), **noise.describe()}
    metrics.update({f"psnr_{r_['solver']}_{r_['column']}_v{mags.index(r_['magnitude'])}": r_["psnr"] for r_ in rows})
    for key in ("phi_effective_rank", "phi_effective_rank_centered", "phi_scintillation_index", "phi_coherence"):
        metrics.update({f"{key}_{s['column']}": s[key] for s in stats})
    best = max((r_ for r_ in rows if r_["column"] == columns[-1][0] and r_["magnitude"] == min(mags)), key=lambda r_: r_["psnr"])
    metrics.update(psnr=best["psnr"], ssim=best["ssim"], best_solver=best["solver"])
    for name, fig in realism_figures(rows, stats, list(solvers), sizes, mags, n, flux_only).items():
        save_figure(fig, figure_file(cfg, out_dir, f"realism_{name}"))
    return metrics


def _cell(solver, label, phi, y, x, n, dtype, center: bool) -> dict[str, Any]:
    """One reconstruction: the centred system for a mean-1 Φ, the plain one for the paper's."""
    import time

    from cssat.experiments.pipeline import reconstruct, scores
    t = time.perf_counter()
    rec = reconstruct(solver, phi.matrix(), y, (n, n), center=center, dtype=dtype)  # centred in float64
    return {"solver": label, **scores(rec.image, None, x.reshape(n, n).numpy()), "seconds": time.perf_counter() - t}
