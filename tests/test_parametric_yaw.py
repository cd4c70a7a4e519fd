"""The box-wing's turn about a searched spin's pole (``box_wing_yaw``): a searched spin's body frame
has z on the pole and an arbitrary phase, the family its panels along ±y. Checked against a
box-wing turned by a known angle: its exact EGI and the same binned onto a grid of normals; and
the experiment's parametric stage in such a frame, which fits the light curve only with the turn."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from cssat._checks import FieldError

P = np.array([1.0, 0.8, 1.3, 5.0, 1.6, math.radians(35), 0.5, 0.35, 0.15])


def _rz(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _mod(deg, period):
    """|deg| folded onto [0, period/2]: an angle's distance from 0 modulo ``period``."""
    return abs((deg + period / 2) % period - period / 2)


def _turned_egi(hinge_deg, psi0_deg, grid=0):
    from cssat.inversion.egi import egi, fibonacci_sphere
    from cssat.inversion.parametric import box_wing_mesh

    p = P.copy()
    p[5] = math.radians(hinge_deg)
    N, A = egi(box_wing_mesh(p, divisions=2))
    N = N @ _rz(psi0_deg).T  # the box-wing as a frame turned by psi0 about z sees it
    if grid:  # each facet's area onto its nearest normal of a Fibonacci grid (an EGI solved on a grid)
        G = fibonacci_sphere(grid).numpy()
        return G, np.bincount(np.argmax(N @ G.T, 1), A, len(G))
    return N, A


@pytest.mark.parametrize("hinge", [35.0, 0.0, -50.0])
@pytest.mark.parametrize("psi0", [0.0, 27.0, -63.0, 150.0])
def test_the_turn_is_the_panels_azimuth(hinge, psi0):
    """Panels not facing the pole: the true turn modulo 180° (a mirror pair is symmetric under a
    half turn) first — to 1e-9° from the exact EGI, to 2° from a 600-normal grid — and a quarter
    turn on second (where the bus outweighs the panels, below)."""
    from cssat.inversion.parametric_fit import box_wing_yaw

    psi, quarter = box_wing_yaw(*_turned_egi(hinge, psi0))
    assert _mod(math.degrees(psi) - psi0, 180.0) < 1e-9 and _mod(math.degrees(quarter - psi), 360.0) == pytest.approx(90.0)
    psi, _ = box_wing_yaw(*_turned_egi(hinge, psi0, grid=600))
    assert _mod(math.degrees(psi) - psi0, 180.0) < 2.0


def test_a_bus_heavier_than_the_panels_leaves_the_turn_among_the_candidates():
    """Small panels on a large bus: the heaviest direction is a bus face, not the panels' normal —
    the true turn is then the second candidate (mod 180°), not the first."""
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_mesh
    from cssat.inversion.parametric_fit import box_wing_yaw

    p = P.copy()
    p[[0, 1, 2, 3, 4]] = [2.0, 1.0, 2.5, 1.5, 0.6]  # ±y faces 4 × 5 m: 20 m² a side; the panels 0.9 m² a side
    p[5] = math.radians(60.0)
    N, A = egi(box_wing_mesh(p, divisions=2))
    for psi0 in (0.0, 27.0, -63.0):
        cands = box_wing_yaw(N @ _rz(psi0).T, A)
        assert _mod(math.degrees(cands[0]) - psi0, 180.0) > 45.0  # the first is the bus's ±y face: a quarter off
        assert min(_mod(math.degrees(c) - psi0, 180.0) for c in cands) < 1e-9


