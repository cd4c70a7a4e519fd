"""Earthshine against the Lambert sphere's closed form and its limits (cssat.optics.earthshine)."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.optics.earthshine import earth_patches, earthshine_brightness, earthshine_irradiance
from cssat.scene.mesh import Mesh

R = 6378.137
FAR_SUN = 1e13  # km: parallel rays


def lambert_sphere_irradiance(albedo, dist_km, alpha_deg, I0=1361.0):
    """(2/3) A I0 (R/D)^2 p(alpha), p = (sin a + (pi - a) cos a) / pi (Lambert sphere, written here)."""
    a = math.radians(alpha_deg)
    return 2 / 3 * albedo * I0 * (R / dist_km) ** 2 * (math.sin(a) + (math.pi - a) * math.cos(a)) / math.pi


@pytest.mark.parametrize("alpha", [0.0, 60.0, 120.0, 150.0])
def test_a_far_satellite_sees_a_lambert_sphere(alpha):
    D = 1e8
    a = math.radians(alpha)
    _, E = earthshine_irradiance([D, 0, 0], [FAR_SUN * math.cos(a), FAR_SUN * math.sin(a), 0.0], albedo=0.3)
    assert E.sum().item() == pytest.approx(lambert_sphere_irradiance(0.3, D, alpha), rel=2e-3)


def test_limits_new_earth_and_the_night_side():
    _, E = earthshine_irradiance([-1e8, 0, 0], [FAR_SUN, 0, 0])  # new Earth: the lit half faces away
    assert E.sum().item() < 1e-9 * lambert_sphere_irradiance(0.3, 1e8, 0.0)
    _, E = earthshine_irradiance([-(R + 500.0), 0, 0], [FAR_SUN, 0, 0])  # LEO over midnight: its cap is all dark
    assert E.sum().item() == 0.0
    _, E = earthshine_irradiance([R + 500.0, 0, 0], [FAR_SUN, 0, 0], albedo=0.0)
    assert E.sum().item() == 0.0


def test_the_patches_tile_the_visible_cap():
    r = R + 700.0
    n, dA = earth_patches(torch.tensor([[0.0, r, 0.0]], dtype=torch.float64), n_theta=8, n_phi=16)
    assert dA.sum().item() == pytest.approx(2 * math.pi * R**2 * (1 - R / r), rel=1e-12)
    assert torch.allclose(torch.linalg.vector_norm(n, dim=-1), torch.ones(1, 128, dtype=torch.float64))
    assert bool(((n[0] @ torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)) >= R / r - 1e-12).all())
    with pytest.raises(FieldError, match="sat_km"):
        earth_patches([100.0, 0.0, 0.0])


def _plate(normal, area=4.0, cd=0.6):
    n = np.asarray(normal, float)
    e1 = np.cross(n, [0, 0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    h = math.sqrt(area) / 2
    v = np.array([-h * e1 - h * e2, h * e1 - h * e2, h * e1 + h * e2, -h * e1 + h * e2])
    return Mesh(v, np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, cd), np.full(2, 0.3))


def test_a_far_plate_reflects_the_earth_as_a_lambertian_facet():
    # a plate facing the Earth far away: every patch is along -x, so the plate gets E from -x and
    # sends the observer E A (cd/pi) (N.l)(N.v) / r^2; the glint term of Eq. 8 is not used
    D, alpha = 1e8, 60.0
    a = math.radians(alpha)
    sat, sun = np.array([D, 0, 0]), np.array([FAR_SUN * math.cos(a), FAR_SUN * math.sin(a), 0.0])
    view = np.array([-0.6, 0.8, 0.0])
    obs = sat + 4e4 * view
    b = earthshine_brightness(_plate([-1, 0, 0]), sat, sun, obs).sum().item()
    E = lambert_sphere_irradiance(0.3, D, alpha)
    assert b == pytest.approx(E * 4.0 * 0.6 / math.pi * 1.0 * 0.6 / (4e4 * 1e3) ** 2, rel=3e-3)
    assert earthshine_brightness(_plate([1, 0, 0]), sat, sun, obs).sum().item() == 0.0  # the plate's back


def test_the_body_rotation_is_applied():
    # the same plate, the same light, turned: a body-frame plate with rotation equals the inertial plate
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    sat, sun, obs = np.array([R + 900.0, 300.0, 0.0]), np.array([FAR_SUN, FAR_SUN, 0.0]), np.array([R, 0.0, 100.0])
    inertial = earthshine_brightness(_plate([-1, 0, 0]), sat, sun, obs, n_theta=8, n_phi=16)
    body = earthshine_brightness(_plate(q @ np.array([-1.0, 0, 0])), sat, sun, obs, rotation=q, n_theta=8, n_phi=16)
    assert inertial.sum().item() > 0
    assert body.sum().item() == pytest.approx(inertial.sum().item(), rel=1e-10)
    with pytest.raises(FieldError, match="rotation"):
        earthshine_brightness(_plate([-1, 0, 0]), sat, sun, obs, rotation=np.eye(2))


def test_a_lambert_brdf_object_reflects_earthshine_as_the_diffuse_term():
    from cssat.optics import Lambert

    sat, sun, obs = np.array([R + 1200.0, 0.0, 500.0]), np.array([FAR_SUN, 0.3 * FAR_SUN, 0.0]), np.array([R, 200.0, 0.0])
    plate = _plate([-1.0, 0.2, 0.0], cd=0.35)
    diffuse = earthshine_brightness(plate, sat, sun, obs, n_theta=8, n_phi=16)
    lambert = earthshine_brightness(plate, sat, sun, obs, brdf=Lambert(0.35), n_theta=8, n_phi=16)
    assert diffuse.sum().item() > 0 and torch.allclose(lambert, diffuse, rtol=1e-12, atol=0)


@pytest.mark.cuda
def test_earthshine_and_magnitudes_follow_the_device():
    from cssat.optics import magnitude

    sat = torch.tensor([R + 1200.0, 0.0, 500.0], dtype=torch.float64)
    sun, obs = torch.tensor([FAR_SUN, 0.3 * FAR_SUN, 0.0], dtype=torch.float64), torch.tensor([R, 200.0, 0.0], dtype=torch.float64)
    cpu = earthshine_brightness(_plate([-1.0, 0.2, 0.0]), sat, sun, obs, n_theta=8, n_phi=16)
    gpu = earthshine_brightness(_plate([-1.0, 0.2, 0.0]), sat.cuda(), sun.cuda(), obs.cuda(), n_theta=8, n_phi=16)
    assert gpu.device.type == "cuda" and torch.allclose(gpu.cpu(), cpu, rtol=1e-10)
    assert magnitude(gpu.sum(1), "g", "AB").device.type == "cuda"


def test_auto_earthshine_is_on_in_leo_and_off_at_geo():
    """``earthshine="auto"``: a LEO light curve (ISS-like orbit, 400 km) gains the earthshine term
    computed directly; a GEO one is the shadowless Eq. 8–9 light curve unchanged."""
    from cssat.optics import simulate_light_curve
    from cssat.optics.lightcurve import earthshine_matters
    from cssat.scene import box, make_scenario

    leo = make_scenario(("1 25544U 98067A   20092.00000000  .00016717  00000-0  10270-2 0  9997",
                         "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391 56354"),
                        start_utc="2020-04-01T00:00:00", n_steps=288, step_s=300)
    geo = make_scenario(n_steps=288, step_s=300)
    assert earthshine_matters(leo) and not earthshine_matters(geo)
    mesh = box([2.0, 1.0, 1.0], cd=0.5, cs=0.0)
    frames = np.broadcast_to(np.eye(3), (288, 3, 3)).copy()
    off, auto = (simulate_light_curve(mesh, leo, shadows=False, attitude=frames, earthshine=e).facets for e in (False, "auto"))
    es = earthshine_brightness(mesh, leo.r_sat, leo.r_sun, leo.r_obs, rotation=frames)
    es = es * torch.as_tensor(leo.elevation_deg > 0, dtype=es.dtype)[:, None]
    assert float(es.sum()) > 0  # the satellite is up and earthlit at some step
    torch.testing.assert_close(auto - off, es.to(auto.dtype))
    g_off, g_auto = (simulate_light_curve(mesh, geo, shadows=False, attitude=frames, earthshine=e).flux for e in (False, "auto"))
    assert torch.equal(g_off, g_auto)
