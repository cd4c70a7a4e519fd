"""The ``denoiser`` config group: post-processing of reconstructions (paper Fig. 9, third column).

``denoiser.name`` picks one of :data:`DENOISERS`; the other keys are that denoiser's settings
(``null`` = the denoiser's default). All work on an image ``(n, n)`` or a stack ``(k, n, n)`` in the
image's own units, and estimate the noise level when ``sigma`` is null.
"""

from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np

from cssat.experiments.common import ConfigError, require_float, require_int

__all__ = ["DENOISERS", "apply_denoiser", "scores"]


def _ksvd(x: np.ndarray, settings: dict, seed: int, dtype, device) -> tuple[np.ndarray, dict]:
    import torch

    from cssat.sparse import ksvd_denoise

    ints = ("n_atoms", "atom_sparsity", "n_train", "n_iter", "max_atoms")
    kw: dict[str, Any] = {}
    for key in ints:
        if settings.get(key) is not None:
            kw[key] = require_int(settings[key], f"denoiser.{key}", 1)
    for key in ("block_size", "step"):
        v = settings.get(key)
        if v is not None:
            vals = [v] if isinstance(v, (int, float, str)) else list(v)
            kw[key] = tuple(require_int(u, f"denoiser.{key}", 1) for u in vals)
            kw[key] = kw[key][0] if len(kw[key]) == 1 else kw[key]
    if settings.get("gain") is not None:
        kw["gain"] = require_float(settings["gain"], "denoiser.gain", lo=1e-6)
    kw["lam"] = require_float(settings.get("lam", 0.0) or 0.0, "denoiser.lam", lo=0.0)
    sigma = settings.get("sigma")
    if sigma is not None:
        sigma = require_float(sigma, "denoiser.sigma", lo=1e-12)
    xt = torch.as_tensor(x, dtype=dtype, device=device)
    try:
        out, info = ksvd_denoise(xt, sigma, seed=seed, return_info=True, **kw)
    except ValueError as err:  # bad settings for this image: a config error naming the field
        raise ConfigError(f"denoiser: {err}") from err
    extra = {
        "denoise_sigma": info.sigma,
        "denoise_sigma_estimated": info.sigma_estimated,
        "denoise_mean_atoms": info.mean_atoms,
        "denoise_block_size": list(info.block_size),
        "denoise_train_rmse": info.training.rmse[-1] if info.training.rmse else None,
    }
    return out.double().cpu().numpy(), extra


def _sigma(x: np.ndarray, settings: dict) -> float:
    from cssat.sparse import estimate_sigma

    s = settings.get("sigma")
    return require_float(s, "denoiser.sigma", lo=1e-12) if s is not None else estimate_sigma(x)


def _tv(x, settings, seed, dtype, device):
    from skimage.restoration import denoise_tv_chambolle

    sigma = _sigma(x, settings)
    # weight in the image's units; default: the noise level (a good rule for Chambolle's TV)
    w = settings.get("weight")
    w = require_float(w, "denoiser.weight", lo=0.0) if w is not None else sigma
    return denoise_tv_chambolle(x, weight=w), {"denoise_sigma": sigma, "denoise_weight": w}


def _wavelet(x, settings, seed, dtype, device):
    from skimage.restoration import denoise_wavelet

    sigma = _sigma(x, settings)
    return denoise_wavelet(x, sigma=sigma, method="BayesShrink", mode="soft", rescale_sigma=True), {"denoise_sigma": sigma}


def _nlm(x, settings, seed, dtype, device):
    from skimage.restoration import denoise_nl_means

    sigma = _sigma(x, settings)
    h = settings.get("h_factor")
    h = require_float(h, "denoiser.h_factor", lo=0.0) if h is not None else 0.8
    if x.ndim == 3:  # a stack: denoise each slice (scikit-image's 3-D NLM expects a volume)
        out = np.stack([denoise_nl_means(s, h=h * sigma, sigma=sigma, fast_mode=True, patch_size=5, patch_distance=6) for s in x])
    else:
        out = denoise_nl_means(x, h=h * sigma, sigma=sigma, fast_mode=True, patch_size=5, patch_distance=6)
    return out, {"denoise_sigma": sigma}


def _none(x, settings, seed, dtype, device):
    return np.array(x, dtype=np.float64, copy=True), {}


#: denoiser name -> function ``(x, settings, seed, dtype, device) -> (denoised, extra metrics)``.
DENOISERS: dict[str, Callable] = {
    "sparse_ksvd": _ksvd,
    "tv": _tv,
    "wavelet": _wavelet,
    "nlm": _nlm,
    "none": _none,
}


def apply_denoiser(
    cfg: Any, x: np.ndarray, *, seed: int = 0, dtype=None, device=None, clip: tuple[float, float] | None = None
) -> tuple[np.ndarray, dict]:
    """Denoise ``x`` (image or stack, float) as ``cfg`` (the ``denoiser`` group) says, then clip
    to the range ``clip`` if given (the experiments' images lie in [0, 1]).

    Returns ``(denoised, metrics)``; metrics hold ``denoiser``, ``seconds_denoise`` and what the
    denoiser reports (e.g. the noise level used). ``cfg = None`` means no denoising.
    """
    import torch

    settings = dict(cfg) if cfg is not None else {"name": "none"}
    name = settings.get("name", "none")
    if name not in DENOISERS:
        raise ConfigError(f"denoiser.name: expected one of {sorted(DENOISERS)}, got {name!r}")
    t = time.perf_counter()
    out, extra = DENOISERS[name](np.asarray(x, dtype=np.float64), settings, seed, dtype or torch.float32, device or "cpu")
    seconds = time.perf_counter() - t
    if clip is not None:
        out = np.clip(out, *clip)
    return out, {"denoiser": name, **extra, "seconds_denoise": seconds}


def scores(rec: np.ndarray, den: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """PSNR and SSIM of a reconstruction and of its denoised version against the truth (range 1)."""
    from cssat.metrics import psnr, ssim

    return {
        "psnr": psnr(rec, truth, data_range=1.0),
        "ssim": ssim(rec, truth, data_range=1.0),
        "psnr_denoised": psnr(den, truth, data_range=1.0),
        "ssim_denoised": ssim(den, truth, data_range=1.0),
    }