def test_the_best_turn_of_a_bus_heavier_than_the_panels_is_the_true_one():
    """Where the first candidate is a quarter off (the bus heavier), the misfit of a brief fit from
    each candidate's start on the light curve seen in the turned frame picks the true turn (mod
    180°) — where the start's own misfit picks the quarter turn (its cubic bus cannot show the
    heavy ±y faces; the panels' start takes them a quarter off instead) — and one turn given is
    returned as is; an empty list of turns, mismatched directions, a negative brief are refused."""
    import torch

    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility
    from cssat.inversion.parametric_fit import best_box_wing_yaw, box_wing_start

    p = P.copy()
    p[[0, 1, 2, 3, 4]] = [2.0, 1.0, 2.5, 3.0, 1.0]  # ±y faces 20 m² a side, the panels 6 m²
    p[5] = math.radians(60.0)
    N, A = egi(box_wing_mesh(p, divisions=2))
    rng = np.random.default_rng(1)
    S, V = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, 200, 3)))
    y = box_wing_light_curve(torch.as_tensor(p), S, V, box_wing_visibility(p, S, V, divisions=2), divisions=2,
                             range_km=1e-3, irradiance=1.0).numpy()
    for psi0 in (27.0, -63.0):
        R = _rz(psi0)
        psi, p0 = best_box_wing_yaw(N @ R.T, A, y, S @ R.T, V @ R.T, 0.01 * np.ones_like(y), divisions=2, brief=10)
        assert _mod(math.degrees(psi) - psi0, 180.0) < 1e-9
        start_only, _ = best_box_wing_yaw(N @ R.T, A, y, S @ R.T, V @ R.T, 0.01 * np.ones_like(y), divisions=2)
        assert _mod(math.degrees(start_only) - psi0, 180.0) == pytest.approx(90.0)
        turned = N @ R.T @ _rz(-math.degrees(psi)).T  # the start: box_wing_start of the EGI turned by R_z(−ψ)
        assert np.array_equal(p0, box_wing_start(turned, A))
    assert best_box_wing_yaw(N, A, y, S, V, yaws=(0.25,))[0] == 0.25
    with pytest.raises(FieldError, match="yaws"):
        best_box_wing_yaw(N, A, y, S, V, yaws=())
    with pytest.raises(FieldError, match="sun"):
        best_box_wing_yaw(N, A, y, S[:-1], V)
    with pytest.raises(FieldError, match="sigma"):
        best_box_wing_yaw(N, A, y, S, V, np.ones(len(y) - 1))
    with pytest.raises(FieldError, match="brief"):
        best_box_wing_yaw(N, A, y, S, V, brief=-1)


def test_panels_facing_the_pole_leave_a_quarter_turn_open_and_one_panel_a_half_turn():
    """Panels facing ±z (hinge 90°): a Lambertian EGI does not see their axis; the bus faces fix the
    frame modulo 90°, so the true turn is one of the two candidates (mod 180°). One panel: each
    candidate also turned by 180° (one panel at +y is not symmetric under it)."""
    from cssat.inversion.parametric_fit import box_wing_yaw

    for psi0 in (0.0, 27.0, -63.0):
        cands = box_wing_yaw(*_turned_egi(90.0, psi0))
        assert len(cands) == 2 and abs(abs(math.degrees(cands[1] - cands[0])) % 180 - 90) < 1e-9
        assert min(_mod(math.degrees(c) - psi0, 180.0) for c in cands) < 1e-9
    one = box_wing_yaw(*_turned_egi(35.0, 27.0), panels=1)
    assert len(one) == 4 and _mod(math.degrees(one[2] - one[0]), 360.0) == pytest.approx(180.0, abs=1e-9)
    assert min(_mod(math.degrees(c) - 27.0, 360.0) for c in one) < 1e-9  # one panel: the turn itself, not modulo 180°
    with pytest.raises(FieldError, match="areas"):
        box_wing_yaw(np.zeros((3, 3)), np.zeros(3))
    with pytest.raises(FieldError, match="panels"):
        box_wing_yaw(*_turned_egi(35.0, 0.0), panels=3)


