"""Simulation 2 (paper Fig. 10–11): the full-rank reference-satellite approach.

The target (the rendered TESS-like model, ``n × n``, ``N = n²``) is measured as
``y = noise(Φx)`` through the ``atmosphere`` group's unknown ``Φ (m, N)``. ``N_ref = N`` reference
images of the Astra-like model under random Sun and view directions, with white noise
(``X_ref (N, N_ref)``, images as columns), are measured through the same atmosphere:
``Y_ref = noise(Φ X_ref)`` (Eq. 22). ``Φ̂ = Y_ref X_ref⁻¹`` (Eq. 24, one LU solve in
``reference.dtype``); the ``solver`` group reconstructs the image from ``Φ̂`` and the ``denoiser``
group denoises it.

Headline metrics: ``psnr``/``ssim`` of the reconstruction; ``psnr_denoised``/``ssim_denoised``.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("cssat")


def memory_peak(n: int, m: int, itemsize: int, ref_itemsize: int) -> tuple[int, dict[str, int]]:
    """``(peak bytes, parts)`` of Simulation 2 at ``N = n²`` pixels and ``m`` samples.

    In the reference stage (``ref_itemsize``) these live together: ``Φ`` (m N), ``Y_ref`` (m N),
    ``X_ref`` (N²) and its LU factor (N²), then ``Φ̂`` (m N) in place of ``X_ref``. In the
    reconstruction (``itemsize``): ``Φ̂Ψ`` (m N) and the OMP's Gram (N²).
    """
    N = n * n
    parts = {"Φ": m * N * ref_itemsize, "Y_ref": m * N * ref_itemsize, "X_ref": N * N * ref_itemsize,
             "LU": N * N * ref_itemsize}
    at_lu = sum(parts.values()) + N * N * 4  # + the float32 renders while X_ref is built
    at_solve = 3 * m * N * ref_itemsize + N * N * ref_itemsize
    later = m * N * ref_itemsize + m * N * itemsize + N * N * itemsize
    return max(at_lu, at_solve, later), parts


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    """Run Simulation 2 into ``out_dir``: ``arrays.npz``, ``figures/fig11_sim2.png``; return the metrics."""
    import torch

    from cssat.data import load_target
    from cssat.experiments.build import build_denoiser, build_measurement, build_solver
    from cssat.experiments.common import ConfigError, figure_file, require_int, run_settings, torch_dtype, write_npz
    from cssat.experiments.pipeline import phi_stats, reconstruct, scores
    from cssat.experiments.refsets import reference_set, reference_settings
    from cssat.experiments.resources import check_memory, peak_rss_bytes
    from cssat.plots import save_figure, sim2_figure
    from cssat.reference import estimate_sensing_full_rank, relative_error

    dtype, device, seed, n, N, m = run_settings(cfg, max_size=1024)
    n_ref = cfg.reference.get("n")
    n_ref = N if n_ref is None else require_int(n_ref, "reference.n", N, N)
    ref_seed, ref_mesh = reference_settings(cfg, seed)
    solver, denoiser = build_solver(cfg.solver, m, N), build_denoiser(cfg.get("denoiser"))
    ref_dtype = torch_dtype(cfg.reference.get("dtype", "float64"), field="reference.dtype")
    peak, parts = memory_peak(n, m, torch.finfo(dtype).bits // 8, torch.finfo(ref_dtype).bits // 8)
    est = check_memory(parts, cfg, "lower target.size or cs.m, or use reference.dtype=float32", peak=peak)
    x = load_target(str(cfg.target.image), n)
    timings: dict[str, float] = {}

    t = time.perf_counter()
    # Φ is drawn in float32 (Simulation 1's Φ for this seed) and held exactly in reference.dtype,
    # in which y, Y_ref = Φ X_ref and the solve are computed
    meas, atm = build_measurement(cfg, m, N, seed, ref_dtype, device, sensing_dtype=torch.float32, experiment="sim2")
    y = meas(torch.as_tensor(x, dtype=ref_dtype, device=device).reshape(N)).to(dtype)
    timings["seconds_measure"] = time.perf_counter() - t
    t = time.perf_counter()
    refs, cached = reference_set(cfg, n, n_ref, ref_seed, ref_mesh)  # (N_ref, n, n) float32
    timings["seconds_references"] = time.perf_counter() - t
    t = time.perf_counter()
    Xt = refs.reshape(n_ref, N).to(dtype=ref_dtype, device=device)  # X_refᵀ: reference k is row k
    del refs
    phi = meas.matrix()
    Y_ref = meas.add_noise(phi @ Xt.T, torch.Generator().manual_seed(seed + 2))  # Eq. 22, (m, N_ref)
    timings["seconds_reference_light_curves"] = time.perf_counter() - t

    t = time.perf_counter()
    try:
        phi_hat, rcond = estimate_sensing_full_rank(Xt.T, Y_ref, return_rcond=True)  # Eq. 24
    except ValueError as err:
        raise ConfigError(f"reference: {err}") from err
    del Xt, Y_ref
    timings["seconds_estimate"] = time.perf_counter() - t
    phi_err, stats = relative_error(phi_hat, phi), phi_stats(cfg, phi, (n, n))
    noise = meas.describe()
    del phi, meas

    r = reconstruct(solver, phi_hat.to(dtype), y, (n, n), denoiser=denoiser, center=cfg.get("center", "auto"))  # Eq. 5/6
    del phi_hat
    metrics: dict[str, Any] = {
        **scores(r.image, r.denoised, x),
        "phi_relative_error": phi_err, "x_ref_rcond": rcond, "reference_dtype": str(cfg.reference.get("dtype", "float64")),
        "m": m, "n": n, "n_pixels": N, "reference_n": n_ref, "reference_noise": float(cfg.reference.get("noise", 0.0)),
        "reference_cached": cached, **atm.describe(), **noise, **stats,
        "seed": seed, "dtype": str(cfg.get("dtype", "float32")), "device": str(device),
        "peak_memory_estimate_gb": est / 2**30, "peak_rss_gb": peak_rss_bytes() / 2**30,
        **r.metrics, **timings,
    }
    metrics["psnr_gain_denoised"] = metrics["psnr_denoised"] - metrics["psnr"]
    write_npz(out_dir / "arrays.npz", truth=x, y=y, reconstruction=r.image, denoised=r.denoised, **r.arrays)
    save_figure(sim2_figure(x, r.image, r.denoised, metrics), figure_file(cfg, out_dir, "fig11_sim2"))
    log.info("sim2: ‖Φ̂−Φ‖/‖Φ‖ = %.2e, PSNR %.2f dB, denoised %.2f dB (%+.2f), peak RSS %.1f GB",
             phi_err, metrics["psnr"], metrics["psnr_denoised"], metrics["psnr_gain_denoised"], metrics["peak_rss_gb"])
    return metrics
