"""The pipeline every image experiment shares: measure → reconstruct → clip → denoise → score.

:func:`reconstruct` runs a solver object on a light curve and a denoiser object on its result;
:func:`denoise` runs a denoiser alone (sim3's 3-D stack); :func:`scores` gives the metrics of the
common schema (``psnr``, ``ssim``, ``psnr_denoised``, ``ssim_denoised``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from torch import Tensor

from cssat.experiments.common import ConfigError

if TYPE_CHECKING:
    import torch


__all__ = ["Reconstruction", "reconstruct", "denoise", "scores", "solver_name", "is_positive", "phi_stats"]

#: the experiments' images lie in [0, 1]
IMAGE_RANGE = (0.0, 1.0)


@dataclass
class Reconstruction:
    """What :func:`reconstruct` returns."""

    raw: Tensor  #: the solver's image, unclipped, ``shape``
    image: np.ndarray  #: the reconstruction clipped to the image range, float64
    denoised: np.ndarray  #: ``image`` denoised (and clipped), float64
    metrics: dict[str, Any] = field(default_factory=dict)  #: solver + denoiser settings and timings
    arrays: dict[str, Tensor] = field(default_factory=dict)  #: tensors the solver returned (coefficients)


def solver_name(obj: Any) -> str:
    """The name a solver or denoiser object reports (``name``, else its class name)."""
    return str(getattr(obj, "name", type(obj).__name__))


def denoise(denoiser: Any, x: np.ndarray, *, field: str = "denoiser",
            clip: tuple[float, float] | None = IMAGE_RANGE) -> tuple[np.ndarray, dict[str, Any]]:
    """``(denoised float64, metrics)``: ``denoiser(x)`` clipped to ``clip``; metrics hold
    ``denoiser``, ``seconds_denoise`` and what the denoiser reports. A ``ValueError`` of the
    denoiser (settings that do not fit this image, e.g. blocks larger than it) is a ConfigError
    naming ``field``."""
    t = time.perf_counter()
    try:
        out, info = denoiser(x, None)
    except ValueError as err:
        raise ConfigError(f"{field}: {err}") from err
    out = out.detach().double().cpu().numpy() if isinstance(out, Tensor) else np.asarray(out, dtype=np.float64)
    if out.shape != np.shape(x):
        raise ValueError(f"{field}: {solver_name(denoiser)} returned shape {out.shape} for an image of shape {np.shape(x)}")
    if clip is not None:
        out = np.clip(out, *clip)
    return out, {"denoiser": solver_name(denoiser), **info, "seconds_denoise": time.perf_counter() - t}


def phi_stats(cfg: Any, phi: Any, shape: Sequence[int]) -> dict[str, Any]:
    """:func:`cssat.physics.sensing_stats` of the run's Φ, as ``phi_stats`` says: ``true`` (all),
    ``false`` (none), ``auto`` (mean and scintillation index always; the effective rank and the
    coherence of ΦΨ when Φ has at most 2²⁴ entries, e.g. 64² pixels × 3277 samples — at 128² their
    SVD and Gram would cost minutes)."""
    from cssat.physics import sensing_stats

    mode = cfg.get("phi_stats", "auto")
    if mode not in (True, False, "auto"):
        raise ConfigError(f"phi_stats: expected true, false or auto, got {mode!r}")
    if mode is False:
        return {}
    mat = phi.matrix() if hasattr(phi, "matrix") else phi
    full = mode is True or mat.numel() <= 2**24
    return sensing_stats(mat, shape, full=full, max_rows=4096 if full else 1024)


def is_positive(phi: Any) -> bool:
    """Whether a sensing matrix is a mean-1-like, positive one: its mean exceeds 3× its std (on
    its first 1024 rows)."""
    mat = (phi.matrix() if hasattr(phi, "matrix") else phi)[:1024]  # 1024 samples decide it
    return bool(mat.mean().abs() > 3 * mat.std())


def reconstruct(solver: Any, phi: Any, y: Tensor, shape: Sequence[int], *, denoiser: Any = None,
                field: str = "solver", center: bool | str = False, dtype: torch.dtype | None = None) -> Reconstruction:
    """Reconstruct the image of ``shape`` from the light curve ``y (m,)`` measured through ``phi``
    with ``solver``, clip it to [0, 1], and denoise it with ``denoiser`` (``None``: no denoising).

    ``center`` (``True``, ``False`` or ``"auto"``: when :func:`is_positive`) hands the solver the
    system centred on its common term, :func:`cssat.physics.centered` (fluctuations + one total-flux
    row), formed in float64 and cast to ``dtype`` (default ``y``'s): give a float64 ``phi`` and
    ``y`` to keep the fluctuations' digits when the solver runs in float32.

    Metrics: ``solver`` (its name), the scalars of the solver's info, ``seconds_solver``
    (``seconds_dictionary`` apart when the solver reports it), ``centered``, and those of
    :func:`denoise`.
    """
    if center not in (True, False, "auto"):
        raise ConfigError(f"center: expected true, false or auto, got {center!r}")
    if center == "auto":
        center = is_positive(phi)
    if center:
        from cssat.physics import centered

        A, b = centered(phi.matrix() if hasattr(phi, "matrix") else phi, y)
        phi, y = A.to(dtype or y.dtype), b.to(dtype or y.dtype)
    elif dtype is not None:
        phi, y = (phi.matrix() if hasattr(phi, "matrix") else phi).to(dtype), y.to(dtype)
    t = time.perf_counter()
    x_raw, info = solver(phi, y, tuple(shape))
    seconds = time.perf_counter() - t
    if not isinstance(x_raw, Tensor) or tuple(x_raw.shape[-len(shape):]) != tuple(shape):
        raise ValueError(f"{field}: {solver_name(solver)} returned {type(x_raw).__name__} of shape "
                         f"{tuple(getattr(x_raw, 'shape', ()))}, expected an image tensor of shape {tuple(shape)}")
    arrays = {k: v for k, v in info.items() if isinstance(v, Tensor)}
    metrics: dict[str, Any] = {"solver": solver_name(solver), "centered": bool(center)}
    metrics.update({k: v for k, v in info.items() if k not in arrays})
    metrics["seconds_solver"] = seconds - float(info.get("seconds_dictionary", 0.0))
    image = x_raw.clamp(*IMAGE_RANGE).double().cpu().numpy()
    if denoiser is None:
        den, dm = image.copy(), {"denoiser": "none", "seconds_denoise": 0.0}
    else:
        den, dm = denoise(denoiser, image)
    metrics.update(dm)
    return Reconstruction(x_raw, image, den, metrics, arrays)


def scores(rec: np.ndarray, den: np.ndarray | None, truth: np.ndarray) -> dict[str, float]:
    """PSNR and SSIM of a reconstruction, and of its denoised version, against the truth (range 1)."""
    from cssat.metrics import psnr, ssim

    out = {"psnr": psnr(truth, rec, data_range=1.0), "ssim": ssim(truth, rec, data_range=1.0)}
    if den is not None:
        out.update(psnr_denoised=psnr(truth, den, data_range=1.0), ssim_denoised=ssim(truth, den, data_range=1.0))
    return out
