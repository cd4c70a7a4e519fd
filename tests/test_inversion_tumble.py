"""The tumbling spin-state search (issue 24, point 4): the motion's parametrisation against
torque_free and the motion's own measured periods, and a blind recovery of a synthetic tumbler."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cssat._checks import FieldError

SIDEREAL_DAY = 86164.0905


def _motion_case(i1, i2, alpha_deg, L_rate=0.02):
    from cssat.inversion.tumble import TumblingState, tumbling_rates

    a = math.radians(alpha_deg)
    fw, fp = (L_rate * f for f in tumbling_rates(i1, i2, a))
    return TumblingState(i1, i2, a, fw, fp, 0.0, 0.0, 90.0, 0.0, 0.0, "equatorial")


@pytest.mark.parametrize("alpha_deg", [20.0, 70.0])  # a short-axis and a long-axis mode
def test_motion_and_rates_against_torque_free(alpha_deg):
    """``TumblingState.motion`` equals torque_free from the same state (L along z), and its
    frequencies are those of the motion measured directly: ``f_ω`` from the upward zero crossings
    of ω_y (the sn component in either mode), ``f_φ`` from the unwrapped Euler precession angle
    ``φ = atan2(R₂₀, −R₂₁)`` over whole periods of ω."""
    from scipy.spatial.transform import Rotation

    from cssat.scene.attitude import rot_y, torque_free

    st = _motion_case(0.5, 0.8, alpha_deg)
    assert st.short_axis == (alpha_deg < 45.0)
    Ip = st.inertia
    Lb = np.array([math.sin(st.alpha), 0.0, math.cos(st.alpha)])
    T_w = 1.0 / st.f_omega_hz
    t = np.linspace(0.0, 40 * T_w, 40 * 400 + 1)
    R, om = torque_free(np.diag(Ip), Rotation.from_matrix(rot_y(-st.alpha).T).as_quat(), st.L_rate * Lb / Ip, t,
                        return_omega=True)
    assert np.abs(st.motion(t) - R).max() < 1e-6
    wy = om[:, 1]
    up = np.where((wy[:-1] < 0) & (wy[1:] >= 0))[0]
    cross = t[up] - wy[up] * (t[up + 1] - t[up]) / (wy[up + 1] - wy[up])
    P_meas = (cross[-1] - cross[0]) / (len(cross) - 1)
    assert P_meas == pytest.approx(T_w, rel=1e-6)
    phi = np.unwrap(np.arctan2(R[:, 2, 0], -R[:, 2, 1]))
    f_phi_meas = (phi[-1] - phi[0]) / (2 * np.pi * (t[-1] - t[0]))  # whole periods of the motion: exact mean
    assert f_phi_meas == pytest.approx(st.f_phi_hz, rel=1e-6)


def test_the_grid_s_rate_ratios_at_once_equal_them_one_by_one():
    """``_rate_ratios`` (a grid of mode angles in one array pass, for the root search's brackets)
    gives ``f_φ/f_ω`` of :func:`tumbling_rates` (held to torque_free's measured periods above) at
    every angle to rounding, in both modes, and nan exactly where it is nan (a steady spin, equal
    moments)."""
    from cssat.inversion.tumble_state import _rate_ratios
    from cssat.inversion.tumble import tumbling_rates

    rng = np.random.default_rng(0)
    cases = [(0.5, 0.8), (0.55, 0.85), (0.5, 0.5), (0.8, 1.0), (1.0, 1.0)]
    cases += [tuple(sorted(rng.uniform(0.06, 1.0, 2))) for _ in range(20)]
    for i1, i2 in cases:
        alphas = np.sort(rng.uniform(1e-4, math.pi / 2 - 1e-4, 9))
        got = _rate_ratios(i1, i2, alphas, 128)
        want = np.array([fp / fw if fw == fw else math.nan for fw, fp in (tumbling_rates(i1, i2, a, n=128) for a in alphas)])
        assert np.array_equal(np.isnan(got), np.isnan(want)), (i1, i2)
        assert np.allclose(got, want, rtol=1e-13, atol=0, equal_nan=True), (i1, i2)
    assert np.isnan(_rate_ratios(1.0, 1.0, np.array([0.3, 1.0]), 64)).all()  # a sphere: no tumbling


@pytest.mark.parametrize("frame", ["ecliptic", "equatorial"])
def test_invariants_of_a_torque_free_state(frame):
    """``torque_free_invariants`` of the initial state (q0, ω0, a scaled inertia tensor) of a
    ``TumblingState`` at its polhode crossing gives that state's moments, frequencies and ``L``; the
    angular momentum it reports is the one torque_free keeps fixed."""
    from scipy.spatial.transform import Rotation

    from cssat.inversion.spin import _separation_deg
    from cssat.inversion.tumble import TumblingState, torque_free_invariants, tumbling_rates
    from cssat.scene.attitude import torque_free

    i1, i2, a = 0.6, 0.75, math.radians(65.0)
    fw, fp = (0.015 * f for f in tumbling_rates(i1, i2, a))
    st = TumblingState(i1, i2, a, fw, fp, 0.0, -120.0, -35.0, 40.0, 0.0, frame)
    R0 = st.frames(np.zeros(1))[0]
    q0 = Rotation.from_matrix(R0.T).as_quat()
    w0 = st.L_rate * np.array([math.sin(a), 0.0, math.cos(a)]) / st.inertia
    inv = torque_free_invariants(np.diag(4000.0 * st.inertia), q0, w0, frame)
    assert inv["i1"] == pytest.approx(i1) and inv["i2"] == pytest.approx(i2) and not inv["short_axis"]
    assert inv["f_omega_hz"] == pytest.approx(fw, rel=1e-9) and inv["f_phi_hz"] == pytest.approx(fp, rel=1e-9)
    assert _separation_deg((inv["L_lon_deg"], inv["L_lat_deg"]), (-120.0, -35.0)) < 1e-6
    # the frames torque_free integrates from that state are the state's own
    t = np.linspace(0, 3000, 31)
    assert np.abs(torque_free(np.diag(4000.0 * st.inertia), q0, w0, t) - st.frames(t)).max() < 1e-6


def _box_wing_egi():
    """A closed box-wing EGI off any Fibonacci grid: ± pairs (Σ a n = 0), normals (8, 3)."""
    rot = np.array([[0.8, -0.36, 0.48], [0.6, 0.48, -0.64], [0.0, 0.8, 0.6]])  # orthogonal
    base = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]) @ rot.T
    panel = np.array([0.3, -0.5, 0.81])
    panel /= np.linalg.norm(panel)
    n = np.vstack([base, -base, panel, -panel])
    a = np.array([2.0, 3.0, 1.5, 2.0, 3.0, 1.5, 4.0, 4.0])
    return n, a


def _box_wing_tumbler(t, sun, obs):
    """The tests' tumbler (moments 0.55, 0.85, mode angle 22°, P_ω ≈ 1,050 s) and the box-wing's
    Lambertian flux ``(T,)`` at ``t`` seen along ``sun``, ``obs (T, 3)`` — written here with the
    EGI's sum, not cssat's operator."""
    from cssat.inversion.tumble import TumblingState, tumbling_rates

    alpha = math.radians(22.0)
    fw, fp = (0.021 * f for f in tumbling_rates(0.55, 0.85, alpha))
    truth = TumblingState(0.55, 0.85, alpha, fw, fp, 140.0, 40.0, 30.0, 75.0, 0.0, "equatorial")
    n, a = _box_wing_egi()
    R = truth.frames(t)
    sb, ob = np.einsum("tij,tj->ti", R, sun), np.einsum("tij,tj->ti", R, obs)
    return truth, (a / np.pi * np.clip(sb @ n.T, 0, None) * np.clip(ob @ n.T, 0, None)).sum(1)


@pytest.fixture(scope="module")
def tumbler():
    """Two 4-h arcs a day apart fitted, a third day's hour held out; GEO-like geometry (the
    observer turns once a sidereal day), 10 s cadence, 1 % noise."""
    from cssat.inversion.tumble import estimate_tumbling

    t = np.concatenate([np.arange(0, 14400, 10.0), 86400 + np.arange(0, 14400, 10.0), 2 * 86400 + np.arange(0, 3600, 10.0)])
    w = 2 * np.pi / SIDEREAL_DAY
    obs = np.stack([np.cos(w * t + 0.3), np.sin(w * t + 0.3), np.full_like(t, 0.12)], 1)
    obs /= np.linalg.norm(obs, axis=1, keepdims=True)
    sun = np.tile(np.array([0.95, -0.1, 0.3]) / np.linalg.norm([0.95, -0.1, 0.3]), (len(t), 1))
    truth, clean = _box_wing_tumbler(t, sun, obs)
    sig = 0.01 * clean.mean()
    y = clean + sig * np.random.default_rng(3).standard_normal(len(t))
    fit = t < 2 * 86400
    sol = estimate_tumbling(t[fit], y[fit], sun[fit], obs[fit], sigma=sig, frame="equatorial",
                            inertia_grid=[(0.45, 0.65), (0.65, 0.75), (0.45, 0.95), (0.65, 0.95), (0.85, 0.95), (0.35, 0.75)],
                            n_poles=40, coarse_samples=80, coarse_normals=32, n_pairs=2, screen_moments=4, screen_poles=12, n_screen=12, n_starts=6,
                            n_refine=3, mid_samples=150, mid_normals=64, n_normals=200, max_samples=400, arc_s=7200.0)
    return truth, sol, t, y, sun, obs, sig, fit


@pytest.mark.slow
def test_blind_recovery_of_a_tumbler(tumbler):
    """From the light curve alone (the lattice's frequency pairs searched, no moment of the grid
    is the truth's): L within 1° and within 5 of its reported 1σ, both periods within 1e-4, the
    moments within 0.03, the held-out day predicted within 2σ."""
    from cssat.inversion.spin import _separation_deg

    truth, sol, t, y, sun, obs, sig, fit = tumbler
    st = sol.state
    assert _separation_deg((st.lon_deg, st.lat_deg), (truth.lon_deg, truth.lat_deg)) < 1.0, sol
    assert abs(st.f_omega_hz / truth.f_omega_hz - 1) < 1e-4 and abs(st.f_phi_hz / truth.f_phi_hz - 1) < 1e-4, sol
    assert abs(st.i1 - truth.i1) < 0.03 and abs(st.i2 - truth.i2) < 0.03, sol
    assert st.short_axis
    held = ~fit
    pred = sol.predict(t[held], sun[held], obs[held])
    assert np.sqrt(np.mean((pred - y[held]) ** 2)) < 2 * sig
    assert sol.reduced_chi2 < 3.0  # 200 grid normals for 8 off-grid facets: the grid's bias, not the search
    sep = _separation_deg((st.lon_deg, st.lat_deg), (truth.lon_deg, truth.lat_deg))
    # the grid's bias is above the 1 % noise, so the verdict (no held-out data here: the fitted samples'
    # χ² against the χ²_{n-p} quantile) calls the model unreliable and withholds L's 1σ — though L is right
    assert sol.verdict == "unreliable" and "fitted samples" in sol.verdict_why, sol.verdict_why
    assert all(math.isnan(v) for v in sol.errors.values()) and sep < 1.0  # L's, the moments' and periods' 1σ


def test_bad_input_names_the_field():
    from cssat.inversion.tumble import check_tumbling_options, estimate_tumbling

    t = np.arange(0, 3600, 10.0)
    v = np.tile([1.0, 0.0, 0.0], (len(t), 1))
    with pytest.raises(FieldError, match="periods_s"):
        estimate_tumbling(t, np.ones_like(t), v, v, periods_s=(100.0, -1.0))
    with pytest.raises(FieldError, match="inertia_grid"):
        estimate_tumbling(t, np.ones_like(t), v, v, periods_s=(100.0, 50.0), inertia_grid=[(0.9, 0.5)])
    with pytest.raises(FieldError, match="error_grids"):
        check_tumbling_options(error_grids=0)
    with pytest.raises(FieldError, match="error_grids"):  # before the search, not after it
        estimate_tumbling(t, np.ones_like(t), v, v, periods_s=(100.0, 50.0), error_grids=0)
    with pytest.raises(FieldError, match="arc_s"):
        estimate_tumbling(t, np.ones_like(t), v, v, periods_s=(100.0, 50.0), arc_s=5.0)

IN_CLASS = ["brdf=lambert", "shadows=false", "inversion.brdf=simulated"]  # the truth in the inversion's model class


def _cfg(*overrides):
    from hydra import compose, initialize_config_module

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


# a 20 s cadence: Nyquist 1/40 Hz above the Lambertian light curve's harmonics of P_φ 211 s (no glints in class)
SMALL = ["nights.n=2", "nights.fit=1", "threads=1", "scenario.step_s=20", "inversion.n_normals=300", "+inversion.tumbling.periods_s=[796.07,210.54]",
         "+inversion.tumbling.inertia_grid=[[0.55,0.75],[0.65,0.85]]", "+inversion.tumbling.coarse_samples=100",
         "+inversion.tumbling.coarse_normals=32", "+inversion.tumbling.n_screen=8", "+inversion.tumbling.n_starts=4",
         "+inversion.tumbling.n_refine=2", "+inversion.tumbling.mid_samples=150", "+inversion.tumbling.mid_normals=64",
         "+inversion.tumbling.n_normals=200", "+inversion.tumbling.max_samples=300", "+inversion.tumbling.final_fev=20"]


@pytest.mark.slow
def test_the_tumbling_experiment_finds_the_true_state(tmp_path):
    """``experiment=inversion_tumbling`` (one night fitted, small grids, the periods given to within
    1e-4) scores its estimate against the attitude's own invariants: the direction of L within 3°,
    the periods within 1e-4, the short-axis mode, 80 % of the EGI's area within 10°; one night pins
    the periods to ~1e-5 only, so the next night is predicted to 5 % of the flux (a tumbler's light
    curve varies by tens of %), not to the noise. In the search's own model class (a Lambertian
    truth without shadows, inverted as such: ``inversion.brdf=simulated``) — the algorithm's check;
    the default's mismatched truth (glints, shadows) is measured in BENCHMARKS.md."""
    from cssat.experiments import run_experiment

    m = run_experiment(_cfg("experiment=inversion_tumbling", *SMALL, *IN_CLASS), tmp_path / "run")
    assert m["truth_brdf"] == "lambert" and m["inversion_brdf"] == "lambert" and not m["truth_shadows"]
    assert m["status"] == "ok" and m["spin"] == "tumbling" and not m["attitude_known"]
    assert m["pole_error_deg"] < 3.0 and m["period_error_relative"] < 1e-4 and m["tumble_mode_correct"], m
    assert m["egi_recovered_share"] >= 0.8 and m["heldout_rms_relative"] < 0.05, m
    flux = np.load(tmp_path / "run" / "arrays.npz")["flux"]
    assert flux.std() / np.sqrt(np.mean(flux ** 2)) > 0.2  # the flat light curve's relative misfit: the baseline


def test_the_tumbling_options_are_checked_before_work(tmp_path):
    from cssat.experiments import run_experiment

    with pytest.raises(FieldError, match=r"inversion\.tumbling\.bogus"):
        run_experiment(_cfg("experiment=inversion_tumbling", "+inversion.tumbling.bogus=1"), tmp_path / "bad")
    for bad, field in (("+inversion.tumbling.arc_s=-1", r"inversion\.tumbling\.arc_s: .*\(0\.0, inf\]"),
                       ("+inversion.tumbling.n_poles=0", r"inversion\.tumbling\.n_poles"),
                       ("+inversion.tumbling.inertia_grid=-3", r"inversion\.tumbling\.inertia_grid"),
                       ("+inversion.tumbling.inertia_grid=[[0.9,0.5]]", r"inversion\.tumbling\.inertia_grid.*triangle|0 < I1"),
                       ("+inversion.tumbling.periods_s=[1,x]", r"inversion\.tumbling\.periods_s"),
                       ("+inversion.tumbling.min_period_s=15", r"inversion\.tumbling\.min_period_s: 15 s is under two cadences"),
                       ("inversion.min_period_s=19", r"inversion\.min_period_s: 19 s is under two cadences \(scenario.step_s = 10 s\)"),
                       ("nights.fit=5", r"nights\.fit: 5 nights fitted of the 3")):
        with pytest.raises(FieldError, match=field):
            run_experiment(_cfg("experiment=inversion_tumbling", bad), tmp_path / "bad")
        assert not (tmp_path / "bad" / "arrays.npz").exists()
    for bad, field in ((["+inversion.method=tv"], r"inversion\.method: the EGI's solve is the solver group's: solver=nnls"),
                       (["solver=nntv", "solver.lam=-1"], r"solver\.lam"),
                       (["solver=nntv", "solver.tv_neighbours=0"], r"solver\.tv_neighbours"),
                       (["solver=omp", "solver.n_nonzero_coefs=100000"], r"solver\.n_nonzero_coefs")):
        with pytest.raises(FieldError, match=field):
            run_experiment(_cfg("experiment=inversion", *bad), tmp_path / "bad2")
        assert json.loads((tmp_path / "bad2" / "metrics.json").read_text())["status"] == "failed"
        assert not (tmp_path / "bad2" / "arrays.npz").exists()


def test_the_tumbling_verdict_does_not_cry_wolf():
    """Issue 36, point 8: a spinner's curve — one periodic signal (two harmonics) times a slow
    drift of the geometry (a third of its level over the night), with a specular glint of 20× at
    one phase in some cycles only — is NOT called tumbling; a sum of two periodic signals of
    incommensurate periods (ratio the golden mean) IS; a bad threshold is refused by name."""
    from cssat.inversion import estimate_tumbling_periods

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 4 * 3600.0, 30.0)  # one 4-h night at a 30 s cadence
    ph = 2 * np.pi * t / 517.0
    drift = 1.0 + 0.35 * t / t[-1] - 0.2 * (t / t[-1]) ** 2
    spinner = (1.0 + 0.3 * np.cos(ph) + 0.15 * np.sin(2 * ph + 0.4)) * drift
    glint = (np.abs(((t / 517.0) % 1.0) - 0.25) < 0.03) & (rng.random(t.size) < 0.5)
    spinner = spinner * np.where(glint, 20.0, 1.0)
    golden = 0.5 * (1 + math.sqrt(5))
    tumbler = 1.0 + 0.3 * np.cos(ph) + 0.25 * np.cos(ph / golden + 1.0) + 0.1 * np.cos(2 * ph / golden)
    opts = {"min_period_s": 120.0, "max_period_s": 3000.0}
    for y, truth in ((spinner, False), (tumbler, True)):
        sig = 0.005 * np.ones_like(y)
        out = estimate_tumbling_periods(t, y + sig * rng.standard_normal(y.size), sigma=sig, **opts)
        assert out["tumbling"] is truth, (truth, out["aperiodic"], out["why"])
    with pytest.raises(FieldError, match="aperiodic_threshold"):
        estimate_tumbling_periods(t, tumbler, aperiodic_threshold=1.5, **opts)


