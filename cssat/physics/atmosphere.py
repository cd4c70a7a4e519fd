"""Atmosphere models: the random transmission of each emitter's light flux, sample by sample.

An :class:`Atmosphere` draws the weights ``w[t, j]`` by which the flux of emitter ``j`` (a pixel of
the resolved image, or a facet of the mesh) reaches the sensor in light-curve sample ``t``: a
sensing matrix ``Φ (m, n)``. The light curve of a static scene ``x (n,)`` is ``y = Φx``
(paper Eq. 15); of a changing scene ``x_t``, ``y_t = Σⱼ Φ[t, j] x_t[j]`` (Eq. 11, 12).
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from cssat.sparse.operators import GaussianSensing, LinearOperator

__all__ = ["Atmosphere", "GaussianAtmosphere", "EMITTERS"]

#: what an atmosphere's columns weight: the resolved image's pixels or the mesh's facets
EMITTERS = ("pixels", "facets")


class Atmosphere:
    """A model of the atmospheric sensing matrix.

    Subclasses implement :meth:`operator`; ``emitters`` says what the columns weight
    (``"pixels"``: Eq. 12, the image experiments; ``"facets"``: Eq. 11, where a mesh is at hand).
    """

    name = "atmosphere"
    emitters = "pixels"

    def operator(
        self, m: int, n: int, *, seed: int = 0, dtype: torch.dtype | None = None, device: Any = None
    ) -> LinearOperator:  # pragma: no cover - abstract
        """The sensing operator ``Φ (m, n)`` for ``m`` samples of ``n`` emitters, drawn from ``seed``."""
        raise NotImplementedError

    def weights(
        self, m: int, n: int, *, seed: int = 0, dtype: torch.dtype | None = None, device: Any = None
    ) -> Tensor:
        """The dense weights ``Φ (m, n)`` (row ``t`` = sample ``t``)."""
        return self.operator(m, n, seed=seed, dtype=dtype, device=device).matrix()

    def describe(self) -> dict[str, Any]:
        """Flat settings for ``metrics.json`` (``atmosphere``, ``atmosphere_*``)."""
        return {"atmosphere": self.name, "atmosphere_emitters": self.emitters}


class GaussianAtmosphere(Atmosphere):
    """The paper's atmosphere (Eq. 11, 12, 15): i.i.d. Gaussian weights ``N(mean, std²)``, by
    default ``mean = 0`` and ``std = 1/√n`` for ``n`` emitters.

    Each row ``t`` is drawn from its own generator seeded by ``(seed, t)``
    (:class:`~cssat.sparse.GaussianSensing`): the first ``m`` rows do not depend on ``m``.

    Physics: a mathematical stand-in, not a model of turbulence. Real transmission is positive,
    with mean ≈ 1 and fluctuations of about 1 % (scintillation), and at GEO every pixel of a
    satellite sees nearly the same atmosphere; zero-mean weights imply negative fluxes. The
    paper uses this model because a Gaussian matrix satisfies the restricted isometry property.
    """

    name = "gaussian"

    def __init__(self, mean: float = 0.0, std: float | None = None, emitters: str = "pixels"):
        if isinstance(mean, bool) or not isinstance(mean, (int, float)) or not math.isfinite(mean):
            raise ValueError(f"mean: expected a finite number, got {mean!r}")
        if std is not None and (isinstance(std, bool) or not isinstance(std, (int, float))
                                or not math.isfinite(std) or std < 0):
            raise ValueError(f"std: expected null (1/√n) or a finite number >= 0, got {std!r}")
        if emitters not in EMITTERS:
            raise ValueError(f"emitters: expected one of {list(EMITTERS)}, got {emitters!r}")
        self.mean, self.std, self.emitters = float(mean), None if std is None else float(std), emitters

    def operator(self, m, n, *, seed=0, dtype=None, device=None) -> GaussianSensing:
        return GaussianSensing(m, n, seed=seed, dtype=dtype, device=device, mean=self.mean, std=self.std)

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "atmosphere_mean": self.mean, "atmosphere_std": self.std}

    def __repr__(self) -> str:
        return f"GaussianAtmosphere(mean={self.mean:g}, std={self.std}, emitters={self.emitters!r})"
