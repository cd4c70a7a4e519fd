"""The Sun's constants the optics layer shares (a module of its own, below photometry and
passbands, so that neither imports the other for them)."""

from __future__ import annotations

__all__ = ["SOLAR_IRRADIANCE_W_M2", "SUN_RADIUS_KM", "AU_KM", "SUN_MAGNITUDE_V"]

SOLAR_IRRADIANCE_W_M2 = 1361.0  # I₀, total solar irradiance at 1 AU (Kopp & Lean 2011)
SUN_RADIUS_KM = 695_700.0
AU_KM = 149_597_870.7
SUN_MAGNITUDE_V = -26.74  # apparent V magnitude of the Sun at 1 AU
