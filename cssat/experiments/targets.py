"""The target stage: the object whose unknown the forward model measures (the ``target`` group).

:class:`ImageTarget` is an image, ``n × n`` (the paper's rendered TESS-like spacecraft, a
scikit-image test image or a file); the light-curve experiment's target is a mesh in a scenario
(:class:`cssat.experiments.scene.SceneTarget`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, int_param

__all__ = ["ImageTarget", "MIN_SIZE"]

#: the smallest target an experiment scores: SSIM's 7 × 7 window (and the denoisers' 8 × 8 blocks)
MIN_SIZE = 8


class ImageTarget:
    """A target image (``cssat.data.load_target``): ``image`` a file path (PNG, JPEG, …) or a
    built-in name, converted to gray, resized to ``size × size`` and scaled to ``[0, 1]``."""

    kind = "image"

    def __init__(self, image: str = "tess", size: int = 128):
        if not isinstance(image, str) or not image:
            raise FieldError("image", f"expected a file path or a built-in image name, got {image!r}")
        self.image = image
        self.size = int_param(size, "size", MIN_SIZE, 4096)
        self._array: np.ndarray | None = None

    def load(self) -> np.ndarray:
        """The image ``(size, size)`` float64 in ``[0, 1]`` (read once)."""
        from cssat.data import load_target  # heavy: cssat.data imports torch

        if self._array is None:
            self._array = load_target(self.image, self.size, field="image")
        return self._array

    def describe(self) -> dict[str, Any]:
        return {"target": self.image, "n": self.size, "n_pixels": self.size * self.size}

    def __repr__(self) -> str:
        return f"ImageTarget(image={self.image!r}, size={self.size})"
