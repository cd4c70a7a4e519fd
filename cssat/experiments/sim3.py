"""Simulation 3 (paper Fig. 12–14): the rank-deficient reference-satellite approach.

The target (TESS-like, ``n × n``, 64² in the paper) is measured as ``y = noise(Φx)`` through the
``atmosphere`` group. A pool of reference images (Astra-like model, random Sun and view
directions, white noise; 8000 in the paper) is rendered once; each of ``reference.repeats`` (9)
repeats draws ``N_ref`` of them (3277), measures them through the same atmosphere
(``Y_ref``, Eq. 22), estimates ``Φ̂`` by the sparse model ``Φᵀ = ΨA`` (Eq. 26–30, batch-OMP with
``T₀`` or ``ε₀``), reconstructs the image with the ``solver`` group from ``Φ̂`` (held as
``Φ̂Ψ = Âᵀ``) and denoises it in 2-D with ``denoiser``. The raw results are then stacked
``(repeats, n, n)`` and denoised in 3-D with ``denoiser3d``. The minimum-norm estimate
``Y_ref X_ref⁺`` is reconstructed beside the sparse one as a baseline.

Headline metrics: ``psnr``/``ssim`` of the best repeat's raw reconstruction (the paper's Fig. 14
(b)); ``psnr_denoised`` (its 2-D denoised version) and ``psnr_denoised_3d``; means over the
repeats as ``psnr_mean*``; per-repeat lists as ``repeat_*``.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from cssat._progress import progress_bar
from cssat.experiments.common import progress_setting

log = logging.getLogger("cssat")


def memory_parts(n: int, m: int, n_ref: int, pool: int, itemsize: int, repeats: int = 1) -> dict[str, int]:
    """The large arrays (bytes): the pool (float32) and, when formed once, its light curves
    ``(m, pool)``; ``Φ``, ``Y_ref``, ``D = X_refᵀΨ``, the OMP's Gram ``(N, N)``, and the
    coefficients ``Âᵀ``, ``Φ̂`` and the baseline's (each ``m × N``)."""
    N = n * n
    shared = m * pool * itemsize if _share_light_curves(pool, n_ref, repeats) else 0
    return {"pool": pool * N * 4, "pool light curves": shared, "Φ": m * N * itemsize, "Y_ref": m * n_ref * itemsize,
            "D": 2 * n_ref * N * itemsize, "Gram": N * N * itemsize, "coefficients": 4 * m * N * itemsize}


#: ``reference.n_nonzero_coefs: auto``: T₀ = round(200 · (64 / n)^1.5) — the paper-size default
#: 200 at 64², 71 at 128². The estimate's Batch-OMP updates cost ``m · N · T₀² / 2`` value reads,
#: ∝ n⁴ T₀² with m ∝ N: this rule makes them grow only as n, what lets 9 repeats at 128² fit
#: 30 minutes on 2 cores. It is a compute budget, not a model choice: more atoms fit Φ̂ better
#: (BENCHMARKS.md, the T₀ tables at 64² and 128²).
T0_AUTO = (200, 64, 1.5)

#: ``reference.baseline: auto`` computes the minimum-norm baseline on every repeat while
#: ``m · N`` is at most this (64²: 3277 × 4096), else on the first repeat only (at 128² a
#: baseline — its Cholesky solve, ``Φ̂Ψ`` and its reconstruction — costs ~2 minutes a repeat)
BASELINE_ALL_MAX = 2**24


def reference_sizes(cfg: Any, n: int) -> tuple[int, int]:
    """``(N_ref, pool)``: ``reference.n`` (null → ``round(reference.ratio · n²)``, 3277 at 64²)
    and ``reference.pool`` (null → ``round(reference.pool_ratio · n²)``, 8000 at 64², 32000 at
    128²: the pool grows with the pixel count, so draws of ``N_ref`` overlap as much at any size)."""
    from cssat.experiments.common import require_float, require_int

    ref, N = cfg.reference, n * n
    pool = ref.get("pool")
    if pool is None:
        pool = max(1, round(require_float(ref.get("pool_ratio"), "reference.pool_ratio", lo=0.0) * N))
    pool = require_int(pool, "reference.pool", 1)
    n_ref = ref.get("n")
    if n_ref is None:
        n_ref = max(1, round(require_float(ref.get("ratio"), "reference.ratio", lo=0.0, hi=1.0) * N))
    return require_int(n_ref, "reference.n", 1, min(pool, N)), pool