@pytest.mark.parametrize("key, value", [("aperiodic_threshold", 0.0), ("aperiodic_threshold", 2.0), ("window_s", -1.0)])
def test_the_characterise_tumbling_options_are_checked_before_work(key, value):
    from omegaconf import OmegaConf

    from cssat.experiments.forward.observed import observed_settings

    cfg = OmegaConf.create({"observations": "lc.csv", "tumbling": {key: value}})
    with pytest.raises(FieldError, match=f"tumbling.{key}"):
        observed_settings(cfg)


def test_the_typical_residual_ignores_a_glint():
    """The inversion experiments' ``*_typical_over_noise`` (``median |r/σ| / 0.6745``): 1 for
    Gaussian residuals at the noise (the half-normal's median is 0.6745σ), and one unpredicted
    glint of 10⁴σ among 20,000 samples, which multiplies the rms by 70, moves it by under 1 %; None without σ."""
    from cssat.experiments.forward.egi_score import _rms, _typical

    rng = np.random.default_rng(0)
    sig = np.full(20_000, 0.01)
    r = sig * rng.standard_normal(sig.size)
    m = np.ones(sig.size, bool)
    base = _typical(r, sig, m)
    assert abs(base - 1.0) < 0.03
    r[123] = 1e4 * sig[123]
    assert _rms(r, m) / _rms(sig, m) > 50 and abs(_typical(r, sig, m) / base - 1.0) < 0.01
    assert _typical(r, None, m) is None and _typical(r, sig, np.zeros(sig.size, bool)) is None