def _stage(yaw, psi0=40.0, seed=0, truth=P, **cfg):
    """The experiment's parametric stage (``cfg``: more of its settings) on the box-wing ``truth``
    seen in a frame turned by ``psi0`` about z (as a searched spin's frame is), 2 % noise; returns
    the stage's metrics."""
    import torch

    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility
    from cssat.models.egi.config import ParametricConfig

    rng = np.random.default_rng(seed)
    S = rng.normal(size=(240, 3))
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    V = rng.normal(size=(240, 3))
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    clean = box_wing_light_curve(torch.as_tensor(truth), S, V, box_wing_visibility(truth, S, V, divisions=2),
                                 divisions=2, range_km=1e-3, irradiance=1.0).numpy()
    sigma = 0.02 * clean.mean() * np.ones_like(clean)
    y = clean + sigma * rng.normal(size=len(clean))
    R = _rz(psi0)  # the searched frame: the truth's vectors turned by psi0
    N, A = egi(box_wing_mesh(truth, divisions=2))
    fit = np.arange(240) < 160
    m = SimpleNamespace(fit=fit, held=~fit, sigma=sigma, y=y, night=(~fit).astype(int))
    a = SimpleNamespace(sun_b=S @ R.T, obs_b=V @ R.T, metrics={"spin": "search"})
    sol = SimpleNamespace(res=SimpleNamespace(normals=N @ R.T, areas=A), model_unit=np.zeros(240), metrics={})
    solve_parametric(ParametricConfig(**dict(dict(divisions=2, outer=2, inner=30, yaw=yaw), **cfg)), m, a, sol)
    return sol.metrics


def test_the_stage_in_a_turned_frame_fits_only_with_the_turn():
    """In frames turned 40° and −100° about z the stage with ``yaw=auto`` (a searched spin) finds
    the turn (mod 180°: a mirror pair's half turn is the family's hinge → −hinge) and gives the same
    fit in both (frame-invariant to 1e-6), as good as the stage in the truth's own frame (within
    10 %: the half-turned start takes another path); with ``yaw=none`` (the frame's own axes, right
    only for a known attitude) it misses the held-out samples by over 5× that — the family cannot
    turn its panels off ±y."""
    own = _stage("none", psi0=0.0)
    a40, a100 = _stage("auto"), _stage("auto", psi0=-100.0)
    assert _mod(a40["parametric_yaw_deg"] - 40.0, 180.0) < 1e-6 and _mod(a100["parametric_yaw_deg"] + 100.0, 180.0) < 1e-6
    assert a40["heldout_rms_over_noise"] == pytest.approx(a100["heldout_rms_over_noise"], rel=1e-6)
    assert a40["heldout_rms_over_noise"] == pytest.approx(own["heldout_rms_over_noise"], rel=0.1)
    # with one σ for every sample the held-out reduced χ² is the rms over the noise, squared
    assert a40["heldout_chi2_n"] == pytest.approx(a40["heldout_rms_over_noise"] ** 2, rel=1e-9)
    assert a40["fit_chi2_n"] == pytest.approx(a40["fit_rms_over_noise"] ** 2, rel=1e-9)  # and on the fitted samples
    assert a40["night_chi2_n"] == pytest.approx([a40["fit_chi2_n"], a40["heldout_chi2_n"]], rel=1e-9)  # night 0 fitted, 1 held out
    none = _stage("none")
    assert none["parametric_yaw_deg"] == 0.0 and none["heldout_rms_over_noise"] > 5 * own["heldout_rms_over_noise"]


def test_the_stage_s_multi_start_over_aspects_reaches_long_wings():
    """Wings 8 × 1 m, the attitude known (``yaw=none``): the multi-start over aspects (3.75, 8),
    both fitted in full (``plain_keep`` 2), keeps the true aspect's fit, which misses the fitted
    and the held-out samples by under 0.9× what the default start's (aspect 3.75) does (2.7 and
    2.1× the noise against 3.3 and 2.5×: the size–albedo valley's, not the aspect's); the start's
    aspect is reported."""
    p = P.copy()
    p[[3, 4]] = [8.0, 1.0]
    one = _stage("none", psi0=0.0, truth=p)
    multi = _stage("none", psi0=0.0, truth=p, aspects=[3.75, 8.0], plain_keep=2)
    assert one["parametric_start_aspect"] == pytest.approx(3.75) and multi["parametric_start_aspect"] == pytest.approx(8.0)
    for k in ("fit_rms_over_noise", "heldout_rms_over_noise"):
        assert multi[k] < 0.9 * one[k]


