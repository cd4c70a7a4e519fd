"""The specular term's energy: a real mirror (glint="physical") against the paper's Eq. 9."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.optics import facet_brightness
from cssat.optics.brdf import PaperBRDF
from cssat.optics.photometry import AU_KM, SOLAR_IRRADIANCE_W_M2, SUN_RADIUS_KM
from cssat.scene import Mesh

CS = 0.3
RANGE_KM = 1000.0


def _facet(cd=0.0, cs=CS):
    """One triangle in the x–y plane, normal +z, area 0.5 m²."""
    return Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), cd, cs)


def _reflected_fraction(brightness_of_views, incidence_deg, rho_max_deg=0.6, n_rho=3000, n_phi=48):
    """Brute-force quadrature over the viewing directions around the mirror direction R: the
    reflected power ∫ b(v) r² dΩ over the incident power ``I₀ A (S·N)``. Midpoint rule in polar
    coordinates about R: ``v = cos ρ R + sin ρ (cos φ e₁ + sin φ e₂)``, ``dΩ = sin ρ dρ dφ``."""
    th = math.radians(incidence_deg)
    sun = np.array([math.sin(th), 0.0, math.cos(th)])
    R = np.array([-math.sin(th), 0.0, math.cos(th)])
    e1, e2 = np.array([math.cos(th), 0.0, math.sin(th)]), np.array([0.0, 1.0, 0.0])
    drho, dphi = math.radians(rho_max_deg) / n_rho, 2 * math.pi / n_phi
    rho = (np.arange(n_rho) + 0.5) * drho
    phi = (np.arange(n_phi) + 0.5) * dphi
    P, F = np.meshgrid(rho, phi, indexing="ij")
    v = (np.cos(P)[..., None] * R + np.sin(P)[..., None] * (np.cos(F)[..., None] * e1 + np.sin(F)[..., None] * e2)).reshape(-1, 3)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    b = brightness_of_views(np.broadcast_to(sun, v.shape).copy(), v).numpy().reshape(n_rho, n_phi)
    power = (b * (RANGE_KM * 1e3) ** 2 * np.sin(P) * drho * dphi).sum()
    return power / (SOLAR_IRRADIANCE_W_M2 * 0.5 * math.cos(th))


@pytest.mark.parametrize("incidence_deg", [0.0, 30.0, 60.0])
@pytest.mark.parametrize("sun_range_km", [AU_KM, 0.7 * AU_KM])
def test_physical_glint_reflects_cs_of_the_incident_flux(incidence_deg, sun_range_km):
    mesh = _facet()
    frac = _reflected_fraction(lambda s, v: facet_brightness(mesh, s, v, range_km=RANGE_KM, sun_range_km=sun_range_km,
                                                             glint="physical"), incidence_deg)
    assert frac == pytest.approx(CS, rel=2e-3)


@pytest.mark.parametrize("incidence_deg", [0.0, 45.0])
def test_paper_glint_reflects_eleven_times_a_mirror(incidence_deg):
    """Eq. 9's energy: the 0.5° window's cap 2π(1 − cos 0.5°) times (r_Sun/a_Sun)² times C_s
    (11.06 C_s at 1 AU) — 11.06× a flat mirror's."""
    mesh = _facet()
    frac = _reflected_fraction(lambda s, v: facet_brightness(mesh, s, v, range_km=RANGE_KM, glint="paper"), incidence_deg)
    factor = 2 * math.pi * (1 - math.cos(math.radians(0.5))) * (AU_KM / SUN_RADIUS_KM) ** 2
    assert factor == pytest.approx(11.062, abs=1e-3)
    assert frac == pytest.approx(factor * CS, rel=2e-3)


@pytest.mark.parametrize("glint,factor", [("physical", 1.0), ("paper", None)])
def test_paper_brdf_object_has_the_same_energy(glint, factor):
    """The BRDF object (``brdf=paper``) integrated alike: ``I₀ A f (S·N)(V·N)/r²``."""
    brdf = PaperBRDF(cd=0.0, cs=CS, glint=glint)
    n = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)

    def views(s, v):
        f = brdf.evaluate(n, torch.as_tensor(s), torch.as_tensor(v))
        return SOLAR_IRRADIANCE_W_M2 * 0.5 * f * torch.as_tensor(s)[:, 2] * torch.as_tensor(v)[:, 2] / (RANGE_KM * 1e3) ** 2

    frac = _reflected_fraction(views, 20.0)
    if factor is None:
        factor = 2 * math.pi * (1 - math.cos(math.radians(0.5))) * (AU_KM / SUN_RADIUS_KM) ** 2
    assert frac == pytest.approx(factor * CS, rel=2e-3)


def test_physical_glint_radiance_is_cs_times_the_suns():
    """Inside the disk, the facet's radiance is C_s L_Sun, L_Sun = I₀/(π sin²α): the irradiance
    at the observer is C_s L_Sun A (V·N)/r²."""
    mesh = _facet()
    th = math.radians(40.0)
    sun = np.array([[math.sin(th), 0.0, math.cos(th)]])
    view = np.array([[-math.sin(th), 0.0, math.cos(th)]])
    b = float(facet_brightness(mesh, sun, view, range_km=RANGE_KM, glint="physical")[0, 0])
    L_sun = SOLAR_IRRADIANCE_W_M2 / (math.pi * (SUN_RADIUS_KM / AU_KM) ** 2)
    assert b == pytest.approx(CS * L_sun * 0.5 * math.cos(th) / (RANGE_KM * 1e3) ** 2, rel=1e-12)
    # just outside the disk (0.27° from R, the Sun's radius is 0.2665°): no glint
    tilt = th + math.radians(0.27)
    outside = np.array([[-math.sin(tilt), 0.0, math.cos(tilt)]])
    assert float(facet_brightness(mesh, sun, outside, range_km=RANGE_KM, glint="physical")[0, 0]) == 0.0


def test_glint_option_is_checked():
    with pytest.raises(FieldError, match="glint.*paper.*physical"):
        facet_brightness(_facet(), [[0, 0, 1.0]], [[0, 0, 1.0]], glint="mirror")
    with pytest.raises(FieldError, match="glint"):
        PaperBRDF(glint="mirror")
