"""The inversion's verdict and the pole's interval: the held-out test's threshold against a
Monte Carlo of a linear model, the verdict on a model that does not fit, no 1σ when unreliable,
and the profile interval against a brute-force χ² scan."""

from __future__ import annotations

import math

import numpy as np
import pytest

SIDEREAL_DAY = 86164.0905


def test_the_heldout_threshold_is_the_generalised_chi2_of_a_linear_model():
    """Mean and 99 % quantile of the held-out χ² of a least-squares fit, against 20,000 draws."""
    from cssat.inversion.spin_errors import heldout_threshold

    rng = np.random.default_rng(3)
    n_f, n_h, p = 120, 60, 8
    J_f = rng.normal(size=(n_f, p))
    J_h = rng.normal(size=(n_h, p)) * 2.5  # extrapolation: larger leverage than the fitted samples
    beta = rng.normal(size=p)
    pinv = np.linalg.pinv(J_f)
    draws = np.empty(20000)
    for i in range(len(draws)):
        b = pinv @ (J_f @ beta + rng.normal(size=n_f))
        r = J_h @ beta + rng.normal(size=n_h) - J_h @ b
        draws[i] = r @ r
    lim = heldout_threshold(J_f, J_h, alpha=0.01)
    assert lim["mean"] == pytest.approx(draws.mean(), rel=0.01)
    assert lim["threshold"] == pytest.approx(np.quantile(draws, 0.99), rel=0.03)
    assert lim["leverage"] > 0.1 * n_h  # the prediction error counts: not the bare χ²_{n_h}


def test_judge_says_why_and_needs_the_noise():
    from cssat.inversion.spin_errors import judge

    v, why = judge(300.0, 100, 150.0, chi2_fit=100.0, n_fit=100, fit_threshold=150.0, sigma_given=True, what="the pole")
    assert v == "unreliable" and "held-out" in why and "3" in why
    v, _ = judge(110.0, 100, 150.0, chi2_fit=100.0, n_fit=100, fit_threshold=150.0, sigma_given=True, what="the pole")
    assert v == "reliable"
    v, why = judge(None, 0, None, chi2_fit=100.0, n_fit=100, fit_threshold=150.0, sigma_given=False, what="the pole")
    assert v == "unreliable" and "sigma" in why
    v, why = judge(None, 0, None, chi2_fit=100.0, n_fit=100, fit_threshold=150.0, sigma_given=True, what="the pole")
    assert v == "reliable" and "overfitting" in why


def _geometry(t):
    w = 2 * np.pi / SIDEREAL_DAY
    obs = np.stack([np.cos(w * t + 0.3), np.sin(w * t + 0.3), np.full_like(t, 0.12)], 1)
    obs /= np.linalg.norm(obs, axis=1, keepdims=True)
    sun = np.tile(np.array([0.95, -0.1, 0.3]) / np.linalg.norm([0.95, -0.1, 0.3]), (len(t), 1))
    return sun, obs


def _render(t, sun, obs, normals, areas, pole, period, glint=0.0):
    """Lambert light curve (plus, with ``glint``, a Blinn–Phong-200 lobe of that weight: outside a
    Lambert EGI) of facets turning counter-clockwise about ``pole`` (scipy rotations)."""
    from scipy.spatial.transform import Rotation

    B0, _ = Rotation.align_vectors([pole], [[0.0, 0.0, 1.0]])
    out = np.empty(len(t))
    for i, ti in enumerate(t):
        n = (Rotation.from_rotvec(2 * np.pi * ti / period * pole) * B0).apply(normals)
        mu0, mu = np.clip(n @ sun[i], 0, None), np.clip(n @ obs[i], 0, None)
        h = (sun[i] + obs[i]) / np.linalg.norm(sun[i] + obs[i])
        out[i] = (areas / np.pi * mu0 * mu).sum() + glint * (areas * np.clip(n @ h, 0, None) ** 200 * (mu0 > 0) * (mu > 0)).sum()
    return out


def _body():
    import trimesh

    pts = np.random.default_rng(7).normal(size=(14, 3)) * np.array([2.0, 1.2, 0.7])
    hull = trimesh.convex.convex_hull(pts)
    return np.array(hull.face_normals), np.array(hull.area_faces)


SMALL = dict(frame="equatorial", n_poles=20, n_starts=2, n_refine=1, coarse_normals=100, coarse_samples=150,
             n_normals=200, max_samples=200)


@pytest.fixture(scope="module")
def glinting():
    """A glinting body (a specular lobe as bright as the diffuse light) over four nights, the
    fourth held out, 1 % noise: a Lambert EGI does not describe it."""
    from cssat.inversion import estimate_spin

    rng = np.random.default_rng(11)
    t = np.sort(np.concatenate([d * 86400.0 + rng.uniform(0, 6 * 3600.0, 70) for d in range(4)]))
    sun, obs = _geometry(t)
    pole = np.array([0.3, 0.5, 0.81])
    pole /= np.linalg.norm(pole)
    y = _render(t, sun, obs, *_body(), pole, 600.0, glint=1.0)
    s = 0.01 * float(np.mean(y))
    y = y + rng.normal(size=t.size) * s
    fit = t < 3 * 86400
    sol = estimate_spin(t[fit], y[fit], sun[fit], obs[fit], sigma=s, period_s=None, min_period_s=150, max_period_s=3000,
                        heldout=(t[~fit], y[~fit], sun[~fit], obs[~fit], s), **SMALL)
    return sol


def test_a_model_that_does_not_fit_is_unreliable_and_reports_no_pole_error(glinting):
    sol = glinting
    assert sol.verdict == "unreliable" and "held-out" in sol.verdict_why
    assert sol.heldout_chi2 > sol.heldout_threshold
    for k in ("pole_err_deg", "lon_err_deg", "lat_err_deg", "formal_pole_err_deg"):
        assert math.isnan(sol[k]), k
    d = sol.describe()
    assert d["spin_verdict"] == "unreliable" and math.isnan(d["spin_pole_err_deg"])
    assert "nan" in repr(sol)  # no sub-degree 1σ printed


def test_the_heldout_tuple_is_checked():
    from cssat._checks import FieldError
    from cssat.inversion import estimate_spin

    t = np.linspace(0, 3 * 3600, 80)
    sun, obs = _geometry(t)
    with pytest.raises(FieldError) as e:
        estimate_spin(t, 1 + 0.1 * np.cos(t / 60), sun, obs, sigma=0.01, period_s=377.0, heldout=(t, t), **SMALL)
    assert e.value.field == "heldout"
