"""The parametric family's finer parts (cssat.inversion.parametric: wings of several panels with gaps,
booms, a deck box, a free pair of unequal dishes): the shadowed light curve of the same satellite built
independently from cssat.scene.models' parts, closed volumes against their analytic sums, the soft
shadows against the ray cast, gradients against finite differences, and named errors."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility, param_names

PARTS = dict(dishes=2, dish_pair="free", wing_panels=3, booms=True, deck=True)
# a 3.2 x 3.0 x 4.2 m bus; wings of three 2.6 x 3.0 m panels with 0.12 m gaps on 1.8 m booms, at 20 deg;
# a 1.35 m reflector on +x tilted 27 deg, a 0.9 m one low on -x looking out (not its mirror image);
# a 1.0 x 0.8 x 0.8 m box on the Earth deck
GEOM = dict(a=1.6, b=1.5, c=2.1, length=2.6, width=3.0, hinge=math.radians(20), gap=1.8, cd_bus=0.35, cd_panel=0.1,
            dish_x=1.75, dish_y=0.0, dish_z=1.0, dish_tilt=math.atan2(0.5, 1.0), dish_azimuth=0.0, dish_radius=1.35,
            dish_depth=0.4, cd_dish=0.6, dish2_x=-1.7, dish2_y=-0.2, dish2_z=-0.4, dish2_tilt=math.atan2(1.0, 0.3),
            dish2_azimuth=math.pi, dish2_radius=0.9, dish2_depth=0.25, panel_gap=0.12, boom_width=0.1, deck_a=0.5,
            deck_b=0.4, deck_h=0.8)
CELLS = dict(divisions=2, dish_rings=4, dish_segments=16)


def _p(**over):
    g = dict(GEOM, **over)
    return np.array([g[k] for k in param_names(**PARTS)])


def _procedural(g):
    """The same satellite from cssat.scene.models' box, panel and dish (written here from the
    module docstring's geometry, not from the family's code), merged."""
    from cssat.scene.mesh import merge
    from cssat.scene.models import box, dish, panel

    a, b, c = g["a"], g["b"], g["c"]
    parts = [box((2 * a, 2 * b, 2 * c), divisions=2, cd=g["cd_bus"], cs=0.0)]
    h = g["hinge"]
    w = g["width"] * np.array([math.sin(h), 0.0, math.cos(h)])
    for side in (1, -1):
        for k in range(3):
            y0 = b + g["gap"] + k * (g["length"] + g["panel_gap"])
            u = np.array([0.0, side * g["length"], 0.0])
            origin = np.array([0.0, side * y0, 0.0]) - w / 2
            first, second, cells = (u, w, (1, 2)) if side > 0 else (w, u, (2, 1))  # ceil(2 / 3) = 1 cell along y
            parts.append(panel(first, second, origin, divisions=cells, cd=g["cd_panel"], cs=0.0))
    for side in (1, -1):
        parts.append(box((g["boom_width"], g["gap"], g["boom_width"]), center=(0.0, side * (b + g["gap"] / 2), 0.0),
                         divisions=1, cd=g["cd_bus"], cs=0.0))  # a thin boom: one cell a face
    parts.append(box((2 * g["deck_a"], 2 * g["deck_b"], g["deck_h"]), center=(0.0, 0.0, c + g["deck_h"] / 2), divisions=2,
                     cd=g["cd_bus"], cs=0.0))
    for pre in ("dish", "dish2"):
        t, phi = g[f"{pre}_tilt"], g[f"{pre}_azimuth"]
        axis = (math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t))
        parts.append(dish(g[f"{pre}_radius"], g[f"{pre}_depth"], center=(g[f"{pre}_x"], g[f"{pre}_y"], g[f"{pre}_z"]),
                          axis=axis, rings=4, segments=16, cd=g["cd_dish"], cs=0.0))
    return merge(parts)


def _directions(T, seed):
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(T, 3))
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    V = S + 0.6 * rng.normal(size=(T, 3))
    return S, V / np.linalg.norm(V, axis=1, keepdims=True)


def test_the_parts_light_curve_is_the_procedural_satellites_with_shadows():
    from cssat.optics.photometry import facet_brightness

    S, V = _directions(80, 0)
    p = torch.as_tensor(_p())
    y = box_wing_light_curve(p, S, V, box_wing_visibility(p, S, V, **CELLS, **PARTS), range_km=1e-3, irradiance=1.0,
                             **CELLS, **PARTS)
    ref = facet_brightness(_procedural(GEOM), S, V, range_km=1e-3, irradiance=1.0, shadows=True).sum(1)
    torch.testing.assert_close(y, ref, rtol=1e-9, atol=1e-12)
    # each part carries light or shadow: without the deck, or with the wing one 7.84 m panel, the curve moves
    for over, parts in (({}, dict(PARTS, deck=False)), ({"length": 3 * 2.6 + 0.24}, dict(PARTS, wing_panels=1))):
        q = np.array([dict(GEOM, **over)[k] for k in param_names(**parts)])
        other = box_wing_light_curve(torch.as_tensor(q), S, V, box_wing_visibility(q, S, V, **CELLS, **parts),
                                     range_km=1e-3, irradiance=1.0, **CELLS, **parts)
        assert float((other - ref).abs().max()) > 0.01 * float(ref.max())


def test_closed_volume_is_the_analytic_sum_of_bus_booms_and_deck():
    import trimesh

    m = box_wing_mesh(_p(), **CELLS, **PARTS)
    tm = trimesh.Trimesh(m.vertices, m.faces, process=True)
    vol = sum(abs(b.volume) for b in tm.split(only_watertight=True))
    g = GEOM
    expected = 8 * g["a"] * g["b"] * g["c"] + 2 * g["boom_width"] ** 2 * g["gap"] + 4 * g["deck_a"] * g["deck_b"] * g["deck_h"]
    assert vol == pytest.approx(expected, rel=1e-9)
    assert m.part_names == ("bus", "panel", "dish")
    # the wings' area: 2 wings x 3 panels x length x width, two-sided
    assert m.areas[m.part == 1].sum() == pytest.approx(2 * 2 * 3 * g["length"] * g["width"], rel=1e-12)


def test_soft_shadows_of_the_parts_tend_to_the_ray_cast():
    """At τ = 0.1 mm the soft visibility thresholded at ½ is Embree's on the bus, booms, deck and
    panels' sub-facets facing both the Sun and the observer (the dishes cast their aperture disk,
    so a few differ): ≥ 97 % agree, and there are shadows to get right."""
    from cssat.inversion.parametric import _geometry, box_wing
    from cssat.inversion.soft_shadow import soft_visibility

    S, V = _directions(150, 1)
    p = _p()
    hard = box_wing_visibility(p, S, V, **CELLS, **PARTS).numpy()
    soft = soft_visibility(p, S, V, tau=1e-4, **CELLS, **PARTS).numpy()
    v, f, part, _ = box_wing(torch.as_tensor(p), **CELLS, **PARTS)
    N, _ = _geometry(v, f)
    front = (((torch.as_tensor(S) @ N.T) > 1e-6) & ((torch.as_tensor(V) @ N.T) > 1e-6)).numpy()
    m = front & (part[None, :] < 2)
    assert 0.05 < 1 - hard[m].mean() < 0.5
    assert (hard[m] == (soft[m] > 0.5)).mean() >= 0.97


def test_the_parts_gradients_are_the_finite_differences():
    from cssat.inversion.soft_shadow import soft_visibility

    S, V = _directions(6, 2)
    names = param_names(**PARTS)
    kw = dict(divisions=1, dish_rings=2, dish_segments=6, **PARTS)
    p = torch.as_tensor(_p(), dtype=torch.float64)

    def y(q):
        return box_wing_light_curve(q, S, V, soft_visibility(q, S, V, tau=0.2, **kw), range_km=1e-3, irradiance=1.0, **kw)

    pt = p.clone().requires_grad_(True)
    (g,) = torch.autograd.grad(y(pt).sum(), pt)
    h = 1e-6
    for name in ("panel_gap", "boom_width", "deck_a", "deck_h", "dish2_x", "dish2_radius", "gap"):
        k = names.index(name)
        e = torch.zeros_like(p)
        e[k] = h
        fd = (float(y(p + e).sum()) - float(y(p - e).sum())) / (2 * h)
        assert float(g[k]) == pytest.approx(fd, rel=1e-5, abs=1e-9), name
        assert fd != 0.0, name


def test_bad_part_options_are_named():
    with pytest.raises(FieldError, match="dish_pair.*needs dishes=2"):
        param_names(1, dish_pair="free")
    with pytest.raises(FieldError, match="dish_pair"):
        param_names(2, dish_pair="unequal")
    with pytest.raises(FieldError, match="wing_panels"):
        param_names(wing_panels=0)
    with pytest.raises(FieldError, match="booms"):
        param_names(booms="yes")
    with pytest.raises(FieldError, match="params.panel_gap"):
        box_wing_mesh(_p(panel_gap=-0.1), **CELLS, **PARTS)
    with pytest.raises(FieldError, match="params.deck_h"):
        box_wing_mesh(_p(deck_h=0.0), **CELLS, **PARTS)
    with pytest.raises(FieldError, match="params"):
        box_wing_mesh(_p()[:-1], **CELLS, **PARTS)
    assert param_names(**PARTS) == tuple(GEOM)  # the documented order: box-wing, dishes, second dish, gap, boom, deck


def test_front_only_soft_visibility_gives_the_same_light_curve_and_gradient():
    """``front_only`` computes the soft shadows only where a sub-facet faces both the Sun and the
    observer: there it equals the dense computation, elsewhere 0; the light curve (whose
    ``(S·N)₊ (V·N)₊`` is 0 there) and its gradient are the dense one's to round-off."""
    from cssat.inversion.parametric import _geometry, box_wing
    from cssat.inversion.soft_shadow import soft_visibility

    S, V = _directions(40, 3)
    kw = dict(CELLS, **PARTS)
    p = torch.as_tensor(_p())
    dense = soft_visibility(p, S, V, tau=0.05, **kw)
    sparse = soft_visibility(p, S, V, tau=0.05, front_only=True, **kw)
    v, f, _, _ = box_wing(p, **kw)
    N, _ = _geometry(v, f)
    front = ((torch.as_tensor(S) @ N.T) > 0) & ((torch.as_tensor(V) @ N.T) > 0)
    assert 0.1 < float(front.double().mean()) < 0.6
    torch.testing.assert_close(sparse[front], dense[front], rtol=1e-12, atol=1e-14)
    assert float(sparse[~front].abs().max()) == 0.0
    grads = []
    for fo in (False, True):
        q = p.clone().requires_grad_(True)
        y = box_wing_light_curve(q, S, V, soft_visibility(q, S, V, tau=0.05, front_only=fo, **kw), **kw)
        grads.append((y.detach(), torch.autograd.grad(y.sum(), q)[0]))
    torch.testing.assert_close(grads[1][0], grads[0][0], rtol=1e-12, atol=0)
    torch.testing.assert_close(grads[1][1], grads[0][1], rtol=1e-9, atol=1e-20)