def test_a_bad_yaw_is_refused_by_name():
    from cssat.models.egi.config import ParametricConfig

    with pytest.raises(FieldError, match=r"inversion\.parametric\.yaw.*auto.*egi.*none"):
        ParametricConfig(yaw="sideways")
    with pytest.raises(FieldError, match=r"inversion\.parametric\.yaw_brief"):
        ParametricConfig(yaw_brief=-1)
    for bad in ([], [0.0], [3.0, -1.0], "long", [[2.0]]):
        with pytest.raises(FieldError, match=r"inversion\.parametric\.aspects.*\(0, 100\]"):
            ParametricConfig(aspects=bad)
    with pytest.raises(FieldError, match=r"inversion\.parametric\.plain_keep"):
        ParametricConfig(plain_keep=0)
    assert ParametricConfig(aspects=6).aspects == [6.0]
    from cssat.models.egi.config import InversionConfig

    with pytest.raises(FieldError, match=r"inversion\.parametric\.aspects.*shape=convex"):
        InversionConfig(shape="convex", parametric=dict(aspects=[2.0, 6.0]))
    for kw in (dict(shape="convex"), dict(shape="parametric", spin="known")):
        with pytest.raises(FieldError, match=r"inversion\.parametric\.refine_spin.*shape=parametric"):
            InversionConfig(parametric=dict(refine_spin=True), **kw)
    assert InversionConfig(shape="parametric", parametric=dict(refine_spin=True)).parametric.refine_spin


def test_the_starts_over_wing_aspects_rank_the_true_aspect_first_and_its_fit_ends_lower():
    """Long thin wings (length 8 × width 1 m): the convex EGI does not hold the wings' aspect, the
    default start's 3.75 is a basin of its own. ``box_wing_starts`` over aspects (2, 3.75, 8): each
    start's length ÷ width is its aspect, its loss (no brief fit) the χ² computed here, the list
    sorted by it; the true aspect's start ranks first, by the start's misfit and by a brief fit's
    loss, and fitted in full it ends at the noise where the default start's fit stays above it;
    bad aspects are refused by name."""
    import torch

    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility
    from cssat.inversion.parametric_fit import box_wing_start, box_wing_starts, fit_box_wing

    p = P.copy()
    p[[3, 4]] = [8.0, 1.0]
    N, A = egi(box_wing_mesh(p, divisions=2))
    rng = np.random.default_rng(1)
    S, V = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, 200, 3)))
    y = box_wing_light_curve(torch.as_tensor(p), S, V, box_wing_visibility(p, S, V, divisions=2), divisions=2,
                             range_km=1e-3, irradiance=1.0).numpy()
    sg = 0.01 * np.ones_like(y)
    starts = box_wing_starts(N, A, y, S, V, sg, yaws=(0.0,), aspects=(2.0, 3.75, 8.0), divisions=2)
    assert [round(s[2][3] / s[2][4], 9) for s in starts] == [8.0, 3.75, 2.0]
    for loss, psi, p0 in starts:
        assert psi == 0.0 and np.array_equal(p0, box_wing_start(N, A, aspect=p0[3] / p0[4]))
        m = box_wing_light_curve(torch.as_tensor(p0), S, V, box_wing_visibility(p0, S, V, divisions=2), divisions=2,
                                 range_km=1e-3, irradiance=1.0).numpy()
        assert loss == pytest.approx(float(np.sum(((y - m) / sg) ** 2)), rel=1e-12)
    assert [loss for loss, _, _ in starts] == sorted(loss for loss, _, _ in starts)
    briefly = box_wing_starts(N, A, y, S, V, sg, yaws=(0.0,), aspects=(2.0, 3.75, 8.0), divisions=2, brief=10)
    assert round(briefly[0][2][3] / briefly[0][2][4], 9) == 8.0
    fits = {a: fit_box_wing(y, S, V, box_wing_start(N, A, aspect=a), sigma=sg, divisions=2, outer=3, inner=40)[1]
            for a in (3.75, 8.0)}
    assert fits[8.0]["rms_over_noise"] < 1.1 < 1.3 < fits[3.75]["rms_over_noise"]
    assert len(box_wing_starts(N, A, y, S, V, yaws=(0.0,), aspects=5.0)) == 1
    for bad in ((), (0.0,), (-2.0,)):
        with pytest.raises(FieldError, match="aspects"):
            box_wing_starts(N, A, y, S, V, yaws=(0.0,), aspects=bad)
