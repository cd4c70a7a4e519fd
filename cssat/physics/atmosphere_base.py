"""What every atmosphere model shares: the :class:`Atmosphere` contract, the checks and reporting
of the positive, mean-1 models, and the helpers that draw their weights.

The models themselves are in :mod:`cssat.physics.atmosphere`, which also makes every name here
reachable by its path.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from cssat._checks import FieldError, float_param, opt
from cssat.sparse.operators import GaussianSensing, LinearOperator

__all__ = ["Atmosphere", "EMITTERS", "ARCSEC"]

#: what an atmosphere's columns weight: the resolved image's pixels or the mesh's facets
EMITTERS = ("pixels", "facets")


class Atmosphere:
    """A model of the atmospheric sensing matrix.

    Subclasses implement :meth:`operator`; ``emitters`` says what the columns weight
    (``"pixels"``: Eq. 12, the image experiments; ``"facets"``: Eq. 11, where a mesh is at hand).
    """

    name = "atmosphere"
    emitters = "pixels"
    #: whether the weights depend on the emitters' directions on the sky (a square image of pixels):
    #: such a model has no facet-wise form
    spatial = False

    def __init__(self, *, object_size_m: float | None = None, range_km: float | None = None):
        self._geometry(object_size_m, range_km)

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

    def _geometry(self, object_size_m: float | None, range_km: float | None) -> None:
        """Record the scene's geometry (every model takes it: the experiments' ``geometry``
        group); a model whose weights do not depend on where the emitters are ignores it."""
        self.object_size_m = opt(object_size_m, float_param, "object_size_m", 0.0, open_lo=True)
        self.range_km = opt(range_km, float_param, "range_km", 0.0, open_lo=True)


# --- for the physical models: positive transmission, mean 1 -------------------------------------

ARCSEC = math.pi / (180 * 3600)


def _geometry(object_size_m: float, range_km: float) -> float:
    """The image's angular size (rad) for an object of ``object_size_m`` at ``range_km``."""
    return float_param(object_size_m, "object_size_m", 0.0, open_lo=True) / (float_param(range_km, "range_km", 0.0, open_lo=True) * 1e3)


def _side(n: int) -> int:
    side = math.isqrt(n)
    if side * side != n:
        raise FieldError("n", f"this atmosphere needs a square image (n = side²), got n = {n}")
    return side


def _unit_normals(m: int, n: int, seed: int, dtype) -> Tensor:
    """``(m, n)`` standard normals, row ``t`` from its own generator (first rows independent of m)."""
    return GaussianSensing(m, n, seed=seed, dtype=dtype, std=1.0).weight


def _lognormal(g: Tensor, log_var: float) -> Tensor:
    """``exp(g − s²/2)``: mean 1 when ``g ~ N(0, s²)``."""
    return torch.exp(g - 0.5 * log_var)


class _PositiveAtmosphere(Atmosphere):
    """Shared checks and reporting of the mean-1 models."""

    def __init__(self, scintillation_index: float | None, diameter_m: float, airmass: float, exposure_s: float,
                 site_altitude_m: float, wavelength_m: float = 550e-9):
        float_param(diameter_m, "diameter_m", 0.0, open_lo=True)
        float_param(airmass, "airmass", 1.0, 40.0)  # 40: the horizon (an airmass of ~38)
        float_param(exposure_s, "exposure_s", 0.0)
        float_param(site_altitude_m, "site_altitude_m", -500.0, 8000.0)  # observatories: the Dead Sea to 5.6 km
        float_param(wavelength_m, "wavelength_m", 0.0, open_lo=True)
        if scintillation_index is not None:
            float_param(scintillation_index, "scintillation_index", 0.0)
        self.diameter_m, self.airmass, self.exposure_s = float(diameter_m), float(airmass), float(exposure_s)
        self.site_altitude_m, self.wavelength_m = float(site_altitude_m), float(wavelength_m)
        self.given_index = scintillation_index
        self._profile_index: float | None = None

    @property
    def scintillation_index(self) -> float:
        """σ_I², given or (null) the continuous HV 5/7 profile's for this telescope
        (:func:`cssat.physics.turbulence.scintillation_index`, the same for every model)."""
        if self.given_index is not None:
            return float(self.given_index)
        if self._profile_index is None:
            from cssat.physics.turbulence import scintillation_index  # heavy: cssat.physics.turbulence imports scipy

            self._profile_index = scintillation_index(self.diameter_m, self.airmass, self.exposure_s,
                                                      self.site_altitude_m, self.wavelength_m)
        return self._profile_index

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "atmosphere_scintillation_index_model": self.scintillation_index,
                "atmosphere_diameter_m": self.diameter_m, "atmosphere_airmass": self.airmass,
                "atmosphere_exposure_s": self.exposure_s}
