"""Light curves of a scenario (paper Eq. 10): the scene's geometry in the body frame and the
facet brightnesses over time."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from cssat._checks import FieldError
from cssat.optics.earthshine import EARTH_RADIUS_KM, earthshine_brightness
from cssat.optics.photometry import facet_brightness
from cssat.scene.attitude import nadir_pointing_frame, to_body
from cssat.scene.mesh import Mesh, as_mesh
from cssat.scene.orbit import Scenario

if TYPE_CHECKING:
    from typing import Any

__all__ = ["LightCurve", "simulate_light_curve"]


@dataclass
class LightCurve:
    """``facets (T, F)`` brightness per facet (W/m² at the observer), ``sun``/``observer``
    ``(T, 3)`` body-frame unit vectors from the object, and the total ``flux (T,)`` = Eq. 10."""

    facets: torch.Tensor
    sun: np.ndarray
    observer: np.ndarray

    @property
    def flux(self) -> torch.Tensor:
        return self.facets.sum(1)


#: ``earthshine="auto"`` turns earthshine on below this altitude (km). The Earth's reflected light
#: on the satellite is at most ``albedo (R⊕/r)²`` of the Sun's (a full Earth, albedo 0.3): 0.7 % at
#: GEO, where over the default inversion geometry it is a median 5.6e-5 of the flux (max 0.3 %,
#: BENCHMARKS.md) — below the photometry's 0.1 % systematic floor — but 1.7 % at 20,000 km and up to
#: a quarter of the Sun's in LEO (1.9 % of the flux beside lumos-sat's LEO cases).
EARTHSHINE_AUTO_ALTITUDE_KM = 20_000.0


def earthshine_matters(scenario: Scenario) -> bool:
    """Whether ``earthshine="auto"`` adds earthshine: the satellite below
    :data:`EARTHSHINE_AUTO_ALTITUDE_KM` at some step (LEO and MEO; not GEO)."""
    alt = np.linalg.norm(np.asarray(scenario.r_sat, dtype=np.float64), axis=1) - EARTH_RADIUS_KM
    return bool(len(alt)) and float(alt.min()) < EARTHSHINE_AUTO_ALTITUDE_KM


def simulate_light_curve(mesh: Mesh, scenario: Scenario, shadows: bool = True, attitude: Any = None,
                         earthshine: bool | str = False, earth_albedo: float = 0.3, **kwargs: Any) -> LightCurve:
    """The atmosphere-free light curve of ``mesh`` in ``scenario``: Eq. 8–9 per facet with self-
    and observer-shadowing (``shadows``), the Earth's shadow (``scenario.sunlit``) and the
    observer's horizon (zero below it). ``attitude``: a :mod:`cssat.scene.attitudes` object
    (``frames(scenario)``) or body frames ``(T, 3, 3)``; default the paper's three-axis
    stabilised (nadir-pointing) attitude. ``earthshine``: add the sunlight the Earth (Lambertian,
    albedo ``earth_albedo``) reflects onto the facets (:mod:`cssat.optics.earthshine`; off by
    default — the paper's model has none); ``"auto"``: on where it matters, when the satellite comes
    below :data:`EARTHSHINE_AUTO_ALTITUDE_KM` (:func:`earthshine_matters`)."""
    mesh = as_mesh(mesh)
    if earthshine == "auto":
        earthshine = earthshine_matters(scenario)
    if attitude is None:
        frame = nadir_pointing_frame(scenario.r_sat, scenario.v_sat)
    elif hasattr(attitude, "frames"):
        frame = attitude.frames(scenario)
    else:
        frame = np.asarray(attitude, dtype=np.float64)
    if frame.shape != (len(scenario), 3, 3):
        raise FieldError("attitude", f"expected body frames of shape ({len(scenario)}, 3, 3), got {frame.shape}")
    sun = to_body(frame, scenario.sun_dir)
    obs = to_body(frame, scenario.obs_dir)
    b = facet_brightness(mesh, sun, obs, range_km=scenario.range_km, sun_range_km=scenario.sun_range_km,
                         sunlit=scenario.sunlit, shadows=shadows, **kwargs)
    if earthshine:
        b = b + earthshine_brightness(mesh, scenario.r_sat, scenario.r_sun, scenario.r_obs, rotation=frame,
                                      albedo=earth_albedo, brdf=kwargs.get("brdf"),
                                      materials=kwargs.get("materials")).to(b.dtype)
    b = b * torch.as_tensor(scenario.elevation_deg > 0, dtype=b.dtype)[:, None]
    return LightCurve(b, sun, obs)
