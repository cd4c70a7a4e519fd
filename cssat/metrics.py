"""Image-quality metrics through scikit-image, in scikit-image's argument order
``(image_true, image_test)``, with an explicit data range.

Both accept numpy arrays or torch tensors:

* one image ``(H, W)`` → a float;
* a batch ``(B, H, W)`` or ``(B, C, H, W)`` (deepinv's layout) → a numpy array ``(B,)``, one value
  per image (for ``C > 1`` the channels of an image are scored together);
* one volume ``(k, n, n)`` with ``volume=True`` → a float (SSIM with a 3-D window, as
  ``skimage.metrics.structural_similarity`` on a 3-D array).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError

__all__ = ["psnr", "ssim"]


def float64_array(a: Any) -> np.ndarray:
    """``a`` (a tensor on any device, an array or a sequence) as a float64 numpy array."""
    if hasattr(a, "detach"):
        a = a.detach().cpu().numpy()
    return np.asarray(a, dtype=np.float64)


def _range(ref: np.ndarray, data_range: float | None) -> float:
    if data_range is None:
        data_range = float(ref.max() - ref.min())
    if not np.isfinite(data_range) or data_range <= 0:
        raise FieldError(
            "data_range", f"must be a positive finite number, got {data_range} "
            "(a constant reference image needs an explicit data_range)"
        )
    return float(data_range)


def _score(one, image_true, image_test, data_range: float | None, volume: bool):
    """Apply ``one(true, test, R, channel_axis)`` to an image, a volume, or each image of a batch."""
    ref, x = float64_array(image_true), float64_array(image_test)
    if x.shape != ref.shape:
        raise FieldError("image_test", f"shape {x.shape} differs from image_true's {ref.shape}")
    if not np.isfinite(x).all():
        raise FieldError("image_test", "contains NaN or Inf")
    if volume:
        if ref.ndim != 3:
            raise FieldError("image_true", f"volume=True needs a (k, n, n) volume, got shape {ref.shape}")
        return float(one(ref, x, _range(ref, data_range), None))
    if ref.ndim == 2:
        return float(one(ref, x, _range(ref, data_range), None))
    if ref.ndim == 3:
        return np.array([one(r, t, _range(r, data_range), None) for r, t in zip(ref, x)])
    if ref.ndim == 4:
        ch = None if ref.shape[1] == 1 else 0
        return np.array([one(r[0] if ch is None else r, t[0] if ch is None else t, _range(r, data_range), ch)
                         for r, t in zip(ref, x)])
    raise FieldError("image_true", f"expected (H, W), (B, H, W) or (B, C, H, W), got shape {ref.shape}")


def psnr(image_true: Any, image_test: Any, data_range: float | None = None, *, volume: bool = False) -> Any:
    """Peak signal-to-noise ratio in dB, ``10 log10(R² / MSE(image_test, image_true))``, in
    scikit-image's order (``skimage.metrics.peak_signal_noise_ratio``).

    ``data_range`` ``R`` is the span of possible values (1.0 for images in [0, 1]); when ``None``
    it is ``image_true.max() − image_true.min()`` (per image in a batch). Infinite for identical
    images. A float for one image or volume, an array ``(B,)`` for a batch (see the module).
    """
    from skimage.metrics import peak_signal_noise_ratio  # heavy: scikit-image, only for psnr()

    return _score(lambda r, t, R, ch: peak_signal_noise_ratio(r, t, data_range=R),
                  image_true, image_test, data_range, volume)


def ssim(image_true: Any, image_test: Any, data_range: float | None = None, *, volume: bool = False) -> Any:
    """Structural similarity (Wang et al. 2004) by ``skimage.metrics.structural_similarity``
    with its default 7×7 window (7×7×7 for a volume), in scikit-image's order; ``data_range``
    and the shapes as in :func:`psnr`."""
    from skimage.metrics import structural_similarity  # heavy: scikit-image, only for ssim()

    return _score(lambda r, t, R, ch: structural_similarity(r, t, data_range=R, channel_axis=ch),
                  image_true, image_test, data_range, volume)
