"""The box-wing's albedos solved by least squares (variable projection): ``box_wing_light_curve``'s
``by_part`` curves and ``fit_box_wing(albedos="profile")``, against scipy's bounded least squares
and the light curve's own linearity."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.optimize import lsq_linear

from cssat._checks import FieldError
from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility, param_names
from cssat.inversion.parametric_fit import fit_box_wing, profile_albedos

CELLS = dict(divisions=2, dishes=2, dish_rings=4, dish_segments=16)
P = np.r_[1.0, 0.8, 1.2, 3.0, 1.0, 0.3, 0.5, 0.35, 0.1, 1.2, 0.0, 0.5, 0.4, 0.0, 0.7, 0.2, 0.6]
UNIT = dict(range_km=1e-3, irradiance=1.0)


def _directions(T: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(T, 3))
    S /= np.linalg.norm(S, axis=1)[:, None]
    V = S + 0.4 * rng.normal(size=(T, 3))
    return S, V / np.linalg.norm(V, axis=1)[:, None]


def test_the_parts_curves_at_unit_albedo_sum_to_the_light_curve():
    S, V = _directions(120, 0)
    vis = box_wing_visibility(P, S, V, **CELLS)
    p = torch.as_tensor(P)
    Y = box_wing_light_curve(p, S, V, vis, by_part=True, **CELLS, **UNIT)
    y = box_wing_light_curve(p, S, V, vis, **CELLS, **UNIT)
    assert Y.shape == (120, 3)
    np.testing.assert_allclose((Y @ torch.tensor([0.35, 0.1, 0.6], dtype=torch.float64)).numpy(), y.numpy(), rtol=1e-12)
    Y2 = box_wing_light_curve(torch.as_tensor(P[:9]), S, V, None, by_part=True, divisions=2, **UNIT)
    assert Y2.shape == (120, 2) and bool((Y2 >= 0).all())


@pytest.mark.parametrize("seed", range(6))
def test_profiled_albedos_are_scipys_bounded_least_squares(seed):
    rng = np.random.default_rng(seed)
    T, P_ = 80, 3
    Y = rng.uniform(0, 1, (T, P_)) * rng.uniform(0.2, 3, P_)
    truth = rng.uniform(-0.3, 1.4, P_) if seed % 2 else rng.uniform(0.05, 0.9, P_)  # odd seeds: bounds active
    sg = rng.uniform(0.01, 0.05, T)
    y = Y @ truth + sg * rng.normal(size=T)
    got = profile_albedos(torch.as_tensor(Y), torch.as_tensor(y), torch.as_tensor(sg), torch.full((P_,), 0.3,
                          dtype=torch.float64), torch.ones(P_, dtype=torch.bool)).numpy()
    ref = lsq_linear(Y / sg[:, None], y / sg, bounds=(1e-4, 1.0), tol=1e-12, lsmr_tol="auto").x
    cost = lambda c: float(np.sum(((Y @ c - y) / sg) ** 2))  # noqa: E731
    assert cost(got) <= cost(ref) * (1 + 1e-9) + 1e-12  # one active-set pass reaches the bounded optimum here
    np.testing.assert_allclose(got, ref, atol=1e-6)


def test_a_held_albedo_stays_and_the_others_fit_around_it():
    S, V = _directions(150, 1)
    vis = box_wing_visibility(P, S, V, **CELLS)
    Y = box_wing_light_curve(torch.as_tensor(P), S, V, vis, by_part=True, **CELLS, **UNIT)
    y = Y @ torch.tensor([0.35, 0.1, 0.6], dtype=torch.float64)
    got = profile_albedos(Y, y, torch.ones_like(y), torch.tensor([0.35, 0.9, 0.9], dtype=torch.float64),
                          torch.tensor([False, True, True]))
    np.testing.assert_allclose(got.numpy(), [0.35, 0.1, 0.6], rtol=1e-9)


def test_a_profiled_fit_at_the_true_geometry_recovers_the_albedos():
    S, V = _directions(150, 2)
    vis = box_wing_visibility(P, S, V, **CELLS)
    y = box_wing_light_curve(torch.as_tensor(P), S, V, vis, **CELLS, **UNIT).numpy()
    p0 = P.copy()
    p0[[7, 8, 16]] = 0.3
    geometry = [n for n in param_names(2) if not n.startswith("cd_")]
    p, info = fit_box_wing(y, S, V, p0, sigma=0.01 * y.max() * np.ones_like(y), outer=1, inner=5, fixed=geometry,
                           albedos="profile", **CELLS)
    np.testing.assert_allclose(p[[7, 8, 16]], [0.35, 0.1, 0.6], rtol=1e-8)
    assert info["rms_over_noise"] < 1e-6
    assert math.isclose(info["params"]["cd_dish"], 0.6, rel_tol=1e-8)


def test_the_profile_gradient_is_the_finite_difference():
    S, V = _directions(60, 3)
    vis = box_wing_visibility(P, S, V, **CELLS)
    y = torch.as_tensor(box_wing_light_curve(torch.as_tensor(P), S, V, vis, **CELLS, **UNIT).numpy() * 1.1)
    sg = torch.full_like(y, 0.01)

    def loss(p):
        Y = box_wing_light_curve(p, S, V, vis, by_part=True, **CELLS, **UNIT)
        c = profile_albedos(Y, y, sg, p[[7, 8, 16]], torch.ones(3, dtype=torch.bool))
        return (((y - Y @ c) / sg) ** 2).mean()

    p = torch.as_tensor(P * 1.05).requires_grad_(True)
    (g,) = torch.autograd.grad(loss(p), p)
    for k in (0, 3, 14):  # a bus size, the panel length, the dish radius
        h = 1e-6 * float(P[k])
        e = torch.zeros_like(p)
        e[k] = h
        fd = (float(loss(p.detach() + e)) - float(loss(p.detach() - e))) / (2 * h)
        assert g[k].item() == pytest.approx(fd, rel=1e-4, abs=1e-8)


def test_a_bad_albedos_option_is_named():
    S, V = _directions(10, 4)
    with pytest.raises(FieldError, match="albedos"):
        fit_box_wing(np.ones(10), S, V, P[:9], albedos="solve", divisions=2)
    with pytest.raises(FieldError, match="free.*at most 6"):
        profile_albedos(torch.ones(5, 7), torch.ones(5), torch.ones(5), torch.zeros(7), torch.ones(7, dtype=torch.bool))


def test_the_experiments_settings_are_checked_and_reach_the_fit():
    """``inversion.parametric.albedos`` / ``albedo_prior``: refused by name when bad; with the prior
    the stage's bus albedo is ``cd0`` exactly, and profiled albedos lie within their bounds."""
    from types import SimpleNamespace

    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_mesh
    from cssat.models.egi.config import ParametricConfig

    with pytest.raises(FieldError, match=r"inversion\.parametric\.albedos.*fit.*profile"):
        ParametricConfig(albedos="solve")
    with pytest.raises(FieldError, match=r"inversion\.parametric\.albedo_prior"):
        ParametricConfig(albedo_prior="maybe")
    S, V = _directions(160, 5)
    p9 = P[:9]
    y = box_wing_light_curve(torch.as_tensor(p9), S, V, box_wing_visibility(p9, S, V, divisions=2), divisions=2,
                             **UNIT).numpy()
    N, A = egi(box_wing_mesh(p9, divisions=2))
    fit = np.arange(160) < 110
    m = SimpleNamespace(fit=fit, held=~fit, sigma=0.02 * y.mean() * np.ones_like(y), y=y, night=(~fit).astype(int))
    a = SimpleNamespace(sun_b=S, obs_b=V, metrics={"spin": "known"})
    sol = SimpleNamespace(res=SimpleNamespace(normals=N, areas=A), model_unit=np.zeros(160), metrics={})
    solve_parametric(ParametricConfig(divisions=2, outer=1, inner=10, cd0=0.25, albedos="profile", albedo_prior=True),
                     m, a, sol)
    assert sol.metrics["parametric_cd_bus"] == 0.25
    assert 1e-4 <= sol.metrics["parametric_cd_panel"] <= 1.0
