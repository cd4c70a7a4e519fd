"""The parametric box-wing (issue 36 point 2): its differentiable light curve against central
finite differences and against cssat's own Embree-shadowed facet photometry on a much finer
mesh; the volume IoU against an analytic two-box case."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility
from cssat.inversion.volume import volume_iou
from cssat.optics.photometry import facet_brightness
from cssat.scene.mesh import Mesh
from cssat.scene.models import box

P = [1.3, 1.2, 1.8, 9.0, 2.4, 0.5, 0.75, 0.3, 0.25]  # an Astra-like bus, 9 m wings at 29°


def _dirs(n, seed):
    x = np.random.default_rng(seed).normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def test_area_and_materials():
    m = box_wing_mesh(P, divisions=2)
    a, b, c, L, W = P[:5]
    assert m.areas.sum() == pytest.approx(8 * (a * b + b * c + a * c) + 2 * 2 * L * W, rel=1e-12)
    assert np.allclose(m.cd[m.part == 0], P[7]) and np.allclose(m.cd[m.part == 1], P[8])


def test_gradient_matches_finite_differences():
    S, V = _dirs(12, 1), _dirs(12, 2)
    p = torch.tensor(P, dtype=torch.float64, requires_grad=True)
    vis = box_wing_visibility(p.detach(), S, V, divisions=2)  # held fixed: the model's definition
    w = torch.as_tensor(np.random.default_rng(7).normal(size=12))  # a random projection of the (T,) output

    def f(q):
        return float((box_wing_light_curve(q, S, V, vis, divisions=2) * w).sum())

    (grad,) = torch.autograd.grad((box_wing_light_curve(p, S, V, vis, divisions=2) * w).sum(), p)
    h = 1e-6
    for k in range(len(P)):
        e = torch.zeros(len(P), dtype=torch.float64)
        e[k] = h
        fd = (f(p.detach() + e) - f(p.detach() - e)) / (2 * h)  # central differences
        assert float(grad[k]) == pytest.approx(fd, rel=1e-6, abs=1e-9), k


def test_shadowed_light_curve_against_embree_on_a_fine_mesh():
    S, V = _dirs(40, 3), _dirs(40, 4)
    p = torch.tensor(P, dtype=torch.float64)
    y = box_wing_light_curve(p, S, V, box_wing_visibility(p, S, V, divisions=8), divisions=8)
    ref = facet_brightness(box_wing_mesh(P, divisions=20), S, V, shadows=True).sum(1)
    unshadowed = box_wing_light_curve(p, S, V, None, divisions=8)
    rms = lambda x: float(torch.sqrt((x**2).mean()))  # noqa: E731
    assert rms(y - ref) <= 0.01 * rms(ref)
    assert rms(unshadowed - ref) > 0.05 * rms(ref)  # the shadows matter at these geometries


def test_refuses_bad_parameters():
    with pytest.raises(FieldError, match="params.width"):
        box_wing_mesh([1, 1, 1, 2, -1, 0, 0, 0.3, 0.3])
    with pytest.raises(FieldError, match="panels"):
        box_wing_mesh(P, panels=3)


def test_volume_iou_two_boxes():
    # two 2 m cubes overlapping by half along x: |A∩B| = 4, |A∪B| = 12 → 1/3
    iou = volume_iou(box((2, 2, 2)), box((2, 2, 2), center=(1, 0, 0)), n_points=20_000, align=False)
    assert iou == pytest.approx(1 / 3, abs=4 * math.sqrt((1 / 3) * (2 / 3) / (20_000 * 12 / 16)))
    # aligned: a translated copy of a box is the same volume
    assert volume_iou(box((2, 1, 1)), Mesh(box((2, 1, 1)).vertices + 5, box((2, 1, 1)).faces, 0.5, 0),
                      n_points=2_000) == 1.0
    # an open triangle has no volume: nothing is shared with the box; two of them, nothing to compare
    tri = Mesh(np.eye(3), [[0, 1, 2]], 0.5, 0.0)
    assert volume_iou(tri, box((1, 1, 1), center=(9, 9, 9)), n_points=100, align=False) == 0.0
    with pytest.raises(FieldError, match="watertight"):
        volume_iou(tri, Mesh(np.eye(3) + 4, [[0, 1, 2]], 0.5, 0.0), n_points=100, align=False)


def _with_runaway_panel(m, half_width):
    """``m`` plus a two-sided open plate ``2 half_width`` square in its z = 0 plane (no volume)."""
    h = float(half_width)
    v = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]]) + len(m.vertices)
    return Mesh(np.vstack([m.vertices, v]), np.vstack([m.faces, f]), 0.5, 0.0)


def test_volume_iou_ignores_a_runaway_open_panel():
    # a fitted 2×2×1 bus inside the true 2×2×2 one: IoU = 4/8 = 1/2 (analytic), whatever open
    # panel the fit carries. A 600 m plate once widened the sampling box so far that ~1 of 100,000
    # points fell inside either body and the estimate read 1.0.
    true, fit = box((2, 2, 2)), _with_runaway_panel(box((2, 2, 1), center=(0, 0, -0.5)), 300.0)
    iou, se = volume_iou(true, fit, n_points=100_000, align=False, return_stderr=True)
    assert se == pytest.approx(math.sqrt(0.25 / 100_000), rel=0.05)  # every point is in the union: the bodies' box
    assert iou == pytest.approx(0.5, abs=4 * se)
    # too few points in the union is refused by name, not printed as a number
    far = box((1, 1, 1), center=(2000, 0, 0))
    with pytest.raises(FieldError, match="n_points.*raise n_points"):
        volume_iou(box((1, 1, 1)), far, n_points=10_000, align=False)
    with pytest.raises(FieldError, match="min_union"):
        volume_iou(true, fit, n_points=1_000, min_union=0)
    with pytest.raises(FieldError, match="return_stderr: expected true or false"):
        volume_iou(true, fit, n_points=1_000, return_stderr="no")


def test_fit_recovers_an_in_class_box_wing():
    from cssat.inversion.parametric_fit import fit_box_wing

    S, V = _dirs(40, 5), _dirs(40, 6)
    p_true = np.array([1.0, 0.8, 1.2, 5.0, 1.5, 0.6, 0.5, 0.4, 0.3])
    y = box_wing_light_curve(torch.as_tensor(p_true), S, V, box_wing_visibility(p_true, S, V, divisions=2), divisions=2,
                             range_km=1e-3, irradiance=1.0).numpy()
    sigma = np.full_like(y, 1e-3 * y.std())
    p0 = p_true * np.r_[1.1, 0.9, 1.1, 0.9, 1.1, 1.15, 1.0, 1.0, 1.0]
    p, info = fit_box_wing(y, S, V, p0, sigma=sigma, divisions=2, outer=2, inner=30)
    assert abs(p[5] - p_true[5]) < 0.02  # the hinge (rad)
    assert info["rms_over_noise"] < 0.02 * np.sqrt(np.mean((y / sigma) ** 2))  # the fit explains > 98 % of the flux


def test_experiment_refuses_a_bad_shape_setting():
    from cssat.models.egi.config import EGISettings

    with pytest.raises(FieldError, match="inversion.shape"):
        EGISettings.from_config({"inversion": {"shape": "blob"}})
    with pytest.raises(FieldError, match="inversion.parametric.panels"):
        EGISettings.from_config({"inversion": {"shape": "parametric", "parametric": {"panels": 3}}})
    with pytest.raises(FieldError, match="inversion.parametric.wings"):
        EGISettings.from_config({"inversion": {"parametric": {"wings": 2}}})
    # a setting of the parametric fit without it (the convex shape): refused, not ignored, whichever setting
    for key, value in (("booms", True), ("dishes", 2), ("wing_panels", 3), ("deck", True), ("visibility", "soft"),
                       ("cd0", 0.5)):
        with pytest.raises(FieldError, match=rf"inversion\.parametric\.{key}: .*inversion\.shape=parametric"):
            EGISettings.from_config({"inversion": {"parametric": {key: value}}})
        s = EGISettings.from_config({"inversion": {"shape": "parametric", "parametric": {key: value}}})
        assert getattr(s.inversion.parametric, key) == value
    assert EGISettings.from_config({"inversion": {"parametric": {"booms": False}}}).inversion.shape == "convex"  # a default


def test_the_experiment_scores_no_iou_rather_than_a_wrong_one(caplog):
    # the inversion experiment's score: a refused estimate is written as None (and logged), not
    # raised at the end of a long fit nor printed as a number
    from types import SimpleNamespace

    from cssat.experiments.forward.egi_parametric import score_parametric
    from cssat.scene.mesh import merge

    # a fit whose two closed parts ran 1800 m apart: ~100 of 100,000 points inside either body
    apart = merge([box((0.1, 0.1, 0.1), center=(-900, 0, 0)), box((0.1, 0.1, 0.1), center=(900, 0, 0))])
    big = box((2, 2, 2))
    sol = SimpleNamespace(param_mesh=apart, res=SimpleNamespace(mesh=box((2, 2, 1))))
    with caplog.at_level("WARNING", logger="cssat"):
        out = score_parametric(big, sol, np.eye(3))
    assert out["shape_iou_true"] is None and "shape_iou_true not scored: n_points" in caplog.text
    assert out["convex_iou_true"] == pytest.approx(0.5, abs=0.02)  # a 2×2×1 box in a 2×2×2 one, aligned
