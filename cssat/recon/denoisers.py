"""Denoisers: post-processing of reconstructions (paper Fig. 9, third column) and the priors of
plug-and-play.

Every denoiser is an object with one call signature::

    denoised, info = denoiser(image, sigma=None)

``image`` is an image ``(H, W)`` or a stack ``(k, H, W)`` — a numpy array (numpy out, float64)
or a tensor (a tensor out, same dtype and device); ``sigma`` is the noise std in the image's own
units, estimated from the image (wavelet MAD, :func:`cssat.sparse.estimate_sigma`) when ``None``
and the denoiser has no ``sigma`` of its own; ``info`` is a flat dict for ``metrics.json``.
Settings are checked when the object is built, before any work. Build them from the ``denoiser``
config group (``_target_``) or directly.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, float_param, int_param, opt, progress_param
from cssat.sparse import estimate_sigma, ksvd_denoise
from cssat.sparse.denoise import DEMO_DEFAULTS, check_settings

if TYPE_CHECKING:
    from cssat._types import Array

__all__ = ["Denoiser", "SparseKSVD", "TVDenoiser", "WaveletDenoiser", "NLMDenoiser", "NoDenoiser"]



class Denoiser:
    """Base class: ``__call__(image, sigma=None) -> (denoised, info)``; subclasses implement
    :meth:`_denoise` on float64 numpy arrays (scikit-image) or override ``__call__``."""

    name = "denoiser"

    def __init__(self, sigma: float | None = None):
        self.sigma = opt(sigma, float_param, "sigma", 0.0, open_lo=True)

    def _sigma(self, x: np.ndarray, sigma: float | None) -> float:
        if sigma is not None:
            return float_param(sigma, "sigma", 0.0)
        return self.sigma if self.sigma is not None else estimate_sigma(x)

    def __call__(self, image: Array, sigma: float | None = None) -> tuple[Array, dict[str, Any]]:
        is_tensor = isinstance(image, Tensor)
        x = image.detach().double().cpu().numpy() if is_tensor else np.asarray(image, dtype=np.float64)
        _check_image(x)
        s = self._sigma(x, sigma)
        if s == 0:  # no noise (e.g. a constant image): nothing to remove, and the weights would divide by 0
            out, info = x.copy(), {"denoise_skipped": True}
        else:
            out, info = self._denoise(x, s)
        if is_tensor:
            out = torch.as_tensor(out, dtype=image.dtype, device=image.device)
        return out, {"denoise_sigma": s, **info}

    def _denoise(self, x: np.ndarray, sigma: float) -> tuple[np.ndarray, dict]:  # pragma: no cover
        raise NotImplementedError

    def check(self, shape: Sequence[int]) -> None:
        """Check the settings against an input of ``shape`` before any work (a FieldError)."""
        if len(shape) not in (2, 3):
            raise FieldError("image", f"expected an image (H, W) or a stack (k, H, W), got shape {tuple(shape)}")


def _check_image(x) -> None:
    if x.ndim not in (2, 3):
        raise FieldError("image", f"expected an image (H, W) or a stack (k, H, W), got shape {tuple(x.shape)}")


class NoDenoiser(Denoiser):
    """No post-processing: returns a copy of the image."""

    name = "none"

    def __call__(self, image: Array, sigma: float | None = None) -> tuple[Array, dict[str, Any]]:
        if isinstance(image, Tensor):
            return image.clone(), {}
        return np.array(image, dtype=np.float64, copy=True), {}


class TVDenoiser(Denoiser):
    """Total-variation denoising (Chambolle 2004; ``skimage.restoration.denoise_tv_chambolle``).
    ``weight`` in the image's units; default: the noise level σ (a good rule for this TV)."""

    name = "tv"

    def __init__(self, sigma: float | None = None, weight: float | None = None):
        super().__init__(sigma)
        self.weight = opt(weight, float_param, "weight", 0.0)

    def _denoise(self, x, sigma):
        from skimage.restoration import denoise_tv_chambolle  # heavy: scikit-image, only for _denoise()

        w = self.weight if self.weight is not None else sigma
        return denoise_tv_chambolle(x, weight=w), {"denoise_weight": w}


class WaveletDenoiser(Denoiser):
    """Wavelet shrinkage (BayesShrink, soft thresholds; ``skimage.restoration.denoise_wavelet``,
    needs PyWavelets)."""

    name = "wavelet"

    def _denoise(self, x, sigma):
        from skimage.restoration import denoise_wavelet  # heavy: scikit-image, only for _denoise()

        return denoise_wavelet(x, sigma=sigma, method="BayesShrink", mode="soft", rescale_sigma=True), {}


class NLMDenoiser(Denoiser):
    """Non-local means (``skimage.restoration.denoise_nl_means``, 5×5 patches, 13×13 search
    window, ``h = h_factor · σ``); a stack is denoised slice by slice."""

    name = "nlm"

    def __init__(self, sigma: float | None = None, h_factor: float = 0.8):
        super().__init__(sigma)
        self.h_factor = float_param(h_factor, "h_factor", 0.0)

    def _denoise(self, x, sigma):
        from skimage.restoration import denoise_nl_means  # heavy: scikit-image, only for _denoise()

        def one(s):
            return denoise_nl_means(s, h=self.h_factor * sigma, sigma=sigma, fast_mode=True, patch_size=5, patch_distance=6)

        return (np.stack([one(s) for s in x]) if x.ndim == 3 else one(x)), {}


