"""Optics layer: Eq. 8–9 by hand, shadows against brute-force ray casting, flux-preserving renders."""

import math

import numpy as np
import pytest
import torch

from cssat.optics import (
    SOLAR_IRRADIANCE_W_M2 as I0,
    apparent_magnitude,
    facet_brightness,
    render,
    shadow_mask,
)
from cssat.optics.photometry import AU_KM, SUN_RADIUS_KM
from cssat.scene import astra_like, box, merge, panel, random_unit_vectors


def plate():
    """A 1 m² square in the xy plane, normal +z (two triangles)."""
    return panel((1, 0, 0), (0, 1, 0), (-0.5, -0.5, 0), two_sided=False, cd=0.8, cs=0.2)


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def rot_y(deg):
    a = math.radians(deg)
    return np.array([math.sin(a), 0, math.cos(a)])


def test_flat_plate_lambert_by_hand():
    m = plate()
    sun = unit([[0, 0, 1], rot_y(30), rot_y(60)])
    obs = unit([rot_y(-45), rot_y(-20), rot_y(10)])
    r_km = 38_500.0
    b = facet_brightness(m, sun, obs, range_km=r_km).sum(1).numpy()
    cos_s = sun[:, 2]
    cos_v = obs[:, 2]
    expected = I0 * 1.0 / (math.pi * (r_km * 1e3) ** 2) * cos_s * 0.8 * cos_v
    np.testing.assert_allclose(b, expected, rtol=1e-12)
    # facing away from the Sun or the observer: dark
    dark = facet_brightness(m, unit([[0, 0, -1]]), unit([[0, 0, 1]])).sum()
    assert float(dark) == 0.0


def test_flat_plate_glint_window():
    """The paper's Eq. 9 (an option since the physical glint is the default): π·cs·(a/r_Sun)² within 0.5°."""
    m = plate()
    s = rot_y(40)
    mirror = np.array([-s[0], 0, s[2]])  # reflection of S about +z
    a = math.radians(40)
    lam = I0 / (math.pi * 1e6) * math.cos(a) * 0.8 * math.cos(a)
    spec = I0 / (math.pi * 1e6) * math.cos(a) * math.pi * 0.2 * (AU_KM / SUN_RADIUS_KM) ** 2
    for off_deg, glint in [(0.0, True), (0.4, True), (0.6, False)]:
        v = rot_y(-(40 + off_deg))
        b = float(facet_brightness(m, s[None], v[None], range_km=1.0, glint="paper").sum())
        cos_v = math.cos(math.radians(40 + off_deg))
        expect = I0 / (math.pi * 1e6) * math.cos(a) * 0.8 * cos_v + (spec if glint else 0.0)
        assert b == pytest.approx(expect, rel=1e-9), off_deg
    # off the plane of incidence by 0.6° at equal angles: no glint either
    v = unit(mirror + np.array([0, math.radians(0.6), 0]))
    b = float(facet_brightness(m, s[None], v[None], range_km=1.0, glint="paper").sum())
    assert b < 2 * lam


def test_bad_directions_are_refused():
    m = plate()
    with pytest.raises(ValueError, match="sun: row 1 has norm"):
        facet_brightness(m, [[0, 0, 1], [0, 0, 2]], [[0, 0, 1], [0, 0, 1]])
    with pytest.raises(ValueError, match="observer: expected unit vectors of shape"):
        facet_brightness(m, [[0, 0, 1]], [[0, 1]])
    with pytest.raises(ValueError, match="size"):
        render(m, [[0, 0, 1]], [[0, 0, 1]], 0)


def moller_trumbore_any(origins, dirs, tris, eps=1e-12):
    """Brute force: does each ray hit any triangle at t > 0?"""
    v0, v1, v2 = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = v1 - v0, v2 - v0
    hit = np.zeros(len(origins), bool)
    for k, (o, d) in enumerate(zip(origins, dirs)):
        p = np.cross(d, e2)
        det = np.einsum("fi,fi->f", e1, p)
        ok = np.abs(det) > eps
        inv = np.where(ok, 1.0 / np.where(ok, det, 1), 0)
        s = o - v0
        u = np.einsum("fi,fi->f", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("i,fi->f", d, q) * inv
        t = np.einsum("fi,fi->f", e2, q) * inv
        hit[k] = np.any(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9))
    return hit


def two_box_scene():
    # a small box in front of a large plate-like box: it shadows part of it
    return merge([box((4, 4, 0.2), divisions=4), box((1, 1, 1), center=(0.3, 0.2, 1.2), divisions=2)])


def test_shadow_mask_matches_brute_force_ray_casting():
    m = two_box_scene()
    rng = np.random.default_rng(0)
    sun = random_unit_vectors(6, rng)
    obs = random_unit_vectors(6, rng)
    sun[0] = unit([0.1, 0.05, 1.0])  # the small box shadows the plate
    obs[0] = unit([-0.2, 0.1, 1.0])
    vis = shadow_mask(m, sun, obs).numpy()
    off = 1e-5 * m.radius
    N, C = m.normals, m.centroids
    for t in range(len(sun)):
        front = (N @ sun[t] > 0) & (N @ obs[t] > 0)
        idx = np.flatnonzero(front)
        o = C[idx] + off * N[idx]
        blocked = moller_trumbore_any(o, np.tile(sun[t], (len(idx), 1)), m.triangles)
        blocked |= moller_trumbore_any(o, np.tile(obs[t], (len(idx), 1)), m.triangles)
        expect = np.zeros(len(m), bool)
        expect[idx] = ~blocked
        assert np.array_equal(vis[t], expect), t
    assert vis[0].sum() < ((N @ sun[0] > 0) & (N @ obs[0] > 0)).sum()  # some shadow in view 0


