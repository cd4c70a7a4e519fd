"""Image-quality metrics through scikit-image, with an explicit data range.

Both accept numpy arrays or torch tensors of one image ``(n, n)`` or one volume ``(k, n, n)``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["psnr", "ssim"]


def _np(a) -> np.ndarray:
    if hasattr(a, "detach"):
        a = a.detach().cpu().numpy()
    return np.asarray(a, dtype=np.float64)


def _range(ref: np.ndarray, data_range: float | None) -> float:
    if data_range is None:
        data_range = float(ref.max() - ref.min())
    if not np.isfinite(data_range) or data_range <= 0:
        raise ValueError(
            f"data_range: must be a positive finite number, got {data_range} "
            "(a constant reference image needs an explicit data_range)"
        )
    return float(data_range)


def _pair(x, ref):
    x, ref = _np(x), _np(ref)
    if x.shape != ref.shape:
        raise ValueError(f"x: shape {x.shape} differs from ref's {ref.shape}")
    if not np.isfinite(x).all():
        raise ValueError("x: contains NaN or Inf")
    return x, ref


def psnr(x, ref, data_range: float | None = None) -> float:
    """Peak signal-to-noise ratio in dB, ``10 log10(R² / MSE(x, ref))``.

    ``data_range`` ``R`` is the span of possible values (1.0 for images in [0, 1]); when ``None``
    it is ``ref.max() − ref.min()``. Infinite for identical images.
    """
    from skimage.metrics import peak_signal_noise_ratio

    x, ref = _pair(x, ref)
    return float(peak_signal_noise_ratio(ref, x, data_range=_range(ref, data_range)))


def ssim(x, ref, data_range: float | None = None) -> float:
    """Structural similarity (Wang et al. 2004) by ``skimage.metrics.structural_similarity``
    with its default 7×7 window; ``data_range`` as in :func:`psnr`."""
    from skimage.metrics import structural_similarity

    x, ref = _pair(x, ref)
    return float(structural_similarity(ref, x, data_range=_range(ref, data_range)))
