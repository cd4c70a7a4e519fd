"""Sun-tracking solar arrays: articulated parts posed per sample from the body-frame Sun."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.optics import facet_brightness, render
from cssat.scene import get_model
from cssat.scene.attitudes import ArticulatedMesh


def _cells(mesh):
    """Facet mask of the solar cells on the +y wing (the joint's facets that are cells)."""
    cell = mesh.part == mesh.part_names.index("solar_cell")
    wing = np.zeros(len(mesh), bool)
    wing[mesh.joints[0].facets] = True
    return cell & wing


def _projected(sun, axis):
    p = sun - (sun @ axis) * axis
    return p / np.linalg.norm(p)


@pytest.mark.parametrize("sun", [(0.3, 0.2, 0.9), (-0.8, -0.5, 0.1), (0.1, 0.9, -0.4), (0.0, -0.3, -1.0)])
def test_tracked_normal_is_the_sun_projected_on_the_plane_normal_to_the_axis(sun):
    mesh = get_model("astra_like", array_tracking="sun")
    assert isinstance(mesh, ArticulatedMesh)
    s = np.asarray(sun, float) / np.linalg.norm(sun)
    (idx, posed), = mesh.poses(s[None])
    normals = posed.normals[_cells(mesh)]
    want = _projected(s, np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(normals, np.broadcast_to(want, normals.shape), atol=1e-12)
    # brute force: no other drive angle brings the cells closer to the Sun
    angles = np.linspace(-180, 180, 361)
    best = max(angles, key=lambda a: float(mesh.posed([a, a]).normals[_cells(mesh)][0] @ s))
    got = mesh.angles_deg(s[None])[0, 0]
    assert abs((got - best + 180) % 360 - 180) <= 0.5 + 1e-9
    # the residual angle is the Sun's elevation out of the plane perpendicular to the axis
    assert math.degrees(math.acos(normals[0] @ s)) == pytest.approx(math.degrees(math.asin(abs(s[1]))), abs=1e-9)


def test_limits_stop_the_drive_at_the_limit_nearer_the_sun():
    mesh = get_model("astra_like", array_tracking="sun", array_limits_deg=[-30.0, 45.0])
    # the cells' normal at drive angle θ is (−cos θ, 0, sin θ): a Sun at θ = 60° is past +45, at −100° past −30
    for theta, want in ((60.0, 45.0), (-100.0, -30.0), (10.0, 10.0), (170.0, 45.0), (-170.0, -30.0)):
        s = np.array([-math.cos(math.radians(theta)), 0.0, math.sin(math.radians(theta))])
        brute = np.linspace(-30, 45, 7501)
        cosines = -np.cos(np.radians(brute)) * s[0] + np.sin(np.radians(brute)) * s[2]
        assert mesh.angles_deg(s[None])[0, 0] == pytest.approx(brute[np.argmax(cosines)], abs=0.011)
        assert mesh.angles_deg(s[None])[0, 0] == pytest.approx(want, abs=1e-9)


def test_fixed_is_todays_mesh_and_bad_options_are_named():
    a, b = get_model("astra_like"), get_model("astra_like", array_tracking="fixed")
    assert type(b) is type(a) and np.array_equal(a.vertices, b.vertices) and np.array_equal(a.cd, b.cd)
    with pytest.raises(FieldError, match="array_tracking.*fixed.*sun"):
        get_model("astra_like", array_tracking="moon")
    with pytest.raises(FieldError, match="array_limits_deg"):
        get_model("astra_like", array_tracking="sun", array_limits_deg=[30, -30])
    with pytest.raises(FieldError, match="array_limits_deg"):
        get_model("astra_like", array_tracking="sun", array_limits_deg=[0, 200])
    with pytest.raises(FieldError, match="array_tracking"):
        get_model("tess_like", array_tracking="sun")


def test_per_epoch_pose_in_the_photometry_and_the_renderer():
    """Each sample's brightness is that of the mesh posed for that sample's Sun (the facet order
    kept), and the rendered images hold the same flux."""
    mesh = get_model("astra_like", array_tracking="sun")
    rng = np.random.default_rng(1)
    sun = rng.normal(size=(5, 3))
    sun /= np.linalg.norm(sun, axis=1, keepdims=True)
    obs = sun + 0.2 * rng.normal(size=(5, 3))
    obs /= np.linalg.norm(obs, axis=1, keepdims=True)
    rng_km = np.array([36000.0, 36100.0, 36200.0, 36300.0, 36400.0])
    b = facet_brightness(mesh, sun, obs, range_km=rng_km, shadows=True)
    for t in range(5):
        ang = mesh.angles_deg(sun[t:t + 1])[0]
        one = facet_brightness(mesh.posed(ang), sun[t:t + 1], obs[t:t + 1], range_km=rng_km[t], shadows=True)
        torch.testing.assert_close(b[t:t + 1], one, rtol=0, atol=0)
    img = render(mesh, sun, obs, 32, brightness=b, dtype=torch.float64)
    torch.testing.assert_close(img.sum((1, 2)), b.sum(1), rtol=1e-9, atol=0)


def test_tracking_arrays_light_a_geo_night_and_brighten_it():
    """Over a night at GEO (phase angles < 90°, the observer on the Sun's side of the arrays) the
    tracked cells send a large share of the light to the observer; the fixed ones (near edge-on to
    the Sun) almost none, and the satellite is brighter with tracking at every lit sample."""
    from cssat.optics import simulate_light_curve
    from cssat.scene import make_scenario

    sc = make_scenario(start_utc="2020-04-01T20:00:00", n_steps=12, step_s=1800.0)
    lit = sc.sunlit > 0
    fluxes = {}
    for tracking in ("fixed", "sun"):
        mesh = get_model("astra_like", array_tracking=tracking)
        lc = simulate_light_curve(mesh, sc, shadows=True)
        cells = mesh.part == mesh.part_names.index("solar_cell")
        fluxes[tracking] = (lc.flux.numpy(), lc.facets[:, cells].sum(1).numpy())
    phase = np.degrees(np.arccos((sc.sun_dir * sc.obs_dir).sum(1)))
    assert (phase[lit] < 90).all()
    share = {k: v[1][lit] / v[0][lit] for k, v in fluxes.items()}
    assert (share["sun"] > 0.3).all()  # the cells' share of the light, tracked: about half
    assert (share["fixed"] < 0.05).all()  # fixed at 0°: edge-on to a Sun in the orbit plane at local midnight
    assert (fluxes["sun"][0][lit] > fluxes["fixed"][0][lit]).all()


def test_scaled_model_and_earthshine_follow_the_pose():
    from cssat.optics import earthshine_brightness

    mesh = get_model("astra_like", array_tracking="sun", scale=2.0)
    s = np.array([0.5, 0.3, -0.81])
    s /= np.linalg.norm(s)
    (_, posed), = mesh.poses(s[None])
    np.testing.assert_allclose(posed.normals[_cells(mesh)][0], _projected(s, np.array([0.0, 1.0, 0.0])), atol=1e-12)
    assert mesh.radius == pytest.approx(2 * get_model("astra_like").radius)
    # earthshine: each sample against the mesh posed for the Sun seen from the satellite
    sat = np.array([[7000.0, 0.0, 0.0], [0.0, 7200.0, 100.0]])
    sun_km = np.array([1.5e8, 2e7, 0.0])
    obs = np.array([6378.0, 0.0, 0.0])
    got = earthshine_brightness(mesh, sat, sun_km, obs, n_theta=8, n_phi=16)
    for t in range(2):
        d = sun_km - sat[t]
        ang = mesh.angles_deg((d / np.linalg.norm(d))[None])[0]
        want = earthshine_brightness(mesh.posed(ang), sat[t], sun_km, obs, n_theta=8, n_phi=16)
        torch.testing.assert_close(got[t:t + 1], want, rtol=0, atol=0)