@pytest.mark.parametrize("i1, i2, alpha_deg, sam", [(0.55, 0.85, 22.0, True), (0.4, 0.9, 70.0, False)])
def test_the_twin_is_the_same_motion_with_the_body_turned_half_a_turn(i1, i2, alpha_deg, sam):
    """``TumblingState.twin()``: at every time its frames are the state's turned 180° about one
    principal axis (``R' Rᵀ`` constant, diagonal ±1, determinant 1) — the largest moment's axis
    in a short-axis mode, the smallest's in a long-axis one —, half a period of ω on."""
    from cssat.inversion.tumble import TumblingState, tumbling_rates

    a = math.radians(alpha_deg)
    fw, fp = tumbling_rates(i1, i2, a)
    st = TumblingState(i1, i2, a, 0.02 * fw, 0.02 * fp, 140.0, 40.0, 30.0, 75.0, 0.0, "equatorial")
    tw = st.twin()
    t = np.linspace(0.0, 2 * 86400.0, 400)
    M = np.einsum("tij,tkj->tik", tw.frames(t), st.frames(t))
    assert st.short_axis == sam
    axis = 2 if sam else 0
    want = -np.eye(3)
    want[axis, axis] = 1.0
    np.testing.assert_allclose(M, np.broadcast_to(want, M.shape), atol=1e-9)
    assert tw.t0_s == pytest.approx(st.t0_s + 0.5 / st.f_omega_hz, rel=1e-12)


