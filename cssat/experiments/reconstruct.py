"""The solver and denoiser stages: reconstruct → clip → denoise → score.

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

from cssat._checks import FieldError, choice_param
from cssat.experiments.context import as_field
from cssat.metrics import psnr, ssim
from cssat.physics import Centered
from cssat.recon import Problem
from cssat.sparse import MatrixOperator, as_operator

if TYPE_CHECKING:
    import torch


__all__ = ["Reconstruction", "reconstruct", "denoise", "scores", "solver_name", "is_positive", "IMAGE_RANGE"]

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
    denoiser (settings that do not fit this image, e.g. blocks larger than it) is a FieldError
    naming ``field``."""
    t = time.perf_counter()
    try:
        out, info = denoiser(x, None)
    except ValueError as err:
        raise FieldError(field, f"{err}") from err
    out = out.detach().double().cpu().numpy() if isinstance(out, Tensor) else np.asarray(out, dtype=np.float64)
    if out.shape != np.shape(x):
        raise FieldError(field, f"{solver_name(denoiser)} returned shape {out.shape} for an image of shape {np.shape(x)}")
    if clip is not None:
        out = np.clip(out, *clip)
    return out, {"denoiser": solver_name(denoiser), **info, "seconds_denoise": time.perf_counter() - t}


def is_positive(phi: Any) -> bool:
    """Whether a sensing matrix is a mean-1-like, positive one: its mean exceeds 3× its std (on
    its first 1024 rows)."""
    mat = as_operator(phi, "phi").matrix()[:1024]  # 1024 samples decide it
    return bool(mat.mean().abs() > 3 * mat.std())


def reconstruct(solver: Any, phi: Any, y: Tensor, shape: Sequence[int], *, denoiser: Any = None,
                field: str = "solver", center: bool | str = False, dtype: torch.dtype | None = None,
                noise_var: Tensor | None = None) -> Reconstruction:
    """Reconstruct the image of ``shape`` from the light curve ``y (m,)`` measured through ``phi``
    (an operator or a dense matrix) with ``solver``, clip it to [0, 1], and denoise it with
    ``denoiser`` (``None``: no denoising).

    ``center`` (``True``, ``False`` or ``"auto"``: when :func:`is_positive`) hands the solver the
    system centred on its common term (:class:`cssat.physics.Centered`: fluctuations + one
    total-flux row), formed in float64 and cast to ``dtype`` (default ``y``'s): give a float64
    ``phi`` and ``y`` to keep the fluctuations' digits when the solver runs in float32. Without
    centring, ``phi`` and ``y`` are cast to ``dtype`` when it differs from ``y``'s.

    Metrics: ``solver`` (its name), the scalars of the solver's info, ``seconds_solver``
    (``seconds_dictionary`` apart when the solver reports it), ``centered``, and those of
    :func:`denoise`.

    ``noise_var`` (``(m,)``, ``y``'s units squared): the noise variance of each sample, handed to
    the solver in its :class:`~cssat.recon.Problem` (mapped onto the centred rows when centred) —
    what the discrepancy principle fits to.
    """
    choice_param(center, "center", (True, False, "auto"))
    if center == "auto":
        center = is_positive(phi)
    dtype = dtype or y.dtype
    if center:
        cache = phi.__dict__.setdefault("_centered", {}) if hasattr(phi, "__dict__") else {}
        if dtype not in cache:  # one per operator and dtype: the grid's cells share Φ (and ADMM's factor)
            cache.clear()
            cache[dtype] = Centered(phi, dtype=dtype)
        op = cache[dtype]
        if noise_var is not None:
            noise_var = op.data_variance(noise_var)
        phi, y = op, op.data(y, dtype)
    elif dtype != y.dtype:
        phi, y = MatrixOperator(as_operator(phi, "phi").matrix().to(dtype)), y.to(dtype)
    problem = Problem(as_operator(phi, "phi"), tuple(shape), noise_var=noise_var)
    t = time.perf_counter()
    with as_field(field):
        x_raw, info = solver(problem, y)
    seconds = time.perf_counter() - t
    if not isinstance(x_raw, Tensor) or tuple(x_raw.shape[-len(shape):]) != tuple(shape):
        raise FieldError(field, f"{solver_name(solver)} returned {type(x_raw).__name__} of shape "
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
    out = {"psnr": psnr(truth, rec, data_range=1.0), "ssim": ssim(truth, rec, data_range=1.0)}
    if den is not None:
        out.update(psnr_denoised=psnr(truth, den, data_range=1.0), ssim_denoised=ssim(truth, den, data_range=1.0))
    return out
