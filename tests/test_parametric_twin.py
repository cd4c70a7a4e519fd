"""The box-wing's twin (cssat.inversion.parametric.box_wing_twin): the same object turned 180° about
the body z axis — the same vertices and the same unshadowed light curve as the original turned by
hand, for every family (the stage's refinement from both twins: test_parametric_spin)."""

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.inversion.parametric import (box_wing_light_curve, box_wing_mesh, box_wing_twin, box_wing_visibility,
                                        param_names)

VALUES = dict(a=1.2, b=1.0, c=1.8, length=6.0, width=2.0, hinge=0.5, gap=1.0, cd_bus=0.3, cd_panel=0.2,
              dish_x=1.3, dish_y=0.3, dish_z=0.4, dish_tilt=1.2, dish_azimuth=0.3, dish_radius=0.8, dish_depth=0.2,
              cd_dish=0.5, dish2_x=-1.1, dish2_y=-0.2, dish2_z=-0.5, dish2_tilt=1.0, dish2_azimuth=2.9,
              dish2_radius=0.6, dish2_depth=0.15, panel_gap=0.2, boom_width=0.2, deck_a=0.5, deck_b=0.4, deck_h=0.6)
FAMILIES = [dict(), dict(dishes=1), dict(dishes=2), dict(dishes=2, dish_pair="free"),
            dict(dishes=2, wing_panels=3, booms=True, deck=True)]
TURN = np.diag([-1.0, -1.0, 1.0])  # 180° about z: x, y -> -x, -y


def _unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: "-".join(f"{k}={v}" for k, v in f.items()) or "plain")
def test_the_twin_is_the_object_turned_half_a_turn(family):
    """Its mesh's vertices are the original's turned by R_z(π) (as sets), and its unshadowed light
    curve seen from directions turned alike equals the original's to rounding — the map of every
    signed parameter (hinge, dish places and axes, a mirror pair kept a mirror pair) checked against
    the geometry itself."""
    p = np.array([VALUES[n] for n in param_names(**family)])
    q = box_wing_twin(p, **family)
    a = np.sort(np.round(np.asarray(box_wing_mesh(p, **family).vertices) @ TURN, 9), axis=0)
    b = np.sort(np.round(np.asarray(box_wing_mesh(q, **family).vertices), 9), axis=0)
    assert a.shape == b.shape and np.allclose(a, b, atol=1e-7)
    rng = np.random.default_rng(3)
    S, V = _unit(rng, 40), _unit(rng, 40)

    def unshadowed(x, S_, V_):
        ones = torch.ones_like(torch.as_tensor(box_wing_visibility(x, S_, V_, **family)))
        return box_wing_light_curve(torch.as_tensor(x), S_, V_, ones, range_km=1e-3, irradiance=1.0, **family).numpy()

    y = unshadowed(p, S, V)
    assert np.abs(y).max() > 0
    np.testing.assert_allclose(unshadowed(q, S @ TURN, V @ TURN), y, rtol=0, atol=1e-12 * np.abs(y).max())
    np.testing.assert_allclose(box_wing_twin(q, **family), p, atol=1e-12)  # a half turn twice is no turn


def test_the_twin_refuses_what_has_no_twin():
    p = np.array([VALUES[n] for n in param_names()])
    with pytest.raises(FieldError, match="panels"):
        box_wing_twin(p, panels=1)
    with pytest.raises(FieldError, match="9 finite values"):
        box_wing_twin(p[:-1])
    with pytest.raises(FieldError, match="9 finite values"):
        box_wing_twin(np.where(np.arange(9) == 5, np.nan, p))
    with pytest.raises(FieldError, match="dish_pair"):
        box_wing_twin(p, dish_pair="free")