def test_a_refinement_that_ends_where_no_motion_is_passed_over(monkeypatch):
    """A refinement can stop where no rigid body has its eight numbers (here: i₁ > i₂, the best
    χ²); the solution is the best refined minimum that is a motion, not a crash."""
    import cssat.inversion.tumble as T

    t = np.arange(0, 7200, 20.0)
    sun = np.tile(np.array([0.95, -0.1, 0.3]) / np.linalg.norm([0.95, -0.1, 0.3]), (len(t), 1))
    obs = np.tile(np.array([0.3, 0.9, 0.1]) / np.linalg.norm([0.3, 0.9, 0.1]), (len(t), 1))
    truth, y = _box_wing_tumbler(t, sun, obs)
    fw, fp, alpha = truth.f_omega_hz, truth.f_phi_hz, truth.alpha
    bad = truth.vector()
    bad[0], bad[1] = 0.9, 0.6  # i₁ > i₂: no motion
    monkeypatch.setattr(T, "_refine", lambda fit, x, al, *rest: (0.0 if x[0] > x[1] else 1.0, np.asarray(x, float), al))
    monkeypatch.setattr(T, "_continuation", lambda samples, cur, *rest: [(0.0, bad, alpha)] + list(cur))
    sol = T.estimate_tumbling(t, y, sun, obs, frame="equatorial", periods_s=(1 / fw, 1 / fp), inertia_grid=[(0.55, 0.85)],
                              n_poles=4, n_t0=2, n_phi=2, n_starts=1, n_refine=1, n_screen=1, coarse_samples=40,
                              coarse_normals=16, mid_samples=40, mid_normals=16, n_normals=32, max_samples=60, arc_s=3600.0,
                              final_fev=2)
    assert sol.state.i1 <= sol.state.i2


