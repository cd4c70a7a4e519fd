"""The tumbler's 1σ of L (cssat.inversion.tumble_fit._errors): the warm-started parametric
bootstrap against a brute-force Monte Carlo of the estimator itself, written here."""

from __future__ import annotations

import math

import numpy as np
import pytest


SIDEREAL_DAY = 86164.0905


def _in_class_case(n_normals: int = 100, k: int = 12):
    """A tumbler (moments 0.55, 0.85, mode angle 22°, P_ω ≈ 1,050 s) whose closed EGI sits on
    ``k`` of the fit's own ``n_normals`` grid normals, Lambert, no shadows (the model the fit
    is), two 2-h arcs a day apart at 20 s, GEO-like geometry: ``truth, samples, normals, clean``."""
    from scipy.optimize import nnls

    from cssat.inversion import fibonacci_sphere
    from cssat.inversion.tumble import TumblingState, tumbling_rates

    rng = np.random.default_rng(11)
    grid = fibonacci_sphere(n_normals).numpy()
    N = grid[rng.choice(n_normals, k, replace=False)]
    a, _ = nnls(np.vstack([100.0 * N.T, np.eye(k)]), np.concatenate([np.zeros(3), rng.uniform(0.2, 1.0, k)]))
    t = np.concatenate([np.arange(0, 7200, 20.0), 86400 + np.arange(0, 7200, 20.0)])
    w = 2 * np.pi / SIDEREAL_DAY
    obs = np.stack([np.cos(w * t + 0.3), np.sin(w * t + 0.3), np.full_like(t, 0.12)], 1)
    obs /= np.linalg.norm(obs, axis=1, keepdims=True)
    sun = np.tile(np.array([0.95, -0.1, 0.3]) / np.linalg.norm([0.95, -0.1, 0.3]), (len(t), 1))
    alpha = math.radians(22.0)
    fw, fp = (0.021 * f for f in tumbling_rates(0.55, 0.85, alpha))
    truth = TumblingState(0.55, 0.85, alpha, fw, fp, 140.0, 40.0, 30.0, 75.0, 0.0, "equatorial")
    R = truth.frames(t)
    sb, ob = np.einsum("tij,tj->ti", R, sun), np.einsum("tij,tj->ti", R, obs)
    clean = (a / np.pi * np.clip(sb @ N.T, 0, None) * np.clip(ob @ N.T, 0, None)).sum(1)
    return truth, (t, sun, obs), grid, clean


@pytest.mark.slow
def test_the_bootstrap_1sigma_of_L_matches_a_brute_force_monte_carlo():
    """The bootstrap's 1σ of L, from ONE noisy light curve, agrees with the spread of the fitted
    L over 16 independent noise draws from the TRUE model, each fitted from the truth
    (brute force, written here) — within the two estimates' sampling error (a factor 1.7; each
    RMS of 16 draws of a 2-D error is good to ~13 %). The Gauss–Newton 1σ with the NNLS support
    held is reported beside it and falls outside that band on this case."""
    from cssat.inversion.spin import _separation_deg
    from cssat.inversion.tumble_fit import _errors, _refine
    from cssat.inversion.tumble_state import TumblingState, _TFit

    truth, (t, sun, obs), grid, clean = _in_class_case()
    sig = 0.01 * clean.mean()
    w = np.full(len(t), 1.0 / sig)
    span, fev = float(t[-1] - t[0]), 60
    x_true = truth.vector()

    def fitted(y):
        fit = _TFit(t, y, w, sun, obs, grid, None)
        chi2, x, alpha = _refine(fit, x_true, truth.alpha, span, fev, truth.t_ref_s, truth.frame)
        return fit, chi2, x, TumblingState.from_vector(x, alpha, truth.t_ref_s, truth.frame)

    rng = np.random.default_rng(5)
    mc = []
    for _ in range(16):  # the estimator's own spread: new noise on the truth, fitted from the truth
        _, _, x, _ = fitted(clean + sig * rng.standard_normal(len(t)))
        mc.append(_separation_deg((truth.lon_deg, truth.lat_deg), (float(x[5]), float(x[6]))))
    mc_rms = float(np.sqrt(np.mean(np.square(mc))))
    fit, chi2, x, state = fitted(clean + sig * rng.standard_normal(len(t)))
    a, chi2 = fit.solve(state)
    errors, _, _ = _errors(fit, state, x, a, chi2, span, True, fev, grids=1, bootstrap=16)
    boot = errors["bootstrap_L_err_deg"]
    assert mc_rms > 0 and 1 / 1.7 < boot / mc_rms < 1.7, (boot, mc_rms, errors["formal_L_err_deg"])
    # the Gauss–Newton 1σ (the NNLS support held) misses that spread here (0.08° against 0.31°):
    # the valley along L is flatter than its curvature — why the bootstrap exists
    assert errors["formal_L_err_deg"] < mc_rms / 1.7
    assert errors["L_err_deg"] == pytest.approx(math.hypot(boot, errors["grid_L_shift_deg"]))
    # L's 1σ ellipse is the same refits' spread kept in two dimensions: its axes add up, in
    # quadrature, to the radial 1σ (the tangent plane's offsets are the separations)
    assert math.hypot(errors["L_major_deg"], errors["L_minor_deg"]) == pytest.approx(errors["L_err_deg"], rel=1e-6)
    assert errors["L_major_deg"] >= errors["L_minor_deg"] > 0 and errors["L_dof"] == 16
    # without the bootstrap the noise's part is the formal one (the old behaviour)
    plain, _, _ = _errors(fit, state, x, a, chi2, span, True, fev, grids=1)
    assert "bootstrap_L_err_deg" not in plain
    assert plain["L_err_deg"] == pytest.approx(math.hypot(plain["formal_L_err_deg"], plain["grid_L_shift_deg"]))
    assert math.hypot(plain["L_major_deg"], plain["L_minor_deg"]) == pytest.approx(plain["L_err_deg"], rel=1e-6)
    assert plain["L_dof"] == 0  # the formal covariance: the Gaussian's regions