def estimate_settings(cfg: Any, N: int) -> tuple[int | None, float | None]:
    """``(T₀, ε₀²)`` of the rank-deficient estimate from ``reference.n_nonzero_coefs`` (an
    integer, ``auto`` = :data:`T0_AUTO`'s rule, or null) and ``reference.epsilon`` (a norm in the
    light curves' units)."""
    from cssat.experiments.common import ConfigError, require_float, require_int

    t0, eps = cfg.reference.get("n_nonzero_coefs"), cfg.reference.get("epsilon")
    if t0 == "auto":
        t0 = min(N, max(1, round(T0_AUTO[0] * (T0_AUTO[1] / math.sqrt(N)) ** T0_AUTO[2])))
    if t0 is None and eps is None:
        raise ConfigError("reference.n_nonzero_coefs: give T0 (Eq. 28), auto, or reference.epsilon (Eq. 29)")
    t0 = None if t0 is None else require_int(t0, "reference.n_nonzero_coefs", 1, N)
    return t0, None if eps is None else require_float(eps, "reference.epsilon", lo=0.0) ** 2


def baseline_repeats(cfg: Any, m: int, N: int, repeats: int) -> int:
    """How many repeats (the first ones) get the minimum-norm baseline: ``reference.baseline``
    true (all), ``first`` (1), false (0) or ``auto`` (all while ``m · N`` ≤ :data:`BASELINE_ALL_MAX`, else 1)."""
    from cssat.experiments.common import ConfigError

    mode = cfg.reference.get("baseline", "auto")
    if mode is True:
        return repeats
    if mode is False:
        return 0
    if mode == "first":
        return 1
    if mode == "auto":
        return repeats if m * N <= BASELINE_ALL_MAX else 1
    raise ConfigError(f"reference.baseline: expected true, false, first or auto, got {mode!r}")


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    """Run Simulation 3 into ``out_dir``: ``arrays.npz``, ``figures/fig13_sim3_results.png`` and
    ``fig14_sim3_denoised.png``; return the metrics."""
    import torch

    from cssat.data import load_target
    from cssat.experiments.build import build_denoiser, build_measurement, build_solver
    from cssat.experiments.common import figure_file, require_int, run_settings, write_npz
    from cssat.experiments.pipeline import denoise, phi_stats
    from cssat.experiments.refsets import reference_set, reference_settings
    from cssat.experiments.resources import check_memory, peak_rss_bytes
    from cssat.metrics import psnr
    from cssat.plots import save_figure, sim3_figures

    dtype, device, seed, n, N, m = run_settings(cfg, max_size=512)
    n_ref, pool = reference_sizes(cfg, n)
    repeats = require_int(cfg.reference.get("repeats", 9), "reference.repeats", 1, 1000)
    n_baseline = baseline_repeats(cfg, m, N, repeats)
    (ref_seed, ref_mesh), estimate = reference_settings(cfg, seed), estimate_settings(cfg, N)
    solver, denoiser = build_solver(cfg.solver, m, N), build_denoiser(cfg.get("denoiser"))
    denoiser3d = build_denoiser(cfg.get("denoiser3d"), "denoiser3d") if repeats >= 2 else None
    est = check_memory(memory_parts(n, m, n_ref, pool, torch.finfo(dtype).bits // 8, repeats), cfg,
                       "lower target.size, reference.pool or cs.m, or use dtype=float32")
    x = load_target(str(cfg.target.image), n)
    timings = dict.fromkeys(("seconds_estimate", "seconds_solver", "seconds_denoise", "seconds_baseline"), 0.0)

    t = time.perf_counter()
    meas, atm = build_measurement(cfg, m, N, seed, dtype, device, experiment="sim3")
    y = meas(torch.as_tensor(x, dtype=dtype, device=device).reshape(N))
    timings["seconds_measure"] = time.perf_counter() - t
    stats = phi_stats(cfg, meas.operator, (n, n))
    t = time.perf_counter()
    pool_imgs, cached = reference_set(cfg, n, pool, ref_seed, ref_mesh)
    timings["seconds_references"] = time.perf_counter() - t

    flat = pool_imgs.reshape(pool, N)
    t = time.perf_counter()
    pool_light = _pool_light_curves(meas.matrix(), flat) if _share_light_curves(pool, n_ref, repeats) else None
    timings["seconds_reference_light_curves"] = time.perf_counter() - t
    per, recs = [], []
    bar = progress_bar(repeats, f"sim3: repeats of Eq. 26-30 with N_ref={n_ref}", progress_setting(cfg), unit="repeat")
    for r in range(repeats):
        idx = torch.randperm(pool, generator=torch.Generator().manual_seed(ref_seed * 1_000_003 + r))[:n_ref]
        Xt = flat[idx].to(dtype=dtype, device=device)  # X_refᵀ (N_ref, N)
        clean = pool_light[:, idx.to(pool_light.device)] if pool_light is not None else None
        row, rec = _repeat(cfg, meas, Xt, y, x, solver, denoiser, estimate, timings, ref_seed * 1_000_003 + r + 1,
                           baseline=r < n_baseline, clean=clean)
        per.append(row)
        recs.append(rec)
        bar.update()
        log.info("sim3 repeat %d: ‖Φ̂−Φ‖/‖Φ‖ %.3f, PSNR %.2f dB, 2-D denoised %.2f dB", r,
                 row["phi_relative_error"], row["psnr"], row["psnr_denoised"])
    bar.close()
    noise = meas.describe()
    del meas, pool_imgs, flat, pool_light

    stack, den2 = np.stack([r.image for r in recs]), np.stack([r.denoised for r in recs])
    den3, dm3 = denoise(denoiser3d, stack, field="denoiser3d") if denoiser3d is not None else (stack.copy(), {"denoiser": "none"})
    timings["seconds_denoise_3d"] = dm3.pop("seconds_denoise", 0.0)
    psnr3 = [psnr(x, d, data_range=1.0) for d in den3]
    metrics = {**_summary(per, psnr3), "m": m, "n": n, "n_pixels": N, "reference_n": n_ref, "reference_pool": pool,
               "repeats": repeats, "baseline_repeats": n_baseline, "reference_n_nonzero_coefs": estimate[0], "reference_tol": estimate[1],
               "reference_cached": cached, **{k: v for k, v in recs[-1].metrics.items() if k.startswith("solver")},
               **atm.describe(), **noise, **stats, "seed": seed, "dtype": str(cfg.get("dtype", "float32")), "device": str(device),
               "peak_memory_estimate_gb": est / 2**30, "peak_rss_gb": peak_rss_bytes() / 2**30,
               "denoiser": recs[-1].metrics["denoiser"], "denoiser_3d": dm3.get("denoiser"), **timings}
    write_npz(out_dir / "arrays.npz", truth=x, y=y, reconstructions=stack, denoised_2d=den2, denoised_3d=den3)
    fig13, fig14 = sim3_figures(x, stack, den2, den3, per, psnr3, metrics["best_repeat"], metrics)
    save_figure(fig13, figure_file(cfg, out_dir, "fig13_sim3_results"))
    save_figure(fig14, figure_file(cfg, out_dir, "fig14_sim3_denoised"))
    three_d = (f"3-D {metrics['psnr_denoised_3d']:.2f} dB ({metrics['gain_3d_over_2d']:+.2f} over 2-D)" if denoiser3d is not None
               else "no 3-D denoising (one repeat: the stack is that image)")
    log.info("sim3: best repeat %d: PSNR %.2f dB, 2-D %.2f dB (%+.2f), %s", metrics["best_repeat"],
             metrics["psnr"], metrics["psnr_denoised"], metrics["gain_2d"], three_d)
    return metrics


def _share_light_curves(pool: int, n_ref: int, repeats: int) -> bool:
    """Whether to form the light curves ``Φ x`` of the whole pool once (``m × pool`` values)
    rather than ``Φ X_ref`` in every repeat: when the repeats draw more images in all than the
    pool holds (9 × 3277 > 8000; at 128², 9 × 13107 > 32000 saves ~110 s)."""
    return repeats * n_ref > pool


def _pool_light_curves(phi, flat, block: int = 4096):
    """``Φ x`` for every image of the pool ``flat (pool, N)``: ``(m, pool)``, in blocks of
    images: each column is the product of Φ with that image, so a repeat's columns are
    ``Φ X_ref`` (to round-off; bit for bit with this project's BLAS — BENCHMARKS.md)."""
    import torch

    out = torch.empty(phi.shape[0], flat.shape[0], dtype=phi.dtype, device=phi.device)
    for s in range(0, flat.shape[0], block):
        out[:, s : s + block] = phi @ flat[s : s + block].to(dtype=phi.dtype, device=phi.device).T
    return out


def _repeat(cfg, meas, Xt, y, x, solver, denoiser, estimate, timings, noise_seed, baseline, clean=None):
    """One repeat: ``Y_ref`` (Eq. 22: ``clean``, the noise-free ``Φ X_ref`` when the pool's
    light curves were formed once, else formed here), the sparse ``Φ̂`` (Eq. 26–30), the
    reconstruction from it and its 2-D denoising, and (``baseline``) the minimum-norm baseline.
    Returns ``(row of metrics, Reconstruction)``."""
    import torch

    from cssat.experiments.pipeline import reconstruct, scores
    from cssat.metrics import psnr
    from cssat.reference import estimate_sensing_min_norm, estimate_sensing_sparse, relative_error
    from cssat.sparse import DictionarySensing

    n = int(cfg.target.size)
    phi = meas.matrix()
    t = time.perf_counter()
    Y_ref = meas.add_noise(phi @ Xt.T if clean is None else clean, torch.Generator().manual_seed(noise_seed))
    timings["seconds_reference_light_curves"] += time.perf_counter() - t
    t = time.perf_counter()
    phi_dense, info = estimate_sensing_sparse(Xt.T, Y_ref, n_nonzero_coefs=estimate[0], tol=estimate[1], shape=(n, n),
                                              normalize=bool(cfg.reference.get("normalize", True)), return_info=True,
                                              progress=progress_setting(cfg))
    timings["seconds_estimate"] += time.perf_counter() - t
    row = {"phi_relative_error": relative_error(phi_dense, phi), "estimate_mean_atoms": float(info.n_iter.double().mean())}
    del phi_dense
    rec = reconstruct(solver, DictionarySensing(info.coefficients, (n, n)), y, (n, n), denoiser=denoiser,
                      center=cfg.get("center", "auto"))  # Φ̂Ψ = Âᵀ
    timings["seconds_solver"] += rec.metrics["seconds_solver"] + rec.metrics.get("seconds_dictionary", 0.0)
    timings["seconds_denoise"] += rec.metrics["seconds_denoise"]
    if baseline:
        t = time.perf_counter()
        phi_mn = estimate_sensing_min_norm(Xt.T, Y_ref)
        row["phi_relative_error_min_norm"] = relative_error(phi_mn, phi)
        row["psnr_min_norm"] = psnr(x, reconstruct(solver, phi_mn, y, (n, n)).image, data_range=1.0)
        timings["seconds_baseline"] += time.perf_counter() - t
    row.update(scores(rec.image, rec.denoised, x))
    return row, rec


def _summary(per: list[dict], psnr3: list[float]) -> dict[str, Any]:
    """The headline (the best repeat's), the means over the repeats and the per-repeat lists."""
    best = int(np.argmax([p["psnr"] for p in per]))
    out: dict[str, Any] = {k: per[best][k] for k in ("psnr", "ssim", "psnr_denoised", "ssim_denoised")}
    out.update(psnr_denoised_3d=psnr3[best], best_repeat=best, gain_2d=per[best]["psnr_denoised"] - per[best]["psnr"],
               gain_3d_over_2d=psnr3[best] - per[best]["psnr_denoised"], psnr_mean_denoised_3d=float(np.mean(psnr3)))
    means = {"psnr": "psnr_mean", "psnr_denoised": "psnr_mean_denoised", "phi_relative_error": "phi_relative_error_mean",
             "phi_relative_error_min_norm": "phi_relative_error_min_norm_mean", "psnr_min_norm": "psnr_min_norm_mean"}
    for key, name in means.items():  # over the repeats that have the value (the baseline may be on the first only)
        vals = [p[key] for p in per if key in p]
        if vals:
            out[name] = float(np.mean(vals))
    keys = list(dict.fromkeys(k for p in per for k in p))
    out.update({f"repeat_{key}": [p.get(key) for p in per] for key in keys})
    out["repeat_psnr_denoised_3d"] = psnr3
    return out
