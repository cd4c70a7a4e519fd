"""Optics: BRDFs (the paper's Eq. 8–9 and the analytic families of :mod:`cssat.optics.brdf`), visibility, light curves (Eq. 10) and the z-buffer renderer.
Knows nothing of compressed sensing; the atmosphere (Eq. 11–12) lives in :mod:`cssat.physics`."""

from cssat.optics.brdf import BRDF, AshikhminShirley, BlinnPhong, CookTorrance, Lambert, PaperBRDF, Phong
from cssat.optics.brdf_table import ABG, Binomial, fit_brdf, fit_brdf_file, read_brdf_table, write_brdf_table
from cssat.optics.earthshine import earthshine_brightness, earthshine_irradiance
from cssat.optics.lightcurve import LightCurve, simulate_light_curve
from cssat.optics.passbands import Passband, ab_magnitude_at, magnitude, std_magnitude, sun_magnitude
from cssat.optics.photometry import (
    SOLAR_IRRADIANCE_W_M2,
    apparent_magnitude,
    check_unit,
    facet_brightness,
    shadow_mask,
)
from cssat.optics.render import default_fov, image_basis, render

__all__ = [
    "BRDF",
    "Lambert",
    "Phong",
    "BlinnPhong",
    "CookTorrance",
    "AshikhminShirley",
    "PaperBRDF",
    "ABG",
    "Binomial",
    "fit_brdf",
    "fit_brdf_file",
    "read_brdf_table",
    "write_brdf_table",
    "LightCurve",
    "Passband",
    "ab_magnitude_at",
    "earthshine_brightness",
    "earthshine_irradiance",
    "magnitude",
    "std_magnitude",
    "sun_magnitude",
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
