"""Noise models of the light-curve sensor, applied in flux units (never in magnitudes)."""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

__all__ = ["NoiseModel", "NoNoise", "GaussianNoise"]


class NoiseModel:
    """``noise(y, generator) -> y_noisy`` for light curves ``y (B, m)``; all randomness from
    ``generator`` (a CPU ``torch.Generator``), so the same seed gives the same noise."""

    name = "noise"

    def __call__(self, y: Tensor, generator: torch.Generator) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """Flat settings for ``metrics.json`` (``noise``, ``noise_*``)."""
        return {"noise": self.name}


class NoNoise(NoiseModel):
    """Noiseless light curves: ``y`` is returned as it is."""

    name = "none"

    def __call__(self, y: Tensor, generator: torch.Generator | None = None) -> Tensor:
        return y

    def __repr__(self) -> str:
        return "NoNoise()"


class GaussianNoise(NoiseModel):
    """Additive white Gaussian noise, ``y + σ ε`` with ``ε ~ N(0, 1)`` per sample.

    ``sigma`` is absolute (in ``y``'s units, W/m² for a light curve); ``relative`` sets
    ``σ = relative · rms(y)`` per light curve instead (the pre-0.2 ``cs.noise``). Exactly one of
    the two may be non-zero; both zero (or null) is noiseless.

    Physics: a stand-in for the sum of shot, background and read noise at a high photon count;
    it ignores that shot noise grows with the flux (see the photometric model for that).
    """

    name = "gaussian"

    def __init__(self, relative: float | None = None, sigma: float | None = None):
        for field, v in (("relative", relative), ("sigma", sigma)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0):
                raise ValueError(f"{field}: expected null or a finite number >= 0, got {v!r}")
        if relative and sigma:
            raise ValueError(f"sigma: give either relative ({relative}) or sigma ({sigma}), not both")
        self.relative = float(relative or 0.0)
        self.sigma = float(sigma or 0.0)

    def __call__(self, y: Tensor, generator: torch.Generator) -> Tensor:
        if self.relative == 0 and self.sigma == 0:
            return y
        eps = torch.randn(*y.shape, generator=generator, dtype=y.dtype).to(y.device)
        if self.relative > 0:
            scale = y.pow(2).mean(-1, keepdim=True).sqrt() * self.relative
        else:
            scale = self.sigma
        return y + scale * eps

    def describe(self) -> dict[str, Any]:
        return {"noise": self.name, "noise_relative": self.relative, "noise_sigma": self.sigma}

    def __repr__(self) -> str:
        return f"GaussianNoise(relative={self.relative:g}, sigma={self.sigma:g})"
