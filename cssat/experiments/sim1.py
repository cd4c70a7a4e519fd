"""Simulation 1 (paper Fig. 8–9): proof of concept with a known Gaussian sensing matrix.

A target image ``x (n × n)`` is measured as a simplified attenuated noisy light curve
``y = Φx`` (Eq. 12–15) with ``Φ (m, N)`` i.i.d. ``N(0, 1/N)``, ``N = n²``; the image is recovered by
batch-OMP over the dictionary ``ΦΨ`` with a 2-D DCT Ψ (Eq. 5 with ``K`` or Eq. 6 with ``ε``),
``x̂ = Ψγ̂``, clipped back to the image range [0, 1], and denoised by the ``denoiser`` group
(default: 2-D sparse K-SVD with the noise level estimated from ``x̂``, Fig. 9's third column).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from cssat.experiments.common import (
    ConfigError,
    require_float,
    require_int,
    run_settings,
    save_figure,
    write_npz,
)

log = logging.getLogger("cssat")


def default_sparsity(m: int, n_pixels: int) -> int:
    """The default ``K`` of Eq. 5 for ``m`` Gaussian measurements of ``n_pixels`` pixels:
    ``K = m (0.05 + 0.25 (m/N)²)``.

    A fixed ``K/m`` is wrong at both ends: with few measurements OMP over-fits (best near
    ``K/m = 0.05``), with ``m`` near ``N`` it under-fits (``K/m ≥ 0.25``). The rule follows the
    best ``K`` of a sweep on the 128² camera image at m = 1444, 4096, 13225 (BENCHMARKS.md).
    """
    r = m / n_pixels
    return max(1, round(m * (0.05 + 0.25 * r * r)))


def solver_settings(solver: Any, m: int, n_pixels: int) -> tuple[int, float | None]:
    """``(K, tol)`` for :func:`cssat.sparse.batch_omp` from the ``solver`` config.

    ``solver.epsilon`` (ε, a norm in y's units) gives the error-constrained Eq. 6 with
    ``tol = ε²`` and ``K`` as a cap (default ``m``); otherwise ``K = solver.n_nonzero_coefs``, or
    ``round(solver.k_ratio · m)``, or :func:`default_sparsity` when both are null (Eq. 5).
    """
    name = solver.get("name", "omp")
    if name != "omp":
        raise ConfigError(f"solver.name: expected one of ['omp'], got {name!r}")
    eps = solver.get("epsilon")
    k = solver.get("n_nonzero_coefs")
    if eps is not None:
        eps = require_float(eps, "solver.epsilon", lo=0.0)
        k = m if k is None else require_int(k, "solver.n_nonzero_coefs", 1, m)
        return k, eps * eps
    if k is None:
        ratio = solver.get("k_ratio")
        if ratio is None:
            k = default_sparsity(m, n_pixels)
        else:
            k = max(1, round(require_float(ratio, "solver.k_ratio", lo=0.0, hi=1.0) * m))
    return require_int(k, "solver.n_nonzero_coefs", 1, m), None


#: reconstruction solvers of Simulation 1 (the ``solver`` config group)
SIM1_SOLVERS = ("omp", "l1", "tv", "pnp")


def tv_default_lam(ratio: float) -> float:
    """The default relative TV weight at the measurement ratio ``m/N``: ``0.01 (1 − m/N)²``.

    Few measurements need a strong prior, many a faithful fit: on the 128² TESS-like target a fixed
    ``1e-2`` gives 31.1 / 41.2 / 45.1 dB at m = 1444 / 4096 / 13225 and ``1e-3`` gives
    20.6 / 30.7 / 63.6 dB (BENCHMARKS.md).
    """
    return 0.01 * (1.0 - min(max(ratio, 0.0), 1.0)) ** 2


def convex_settings(solver: Any, ratio: float | None = None) -> dict[str, Any]:
    """``lam`` (relative to ‖Aᵀy‖∞), ``max_iter``, ``tol`` and ``nonneg`` of the ``l1``/``tv`` solvers.
    A null ``lam`` of ``tv`` follows :func:`tv_default_lam` at the measurement ratio ``ratio``."""
    lam = solver.get("lam", 1e-3)
    if lam is None:
        lam = tv_default_lam(ratio if ratio is not None else 0.5)
    return {
        "lam": require_float(lam, "solver.lam", lo=0.0),
        "max_iter": require_int(solver.get("max_iter", 500), "solver.max_iter", 1),
        "tol": require_float(solver.get("tol", 1e-5), "solver.tol", lo=0.0),
        "nonneg": bool(solver.get("nonneg", True)),
    }


def _pnp(solver: Any, phi, y, n: int, seed: int):
    """Plug-and-play proximal gradient with the configured denoiser and a geometric σ schedule
    (image units: the targets are in [0, 1]); ``solver.init: tv`` starts from the TV solution."""
    import numpy as np
    import torch

    from cssat.sparse import ksvd_denoise
    from cssat.sparse.solvers import pnp_pgd, tv_pdhg

    name = str(solver.get("denoiser", "sparse_ksvd"))
    n_iter = require_int(solver.get("max_iter", 30), "solver.max_iter", 1)
    s0 = require_float(solver.get("sigma_start", 0.1), "solver.sigma_start", lo=1e-6)
    s1 = require_float(solver.get("sigma_end", 0.005), "solver.sigma_end", lo=1e-6)
    inner = require_int(solver.get("ksvd_iter", 3), "solver.ksvd_iter", 1)
    if name == "sparse_ksvd":
        def den(img, s):
            return ksvd_denoise(img, s, n_iter=inner, seed=seed)
    elif name in ("tv", "wavelet"):
        from skimage.restoration import denoise_tv_chambolle, denoise_wavelet

        def den(img, s):
            a = img.double().cpu().numpy()
            out = denoise_tv_chambolle(a, weight=s) if name == "tv" else denoise_wavelet(a, sigma=s, rescale_sigma=True)
            return torch.as_tensor(out)
    else:
        raise ConfigError(f"solver.denoiser: expected one of ['sparse_ksvd', 'tv', 'wavelet'], got {name!r}")
    init = str(solver.get("init", "zero"))
    if init not in ("zero", "tv"):
        raise ConfigError(f"solver.init: expected one of ['zero', 'tv'], got {init!r}")
    x0 = tv_pdhg(phi, y, (n, n), lam=1e-3, max_iter=300) if init == "tv" else None
    sig = np.geomspace(s0, s1, n_iter)
    return pnp_pgd(phi, y, (n, n), den, sigmas=sig, x0=x0, return_info=True)


def check_solver(solver: Any, m: int, N: int) -> str:
    """Validate the ``solver`` config before any work; return its name."""
    name = solver.get("name", "omp")
    if name not in SIM1_SOLVERS:
        raise ConfigError(f"solver.name: expected one of {list(SIM1_SOLVERS)}, got {name!r}")
    if name == "omp":
        solver_settings(solver, m, N)
    elif name in ("l1", "tv"):
        convex_settings(solver, m / N)
    return name


def reconstruct(solver: Any, phi, y, n: int, seed: int = 0):
    """Reconstruct an ``n × n`` image from ``y = Φx`` with the ``solver`` config (one of
    :data:`SIM1_SOLVERS`). ``phi`` is the sensing operator (kept by the caller).

    Returns ``(x_raw (n, n), γ or None, solver metrics, timings)``; ``x_raw`` is not clipped.
    """
    from cssat.sparse import DCT, batch_omp, sensing_dictionary

    name = solver.get("name", "omp")
    if name not in SIM1_SOLVERS:
        raise ConfigError(f"solver.name: expected one of {list(SIM1_SOLVERS)}, got {name!r}")
    m, N = int(y.shape[0]), n * n
    timings: dict[str, float] = {}
    metrics: dict[str, Any] = {"solver": name}
    gamma = None
    t = time.perf_counter()
    if name == "pnp":
        x_raw, sinfo = _pnp(solver, phi, y, n, seed)
    elif name == "tv":  # TV works on the image itself: Φ, not ΦΨ
        from cssat.sparse.solvers import tv_pdhg

        conv = convex_settings(solver, m / N)
        x_raw, sinfo = tv_pdhg(phi, y, (n, n), lam=conv["lam"], nonneg=conv["nonneg"], max_iter=conv["max_iter"],
                               tol=conv["tol"], return_info=True)
    else:
        if name == "omp":
            K, tol = solver_settings(solver, m, N)
        else:
            conv = convex_settings(solver)
        A = sensing_dictionary(phi, (n, n))
        timings["seconds_dictionary"] = time.perf_counter() - t
        t = time.perf_counter()
        if name == "omp":
            gamma, info = batch_omp(A, y, n_nonzero_coefs=K, tol=tol, return_info=True)
            metrics.update({
                "solver_n_nonzero_coefs": K,
                "solver_tol": tol,
                "solver_epsilon": math.sqrt(tol) if tol is not None else None,
                "omp_atoms": int(info.n_iter),
                "omp_path": info.path,
                "relative_residual": float(math.sqrt(float(info.residual_sq)) / max(float(y.norm()), 1e-300)),
            })
        else:
            from cssat.sparse.solvers import fista_l1

            gamma, sinfo = fista_l1(A, y, lam=conv["lam"], max_iter=conv["max_iter"], tol=conv["tol"], return_info=True)
        del A
        x_raw = DCT((n, n))(gamma).reshape(n, n)
    if name == "pnp":
        metrics.update({
            "solver_denoiser": str(solver.get("denoiser", "sparse_ksvd")), "solver_iterations": sinfo.n_iter,
            "solver_sigma_start": float(sinfo.lam[0]), "solver_sigma_end": float(sinfo.lam[-1]),
            "solver_objective": sinfo.objective[-1],
        })
    elif name != "omp":
        metrics.update({
            "solver_lam": conv["lam"], "solver_lam_abs": float(sinfo.lam[0]), "solver_max_iter": conv["max_iter"],
            "solver_tol": conv["tol"], "solver_iterations": sinfo.n_iter, "solver_converged": sinfo.converged,
            "solver_objective": sinfo.objective[-1] if sinfo.objective else None,
        })
        log.info("%s: %d iterations (converged: %s)", name, sinfo.n_iter, sinfo.converged)
    timings["seconds_solver"] = time.perf_counter() - t
    if name == "omp":
        metrics["seconds_omp"] = timings["seconds_solver"]  # the name earlier versions wrote
    return x_raw, gamma, metrics, timings


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    import torch

    from cssat.data import load_target
    from cssat.experiments.denoisers import apply_denoiser, scores
    from cssat.sparse import GaussianSensing

    dtype, device, seed, n, N, m = run_settings(cfg, max_size=4096)
    noise = require_float(cfg.cs.get("noise", 0.0), "cs.noise", lo=0.0)
    solver_name = check_solver(cfg.solver, m, N)
    x = load_target(str(cfg.target.image), n)
    timings: dict[str, float] = {}

    t = time.perf_counter()
    phi = GaussianSensing(m, N, seed=seed, dtype=dtype, device=device)
    xt = torch.as_tensor(x, dtype=dtype, device=device).reshape(N)
    y = phi(xt)
    if noise > 0:
        gen = torch.Generator(device="cpu").manual_seed(seed + 1)
        rms = y.pow(2).mean().sqrt()
        y = y + noise * rms * torch.randn(m, generator=gen, dtype=dtype).to(device)
    if not bool(torch.isfinite(y).all()):
        raise ValueError("y: the light curve contains NaN or Inf")
    timings["seconds_measure"] = time.perf_counter() - t

    x_raw, gamma, solver_metrics, solver_times = reconstruct(cfg.solver, phi, y, n, seed)
    del phi
    timings.update(solver_times)
    x_hat = x_raw.clamp(0.0, 1.0)  # back to the image range

    rec = x_hat.double().cpu().numpy()
    den, den_metrics = apply_denoiser(cfg.get("denoiser"), rec, seed=seed, dtype=dtype, device=device, clip=(0.0, 1.0))
    timings["seconds_denoise"] = den_metrics.pop("seconds_denoise")
    metrics: dict[str, Any] = {
        **scores(rec, den, x),
        "m": m,
        "n": n,
        "n_pixels": N,
        "measurement_ratio": m / N,
        **solver_metrics,
        "noise": noise,
        "seed": seed,
        "dtype": str(cfg.get("dtype", "float32")),
        "device": str(device),
        "target": str(cfg.target.image),
        **den_metrics,
        **timings,
    }
    write_npz(
        out_dir / "arrays.npz",
        truth=x,
        y=y,
        reconstruction=rec,
        reconstruction_unclipped=x_raw,
        denoised=den,
        **({"coefficients": gamma} if gamma is not None else {}),
    )
    _figure(y.cpu().numpy(), rec, den, x, metrics, out_dir / "figures" / "fig9_sim1.png")
    log.info(
        "sim1: PSNR %.2f dB (denoised %.2f dB, %s), SSIM %.3f, m=%d (%.0f%% of N=%d), %s, %.1f s",
        metrics["psnr"], metrics["psnr_denoised"], metrics["denoiser"], metrics["ssim"], m, 100 * m / N, N,
        f"K={metrics['omp_atoms']}" if solver_name == "omp" else f"{solver_name} {metrics['solver_iterations']} it.",
        sum(timings.values()),
    )
    return metrics


def light_curve_image(y: np.ndarray) -> np.ndarray:
    """The light curve ``y (m,)`` laid out row by row in a ``⌈√m⌉ × ⌈√m⌉`` image, padded with NaN
    (the paper's Fig. 9, first column)."""
    side = math.ceil(math.sqrt(len(y)))
    img = np.full(side * side, np.nan)
    img[: len(y)] = y
    return img.reshape(side, side)


def _figure(y: np.ndarray, rec: np.ndarray, den: np.ndarray, truth: np.ndarray, metrics: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(12.5, 3.4))
    panels = [
        (light_curve_image(y), f"light curve y (m = {metrics['m']})", None),
        (rec, f"reconstruction\nPSNR {metrics['psnr']:.2f} dB, SSIM {metrics['ssim']:.3f}", (0, 1)),
        (den, f"denoised ({metrics['denoiser']})\nPSNR {metrics['psnr_denoised']:.2f} dB, SSIM {metrics['ssim_denoised']:.3f}", (0, 1)),
        (truth, f"truth ({metrics['n']}×{metrics['n']})", (0, 1)),
    ]
    for ax, (img, title, lim) in zip(axes, panels):
        kw = {"vmin": lim[0], "vmax": lim[1]} if lim else {}
        ax.imshow(img, cmap="gray", interpolation="nearest", **kw)
        ax.set_title(title, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    if metrics["solver"] == "omp":
        title = f"Simulation 1: batch-OMP, K = {metrics['solver_n_nonzero_coefs']}" + (
            f", ε = {metrics['solver_epsilon']:.3g}" if metrics["solver_epsilon"] is not None else "")
    else:
        title = f"Simulation 1: {metrics['solver']}, {metrics['solver_iterations']} iterations" + (
            f", λ = {metrics['solver_lam']:g}·‖Aᵀy‖∞" if "solver_lam" in metrics else f", denoiser {metrics.get('solver_denoiser')}")
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path)
