"""The parametric family with reflector dishes (cssat.inversion.parametric, dishes=1|2): the same
triangles as cssat.scene.models' procedural parts, the same shadowed light curve, and a fit that
recovers the dish size."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility, param_names
from cssat.inversion.parametric_fit import fit_box_wing
from cssat.optics.photometry import facet_brightness
from cssat.scene.mesh import merge
from cssat.scene.models import box, dish, panel

# astra_like's bus (2.6 x 2.4 x 3.6 m), a 9.1 m wing of 2.4 m on 1.5 m yokes at 20 deg, and its two
# 2.3 m reflectors: vertex (+-1.65, 0, 0.6), axis (+-0.35, 0, 1)
TILT = math.atan2(0.35, 1.0)
P = [1.3, 1.2, 1.8, 9.1, 2.4, math.radians(20), 1.5, 0.3, 0.1,
     1.65, 0.0, 0.6, TILT, 0.0, 1.15, 0.35, 0.25]


def _procedural(p, divisions, rings, segments):
    """The same satellite built from cssat.scene.models' parts (box, panel, dish), merged."""
    a, b, c, L, W, h, gap, cd_bus, cd_panel, x, y, z, t, phi, radius, depth, cd_dish = p
    parts = [box((2 * a, 2 * b, 2 * c), divisions=divisions, cd=cd_bus, cs=0.0)]
    w = W * np.array([math.sin(h), 0.0, math.cos(h)])
    for side in (1, -1):
        u = np.array([0.0, side * L, 0.0])
        origin = np.array([0.0, side * (b + gap), 0.0]) - w / 2
        first, second = (u, w) if side > 0 else (w, u)
        parts.append(panel(first, second, origin, divisions=(divisions, divisions), cd=cd_panel, cs=0.0))
    for s in (1, -1):
        axis = (s * math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t))
        parts.append(dish(radius, depth, center=(s * x, y, z), axis=axis, rings=rings, segments=segments, cd=cd_dish, cs=0.0))
    return merge(parts)


def _dirs(n, seed):
    x = np.random.default_rng(seed).normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _geometry(n, seed):
    """Sun and observer at phase angles below 100 deg, the Sun above the bus's equator mostly."""
    S = _dirs(n, seed)
    V = S + 0.9 * _dirs(n, seed + 100)
    return S, V / np.linalg.norm(V, axis=1, keepdims=True)


def test_same_triangles_as_the_procedural_parts():
    fam = box_wing_mesh(P, divisions=3, dishes=2)
    ref = _procedural(P, 3, 12, 40)
    assert np.array_equal(fam.faces, ref.faces)
    np.testing.assert_allclose(fam.vertices, ref.vertices, rtol=0, atol=1e-13)
    np.testing.assert_array_equal(fam.cd, ref.cd)
    assert fam.part_names == ("bus", "panel", "dish")


def test_reproduces_the_procedural_light_curve_with_shadows_to_round_off():
    S, V = _geometry(60, 1)
    p = torch.tensor(P, dtype=torch.float64)
    vis = box_wing_visibility(p, S, V, divisions=3, dishes=2)
    y = box_wing_light_curve(p, S, V, vis, divisions=3, dishes=2, range_km=36000.0)
    ref = facet_brightness(_procedural(P, 3, 12, 40), S, V, range_km=36000.0, shadows=True).sum(1)
    torch.testing.assert_close(y, ref, rtol=1e-10, atol=0)
    # the dishes carry light and shadow: without them the curve differs by more than 5 % rms
    no_dish = box_wing_light_curve(p[:9], S, V, box_wing_visibility(p[:9], S, V, divisions=3), divisions=3, range_km=36000.0)
    assert float(torch.sqrt(((no_dish - ref) ** 2).mean())) > 0.05 * float(torch.sqrt((ref**2).mean()))


def test_gradient_in_the_dish_parameters_matches_finite_differences():
    S, V = _geometry(10, 2)
    p = torch.tensor(P, dtype=torch.float64, requires_grad=True)
    kw = dict(divisions=2, dishes=2, dish_rings=4, dish_segments=12)
    vis = box_wing_visibility(p.detach(), S, V, **kw)
    w = torch.as_tensor(np.random.default_rng(3).normal(size=10))
    (grad,) = torch.autograd.grad((box_wing_light_curve(p, S, V, vis, **kw) * w).sum(), p)
    h = 1e-6
    for k in range(9, 17):
        e = torch.zeros(17, dtype=torch.float64)
        e[k] = h
        f = lambda q: float((box_wing_light_curve(q, S, V, vis, **kw) * w).sum())  # noqa: E731
        assert float(grad[k]) == pytest.approx((f(p.detach() + e) - f(p.detach() - e)) / (2 * h), rel=1e-5, abs=1e-9), k


def test_fit_from_a_perturbed_start_recovers_the_dish_size():
    """Data: the procedural satellite's shadowed curve with 1 % noise; the albedos known (flux is
    albedo × area: a size needs an albedo prior), everything else fitted from a start with the
    dishes 30 % too wide and 40 % too shallow and the wings 15 % off."""
    kw = dict(divisions=2, dishes=2, dish_rings=6, dish_segments=16)
    S, V = _geometry(120, 5)
    clean = facet_brightness(_procedural(P, 2, 6, 16), S, V, range_km=1e-3, irradiance=1.0, shadows=True).sum(1).numpy()
    sigma = 0.01 * clean + 1e-3 * clean.max()
    y = clean + sigma * np.random.default_rng(6).normal(size=len(clean))
    p0 = np.array(P)
    p0[14] *= 1.3
    p0[15] *= 0.6
    p0[3] *= 1.15
    p0[4] *= 0.85
    p, info = fit_box_wing(y, S, V, p0, sigma=sigma, fixed=("cd_bus", "cd_panel", "cd_dish"), outer=4, inner=60, **kw)
    assert p[14] == pytest.approx(P[14], rel=0.10)
    assert info["rms_over_noise"] < 3.0  # the fit reaches the noise (the wings' length and width trade, their area fits)
    assert set(info["params"]) == set(param_names(2))


def test_bad_dish_options_are_named():
    with pytest.raises(FieldError, match="dishes"):
        box_wing_mesh(P, dishes=3)
    with pytest.raises(FieldError, match="params"):
        box_wing_mesh(P[:9], dishes=2)
    bad = list(P)
    bad[14] = -1.0
    with pytest.raises(FieldError, match="params.dish_radius"):
        box_wing_mesh(bad, dishes=2)
    with pytest.raises(FieldError, match="fixed"):
        fit_box_wing(np.ones(3), _dirs(3, 0), _dirs(3, 1), P, dishes=2, fixed=("cd_wing",))