class SparseKSVD(Denoiser):
    """Sparse K-SVD denoising in 2-D (an image) or 3-D (a stack), paper Eq. 16–21
    (:func:`cssat.sparse.ksvd_denoise`; Rubinstein, Zibulevsky & Elad 2010).

    ``None`` settings take KSVDSBox's demo values for the input's dimensionality
    (:data:`cssat.sparse.DEMO_DEFAULTS`: 2-D blocks 8×8, 100 atoms, T_dict 6, gain 1.15, 30000
    training blocks, 15 iterations, step 1; 3-D cubes, 1000 atoms, T_dict 16, gain 1.04, 80000
    blocks, step 2). A numpy image is computed as a tensor of ``dtype`` on ``device``; a tensor
    keeps its own. ``seed`` makes the training order reproducible.
    """

    name = "sparse_ksvd"

    #: the settings of :func:`cssat.sparse.ksvd_denoise` this denoiser passes on (``None``: its default)
    SETTINGS = ("block_size", "step", "n_atoms", "atom_sparsity", "gain", "n_train", "n_iter", "max_atoms", "lam")

    def __init__(self, sigma: float | None = None, *, seed: int = 0, dtype: str | torch.dtype = "float32",
                 device: str | torch.device = "cpu", progress: bool | None = None, **settings: Any):
        """``settings``: any of :data:`SETTINGS` — ``block_size``, ``step`` (int or per-axis ints),
        ``n_atoms``, ``atom_sparsity``, ``n_train``, ``n_iter``, ``max_atoms`` (ints ≥ 1), ``gain``
        (> 0), ``lam`` (≥ 0). ``progress``: tqdm bars of the training and the coding (``None``: on
        a terminal only)."""
        super().__init__(sigma)
        self.progress = progress_param(progress)
        unknown = sorted(set(settings) - set(self.SETTINGS))
        if unknown:
            raise FieldError(unknown[0], f"not a sparse-KSVD setting; expected one of {list(self.SETTINGS)}")
        self.kw: dict[str, Any] = {}
        for key in ("n_atoms", "atom_sparsity", "n_train", "n_iter", "max_atoms"):
            if settings.get(key) is not None:
                self.kw[key] = int_param(settings[key], key, 1)
        for key in ("block_size", "step"):
            v = settings.get(key)
            if v is not None:
                vals = [v] if not isinstance(v, Sequence) or isinstance(v, str) else list(v)
                t = tuple(int_param(u, key, 1) for u in vals)
                self.kw[key] = t[0] if len(t) == 1 else t
        if "step" in self.kw:  # the blocks are 8 a side unless given (both demos): a step past them leaves pixels out
            steps = np.atleast_1d(self.kw["step"])
            blocks = np.atleast_1d(self.kw.get("block_size", DEMO_DEFAULTS[2]["block"]))
            if (len(steps) == len(blocks) or 1 in (len(steps), len(blocks))) and np.any(steps > blocks):
                raise FieldError("step", f"{self.kw['step']} must not exceed the block size "
                                         f"{self.kw.get('block_size', DEMO_DEFAULTS[2]['block'])}, or pixels would be left out")
        if settings.get("gain") is not None:
            self.kw["gain"] = float_param(settings["gain"], "gain", 0.0, open_lo=True)
        self.kw["lam"] = float_param(settings.get("lam") or 0.0, "lam", 0.0)
        self.seed = int_param(seed, "seed", 0)
        if isinstance(dtype, str):
            if dtype not in ("float32", "float64"):
                raise FieldError("dtype", f"expected one of ['float32', 'float64'], got {dtype!r}")
            dtype = getattr(torch, dtype)
        self.dtype, self.device = dtype, torch.device(device)

    def check(self, shape: Sequence[int]) -> None:
        """Block and step sizes, atoms and training blocks against an input of ``shape``."""
        check_settings(shape, **self.kw)

    def __call__(self, image: Array, sigma: float | None = None) -> tuple[Array, dict[str, Any]]:
        is_tensor = isinstance(image, Tensor)
        x = image if is_tensor else torch.as_tensor(np.asarray(image), dtype=self.dtype, device=self.device)
        _check_image(x)
        if sigma is None:
            sigma = self.sigma
        out, info = ksvd_denoise(x, sigma, seed=self.seed, return_info=True, progress=self.progress, **self.kw)
        extra = {
            "denoise_sigma": info.sigma,
            "denoise_sigma_estimated": info.sigma_estimated,
            "denoise_mean_atoms": info.mean_atoms,
            "denoise_block_size": list(info.block_size),
            "denoise_train_rmse": info.training.rmse[-1] if info.training.rmse else None,
        }
        return (out if is_tensor else out.double().cpu().numpy()), extra
