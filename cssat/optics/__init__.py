"""Optics: BRDF and visibility (Eq. 8–9), light curves (Eq. 10), the z-buffer renderer and the
atmosphere models (Eq. 11–12). Knows nothing of compressed sensing."""

from cssat.optics.atmosphere import atmosphere_weights, attenuated_facetwise, attenuated_pixelwise
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
    "atmosphere_weights",
    "attenuated_facetwise",
    "attenuated_pixelwise",
    "check_unit",
    "default_fov",
    "facet_brightness",
    "image_basis",
    "render",
    "shadow_mask",
    "simulate_light_curve",
]