def test_convex_mesh_has_no_self_shadowing():
    m = box((1, 2, 3), divisions=3)
    rng = np.random.default_rng(1)
    sun, obs = random_unit_vectors(20, rng), random_unit_vectors(20, rng)
    with_shadows = facet_brightness(m, sun, obs, shadows=True)
    without = facet_brightness(m, sun, obs)
    torch.testing.assert_close(with_shadows, without, rtol=0, atol=0)


@pytest.mark.parametrize("size", [16, 64])
def test_pixel_sum_equals_light_curve(size):
    m = astra_like()
    rng = np.random.default_rng(2)
    sun, obs = random_unit_vectors(12, rng), random_unit_vectors(12, rng)
    b = facet_brightness(m, sun, obs, shadows=True, range_km=38_500.0)
    img = render(m, sun, obs, size, brightness=b, dtype=torch.float64)
    assert img.shape == (12, size, size)
    torch.testing.assert_close(img.sum((1, 2)), b.sum(1), rtol=1e-10, atol=0)
    assert bool((img >= 0).all())


def test_render_of_a_plate_facing_the_viewer_is_flat_and_the_right_size():
    m = plate()
    sun = obs = np.array([[0.0, 0.0, 1.0]])
    img = render(m, sun, obs, 40, fov_m=2.0, dtype=torch.float64, up=(0, 1, 0))[0]
    # 1 m square in a 2 m field of 40 px: 20 x 20 pixels; flat shading spreads each of the two
    # triangles' brightness evenly over its own pixels (the diagonal goes to one of them)
    lit = img > 0
    assert int(lit.sum()) == 400
    levels = torch.unique(img[lit])
    assert len(levels) == 2
    b = facet_brightness(m, sun, obs)[0]
    counts = [int((img == lv).sum()) for lv in levels]
    assert sorted(counts)[0] >= 180 and sum(counts) == 400
    for lv, n in zip(levels, counts):
        assert any(float(lv) * n == pytest.approx(float(bi)) for bi in b)


def test_render_hides_what_is_behind():
    # a near plate over a far plate, both facing the viewer: only the near one shows where they overlap
    near = panel((1, 0, 0), (0, 1, 0), (-0.5, -0.5, 1.0), two_sided=False)
    far = panel((2, 0, 0), (0, 2, 0), (-1, -1, 0.0), two_sided=False)
    m = merge([near, far])
    sun = obs = np.array([[0.0, 0.0, 1.0]])
    b = torch.zeros(1, len(m), dtype=torch.float64)
    b[0, :2] = 1.0  # near plate
    b[0, 2:] = 100.0  # far plate (much brighter)
    img = render(m, sun, obs, 40, fov_m=4.0, brightness=b, dtype=torch.float64, up=(0, 1, 0))[0]
    centre = img[15:25, 15:25]
    assert float(centre.max()) < 1.0  # the bright far plate is hidden in the middle
    assert float(img.sum()) == pytest.approx(202.0)


def test_apparent_magnitude_of_the_sun_from_its_spectrum():
    # Independent of cssat's constant: the Sun's V magnitude from its spectral irradiance at the
    # V band's effective wavelength, 550 nm (ASTM E-490: 1.86 W m⁻² nm⁻¹ at 1 AU), against the
    # V = 0 flux density 3.631e-11 W m⁻² nm⁻¹ (Bessell, Castelli & Plez 1998).
    m_sun = -2.5 * math.log10(1.86 / 3.631e-11)
    assert float(apparent_magnitude(I0)) == pytest.approx(m_sun, abs=0.05)
    # Pogson's law: a factor 1e-10 in flux is 25 magnitudes
    assert float(apparent_magnitude(I0 * 1e-10) - apparent_magnitude(I0)) == pytest.approx(25.0, abs=1e-12)


def test_threaded_ray_queries_equal_one_batch():
    pytest.importorskip("embreex")
    from cssat.optics.shadow_sampling import any_hit as _any_hit
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    m = astra_like()
    inter = RayMeshIntersector(m.to_trimesh(), scale_to_box=False)
    rng = np.random.default_rng(3)
    n = 150_000
    o = m.centroids[rng.integers(0, len(m), n)] + 1e-3 * rng.standard_normal((n, 3))
    d = random_unit_vectors(n, rng)
    torch.set_num_threads(2)
    try:
        threaded = _any_hit(inter, o, d, threaded=True)
    finally:
        torch.set_num_threads(1)
    assert np.array_equal(threaded, _any_hit(inter, o, d, threaded=False))
    assert 0 < threaded.mean() < 1


@pytest.mark.parametrize("size", [8, 48])
def test_numba_and_torch_renderers_agree(size):
    pytest.importorskip("numba")
    m = merge([astra_like(), box((3, 3, 3), center=(0, 0, 4), divisions=5)])
    rng = np.random.default_rng(7)
    sun, obs = random_unit_vectors(10, rng), random_unit_vectors(10, rng)
    b = facet_brightness(m, sun, obs, shadows=True, range_km=1.0)
    a = render(m, sun, obs, size, brightness=b, dtype=torch.float64, backend="numba")
    t = render(m, sun, obs, size, brightness=b, dtype=torch.float64, backend="torch")
    torch.testing.assert_close(a.sum((1, 2)), b.sum(1), rtol=1e-10, atol=0)
    # the same coverage, depth and tie rules: the same images up to float32 rounding at edges
    same = torch.isclose(a, t, rtol=1e-6, atol=1e-12)
    assert float(same.double().mean()) > 0.999
    with pytest.raises(ValueError, match="backend"):
        render(m, sun, obs, size, brightness=b, backend="opengl")
