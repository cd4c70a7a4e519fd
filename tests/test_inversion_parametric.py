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
    assert torch.autograd.gradcheck(lambda q: box_wing_light_curve(q, S, V, vis, divisions=2), (p,), eps=1e-6, atol=1e-9)


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
    iou = volume_iou(box((2, 2, 2)), box((2, 2, 2), center=(1, 0, 0)), n_points=20_000)
    assert iou == pytest.approx(1 / 3, abs=4 * math.sqrt((1 / 3) * (2 / 3) / (20_000 * 12 / 16)))
    with pytest.raises(FieldError, match="watertight"):
        volume_iou(box_wing_mesh(P).__class__(np.eye(3), [[0, 1, 2]], 0.5, 0.0), box((1, 1, 1), center=(9, 9, 9)), n_points=100)