def test_a_longitude_run_past_a_turn_is_the_same_direction():
    """A refinement's longitude of L is unbounded (the coverage study met 3,620°): the state
    wraps it and its frames are those of the wrapped direction."""
    from cssat.inversion.tumble import TumblingState, tumbling_rates

    fw, fp = tumbling_rates(0.55, 0.85, 0.4)
    far, near = (TumblingState(0.55, 0.85, 0.4, fw * 0.02, fp * 0.02, 10.0, lon, 30.0, 75.0, 0.0, "equatorial")
                 for lon in (10 * 360.0 + 40.0, 40.0))
    assert far.lon_deg == pytest.approx(40.0, abs=1e-9)
    t = np.linspace(0, 3600, 7)
    np.testing.assert_allclose(far.frames(t), near.frames(t), atol=1e-9)


def _unit(lon_deg: float, lat_deg: float) -> np.ndarray:
    lo, la = math.radians(lon_deg), math.radians(lat_deg)
    return np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])


def test_the_continuation_carries_every_basin_not_only_copies_of_one():
    """Seed 932's first arc in miniature: four minima of one basin (L within 2°, across the
    longitude's wrap; frequencies a few thousandths of a turn apart over the 2-h arc) ahead of
    the other side's. Carried: the ``n`` best as before and, beside them, the best of each other
    basin until ``n`` basins are carried — checked against a brute force written here: a minimum
    is a copy of another when the angle between the unit vectors of their L is under 10° and both
    frequencies differ by under a quarter turn over the arc."""
    from cssat.inversion.tumble_fit import _distinct_minima

    arc = 7200.0

    def m(chi2, P_w, P_p, lon, lat):
        return (chi2, np.array([0.74, 0.85, 1 / P_w, 1 / P_p, 100.0, lon, lat, 30.0]), 0.4)

    minima = [m(115.3, 1575.2, 297.349, -147.6, 73.7), m(151.2, 1574.41, 297.306, 211.2, 71.9),
              m(151.3, 1574.17, 297.299, -149.4, 72.0), m(151.3, 1574.61, 297.312, -149.6, 72.0),
              m(160.0, 1575.2, 290.0, -147.6, 73.7),  # the same L, P_φ 1.2 turns apart over the arc
              m(186.9, 1572.26, 298.322, -23.5, -71.5), m(186.9, 1572.25, 298.322, -23.3, -71.5)]

    def brute(n, minima=minima, arc=arc):
        def copy(x, k):
            angle = math.degrees(math.acos(np.clip(_unit(x[5], x[6]) @ _unit(k[5], k[6]), -1, 1)))
            return angle < 10 and abs(x[2] - k[2]) * arc < 0.25 and abs(x[3] - k[3]) * arc < 0.25

        heads = []
        for i, (_, x, _) in enumerate(minima):
            if not any(copy(x, minima[h][1]) for h in heads):
                heads.append(i)
        return sorted(minima[i][0] for i in sorted(set(range(min(n, len(minima)))) | set(heads[:n])))

    assert brute(3) == [115.3, 151.2, 151.3, 160.0, 186.9]  # the brute force itself: the 3 best and 2 more basins
    assert brute(1) == [115.3]
    for n in (1, 2, 3, 5):
        assert [c for c, _, _ in _distinct_minima(minima, n, arc)] == brute(n)
    # over the arc the two best are one basin: a third minimum, the next basin's, is carried; over
    # 1e7 s (116 days) the closest two of the first four are 0.8 turn apart, each its own basin: none
    assert len(_distinct_minima(minima[:5], 2, arc)) == 3 == len(brute(2, minima[:5], arc))
    assert len(_distinct_minima(minima[:5], 2, 1e7)) == 2 == len(brute(2, minima[:5], 1e7))


