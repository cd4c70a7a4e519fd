"""Optics: BRDF and visibility (Eq. 8–9), light curves (Eq. 10) and the z-buffer renderer.
Knows nothing of compressed sensing; the atmosphere (Eq. 11–12) lives in :mod:`cssat.physics`."""

from cssat.optics.lightcurve import LightCurve, simulate_light_curve
from cssat.optics.photometry import (
    SOLAR_IRRADIANCE_W_M2,
    apparent_magnitude,
    check_unit,
    facet_brightness,
    shadow_mask,
)
from cssat.optics.render import default_fov, image_basis, render

__all__ = [
    "LightCurve",
    "SOLAR_IRRADIANCE_W_M2",
    "apparent_magnitude",
    "check_unit",
    "default_fov",
    "facet_brightness",
    "image_basis",
    "render",
    "shadow_mask",
    "simulate_light_curve",
]