def test_the_rescan_of_the_phases_finds_a_minimum_its_start_missed():
    """A continued minimum whose two phases are the first arc's while its frequencies are right
    (here: the truth with ``φ₀`` half a turn and ``t₀`` a third of the polhode period off; 1 %
    noise, 240 samples). Refined from there alone, Levenberg–Marquardt stops far above the
    truth's χ² (asserted: the case needs the rescan); ``_rephase`` from the same start reaches
    the truth's χ² within the noise's scale and L within 1°. The truth's χ² is computed here
    from the truth's own state (one NNLS solve), not from the code under test."""
    from cssat.inversion.spin import _separation_deg
    from cssat.inversion.tumble_fit import _refine, _rephase
    from cssat.inversion.tumble_state import _TFit
    from test_tumble_errors import _in_class_case

    truth, (t, sun, obs), grid, clean = _in_class_case()
    sig = 0.01 * clean.mean()
    y = clean + sig * np.random.default_rng(3).standard_normal(len(t))
    fit = _TFit.spread((t, y, np.full(len(t), 1.0 / sig), sun, obs), np.ones(len(t), bool), 240, grid, None)
    span = float(t[-1] - t[0])
    _, chi2_truth = fit.solve(truth)
    x0 = truth.vector()
    x0[4] += 1 / (3 * x0[2])
    x0[7] = (x0[7] + 180.0) % 360.0
    alone = _refine(fit, x0, truth.alpha, span, 200, truth.t_ref_s, truth.frame)
    assert alone[0] > 3 * chi2_truth  # stuck: the start's phases are in another basin
    out = _rephase(fit, [alone], 6, 8, 200, truth.t_ref_s, truth.frame)
    assert len(out) == 2 and out[1][0] == alone[0]  # the rescanned minimum added beside the continued one
    c, x, _ = out[0]
    assert c <= chi2_truth + 3 * math.sqrt(2 * len(fit.t))  # the truth's minimum, within the χ²'s own spread
    assert _separation_deg((float(x[5]), float(x[6])), (truth.lon_deg, truth.lat_deg)) < 1.0


@pytest.mark.parametrize("key,value", [("bootstrap", -1), ("bootstrap", 1001), ("bootstrap", 2.5), ("bootstrap", "x"),
                                       ("rephase", "x"), ("rephase", 2), ("rephase", None)])
def test_a_bad_bootstrap_or_rephase_is_refused_before_any_work(key, value):
    from cssat.inversion.tumble import check_tumbling_options, estimate_tumbling

    t = np.arange(0, 3600, 10.0)
    v = np.tile([1.0, 0.0, 0.0], (len(t), 1))
    with pytest.raises(FieldError, match=key):
        check_tumbling_options(**{key: value})
    with pytest.raises(FieldError, match=key):
        estimate_tumbling(t, np.ones_like(t), v, v, periods_s=(100.0, 50.0), **{key: value})
