"""The result objects: attribute and mapping access agree, they are read-only, JSON goes there
and back, and :meth:`PeriodResult.model` evaluates the fitted series and trend — checked against
a brute-force least-squares fit and the noise-free truth computed here."""

from __future__ import annotations

import json
import math
import pickle

import numpy as np
import pytest

from cssat._checks import FieldError


def _truth(t, period=137.0):
    """A two-harmonic curve (cos, sin coefficients below) at ``period``, from t = 0."""
    w = 2 * np.pi * t / period
    return 0.30 * np.cos(w) - 0.20 * np.sin(w) + 0.10 * np.cos(2 * w) + 0.05 * np.sin(2 * w)


def _tracks():
    """Two tracks an hour apart, two camera channels interleaved; each track its own quadratic,
    channel "b" 0.07 brighter; noise-free. Returns t, y, tracks, channels and the truth."""
    t = np.r_[np.arange(0.0, 1500.0, 5.0), np.arange(5100.0, 6600.0, 5.0)]
    tracks = np.where(t < 3000, "A", "B")
    channels = np.where(np.arange(len(t)) % 2, "b", "a")
    trend_a = 8.0 + 1e-4 * (t - 700.0) - 2e-8 * (t - 700.0) ** 2
    trend_b = 7.5 - 5e-5 * (t - 5800.0) + 3e-8 * (t - 5800.0) ** 2

    def truth(tt, trk, ch):
        base = np.where(trk == "A", 8.0 + 1e-4 * (tt - 700.0) - 2e-8 * (tt - 700.0) ** 2,
                        7.5 - 5e-5 * (tt - 5800.0) + 3e-8 * (tt - 5800.0) ** 2)
        return _truth(tt) + base - 0.07 * (ch == "b")

    y = _truth(t) + np.where(tracks == "A", trend_a, trend_b) - 0.07 * (channels == "b")
    return t, y, tracks, channels, truth


def _brute_force_dict(t, y, tracks, channels, period, m=2):
    """A period result's model keys from a least-squares fit built here: each track's powers of
    (t − mean)/max|t − mean| to 2, channel b's offset, the m-harmonic series from t.min()."""
    cols, trend = [], []
    for k in ("A", "B"):
        on = tracks == k
        c = t[on].mean()
        s = np.abs(t[on] - c).max()
        trend.append({"start_s": t[on].min(), "stop_s": t[on].max(), "centre_s": c, "scale_s": s, "first": len(cols)})
        for j in range(3):
            cols.append(np.where(on, ((t - c) / s) ** j, 0.0))
    cols.append((channels == "b").astype(float))
    for j in range(1, m + 1):
        cols.append(np.cos(2 * np.pi * j * (t - t.min()) / period))
    for j in range(1, m + 1):
        cols.append(np.sin(2 * np.pi * j * (t - t.min()) / period))
    X = np.stack(cols, 1)
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    return {"period_s": period, "verdict": "periodic", "periodic": True, "model_period_s": period,
            "time_origin_s": float(t.min()), "coefficients": coef[7:].tolist(),
            "trend": [{k: v for k, v in d.items() if k != "first"} | {"coefficients": coef[d["first"]:d["first"] + 3].tolist()}
                      for d in trend],
            "zero_points": {"a": 0.0, "b": float(coef[6])}}


def test_model_against_a_brute_force_least_squares_fit_and_the_truth():
    from cssat.inversion import PeriodResult, series_fit

    t, y, tracks, channels, truth = _tracks()
    d = _brute_force_dict(t, y, tracks, channels, 137.0)
    r = PeriodResult(d)
    # at new times inside the tracks (between the samples), each channel: the noise-free truth
    tn = np.r_[np.linspace(2.5, 1490.0, 97), np.linspace(5102.5, 6590.0, 89)]
    trk = np.where(tn < 3000, "A", "B")
    for ch in ("a", "b"):
        chs = np.full(len(tn), ch)
        np.testing.assert_allclose(r.model(tn, channels=chs), truth(tn, trk, chs), atol=1e-9)
    # the series alone: the harmonics' truth (the trend is the tracks', the zero point channel b's)
    np.testing.assert_allclose(r.model(tn, trend=False), _truth(tn), atol=1e-9)
    # series_fit's weighted fit, by its own parametrisation, gives the same model and series
    fit = series_fit(t, y, 137.0, 2, sigma=np.full(len(t), 0.01), segments=tracks, zero_points=channels)
    np.testing.assert_allclose(fit["coefficients"], d["coefficients"], atol=1e-9)
    rf = PeriodResult({"period_s": 137.0, "verdict": "periodic", "periodic": True, **fit})
    np.testing.assert_allclose(rf.model(tn, channels=np.full(len(tn), "b")), truth(tn, trk, np.full(len(tn), "b")),
                               atol=1e-9)
    with pytest.raises(FieldError) as err:
        rf.model(tn, channels=np.full(len(tn), "z"))
    assert err.value.field == "channels" and "a, b" in err.value.detail


def test_with_model_adds_the_least_squares_series_at_the_results_period():
    """estimate_period's result made to carry its model (as its return may): the series at its
    photometric period with its harmonics and each track's quadratic, equal to a least-squares
    fit of those columns built here; the result's other keys unchanged."""
    from cssat.inversion import PeriodResult, estimate_period

    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 3000.0, 300))
    y = 5.0 + _truth(t) + rng.normal(0.0, 0.05, len(t))
    r = PeriodResult.from_dict(estimate_period(t, y, sigma=0.05, n_surrogates=6))
    rm = r.with_model(t, y, sigma=0.05)
    assert rm.with_model(t, y) is rm and all(rm[k] is r[k] for k in r)
    P, m = r["photometric_period_s"], r["n_harmonics"]
    u = (t - t.mean()) / np.abs(t - t.mean()).max()
    w = 2 * np.pi * (t - t.min()) / P
    X = np.stack([np.ones_like(t), u, u ** 2, *(np.cos(k * w) for k in range(1, m + 1)),
                  *(np.sin(k * w) for k in range(1, m + 1))], 1)
    np.testing.assert_allclose(rm.model(t), X @ np.linalg.lstsq(X, y, rcond=None)[0], atol=1e-9)
    assert float(np.std(y - rm.model(t))) < 0.06  # the fit reaches the noise


def test_model_needs_coefficients_and_says_so():
    from cssat.inversion import PeriodResult

    r = PeriodResult({"period_s": 10.0, "verdict": "periodic", "periodic": True})
    with pytest.raises(FieldError) as err:
        r.model(np.arange(3.0))
    assert err.value.field == "model" and "coefficients" in err.value.detail


def test_the_peers_model_is_their_least_squares_series():
    """lombscargle's .model: the 2-term series at its period with one stretch's quadratic —
    the least-squares fit of those columns built here."""
    from cssat.inversion import find_period

    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0.0, 2500.0, 400))
    y = 9.0 + 2e-5 * t + _truth(t) + rng.normal(0.0, 0.02, len(t))
    r = find_period(t, y, method="lombscargle")
    P = r.period_s
    u = (t - t.mean()) / np.abs(t - t.mean()).max()
    w = 2 * np.pi * (t - t.min()) / P
    X = np.stack([np.ones_like(t), u, u ** 2, np.cos(w), np.cos(2 * w), np.sin(w), np.sin(2 * w)], 1)
    np.testing.assert_allclose(r.model(t), X @ np.linalg.lstsq(X, y, rcond=None)[0], atol=1e-9)
    assert abs(P / 137.0 - 1) < 0.005


def _estimate():
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0.0, 3000.0, 300))
    y = _truth(t) + rng.normal(0.0, 0.05, len(t))
    return estimate_period(t, y, sigma=0.05, n_surrogates=6)


def test_period_result_attributes_and_mapping_agree_and_round_trip():
    from cssat.inversion import PeriodResult

    d = dict(_estimate())  # the dict estimate_period returns (or its result's keys)
    r = PeriodResult.from_dict(d)
    assert PeriodResult.from_dict(r) is r  # idempotent
    copy = PeriodResult(r)
    assert copy is not r and all(copy[k] is r[k] for k in r)
    assert list(dict(r)) == list(d) and list(r.keys()) == list(d.keys()) and len(r) == len(d)
    for k in d:
        assert r[k] is d[k]  # the same objects: what the experiments record is unchanged
        if k.isidentifier():
            assert getattr(r, k) is d[k]
    assert r.period_s == r["period_s"] and r.verdict == r["verdict"] == "periodic" and r.periodic is True
    assert r.alternatives == r["alternatives"] and r.periodogram is r["periodogram"]
    assert abs(r.period_s / 137.0 - 1) < 1e-3
    assert r.get("no such key", 3) == 3 and "no such key" not in r
    with pytest.raises(KeyError):
        r["no such key"]
    with pytest.raises(AttributeError, match="read-only"):
        r.period_s = 1.0
    with pytest.raises(TypeError):
        r["period_s"] = 1.0
    # JSON there and back: the same keys and values, the periodogram's arrays as arrays
    text = r.to_json()
    back = PeriodResult.from_json(text)
    assert json.loads(text)["period_s"] == r.period_s and set(back) == set(r)
    for k in r:
        a, b = r[k], back[k]
        if k == "periodogram":
            for q in ("frequency_hz", "power"):
                assert isinstance(b[q], np.ndarray)
                np.testing.assert_array_equal(a[q], b[q])
        elif isinstance(a, float) and math.isnan(a):
            assert math.isnan(b)
        else:
            assert json.dumps(b) == json.dumps(a if not isinstance(a, np.generic) else a.item())
    again = pickle.loads(pickle.dumps(r))  # across joblib workers
    assert type(again) is PeriodResult and list(again) == list(r) and again.period_s == r.period_s
    with pytest.raises(FieldError) as err:
        PeriodResult({"period_s": 1.0})
    assert err.value.field == "PeriodResult" and "verdict, periodic" in err.value.detail


def _spin_kw():
    return dict(pole_lon_deg=40.0, pole_lat_deg=-30.0, period_s=437.0, lon_err_deg=1.0, lat_err_deg=0.5, pole_err_deg=0.9,
                period_err_s=0.01, formal_pole_err_deg=0.8, formal_period_err_s=0.01, grid_pole_shift_deg=0.4,
                grid_period_shift_s=0.0, chi2=120.0, reduced_chi2=1.1, model_fits=True, normals=np.eye(3),
                areas=np.ones(3), lobe_areas=None, residual=np.zeros(5), synodic={"period_s": 436.0, "given": True},
                alternatives=[], ambiguous=False, frame="equatorial", brdf=None, split_pole_err_deg=None,
                split_period_err_s=None, split_poles=[], coarse=[])


def test_spin_solution_is_a_mapping_with_attributes():
    from cssat.inversion import SpinSolution

    kw = _spin_kw()
    s = SpinSolution(**kw)
    assert dict(s) == {k: s[k] for k in kw} and set(s) == set(kw)
    for k, v in kw.items():
        assert getattr(s, k) is v and s[k] is v
    d = s.describe()
    assert d["spin_pole_lon_deg"] == 40.0 and d["spin_period_s"] == 437.0 and len(d) == 16
    R0, R1 = s.frames(np.array([0.0, 437.0]))  # one sidereal turn: the same body frame
    np.testing.assert_allclose(R0, R1, atol=1e-9)
    np.testing.assert_allclose(R0 @ R0.T, np.eye(3), atol=1e-12)
    back = SpinSolution.from_json(s.to_json())
    np.testing.assert_array_equal(back.normals, kw["normals"])
    assert back.pole_lat_deg == -30.0 and back.synodic == {"period_s": 436.0, "given": True}
    with pytest.raises(AttributeError, match="read-only"):
        s.period_s = 2.0
    with pytest.raises(FieldError, match="frame"):
        SpinSolution(pole_lon_deg=1.0, pole_lat_deg=2.0, period_s=3.0)


def test_event_fit_is_a_mapping_with_attributes():
    from cssat.occultation import EventFit, SilhouetteFit

    cov = np.array([[0.09, 0.01], [0.01, 0.04]])
    d = {"grid_centre_m": np.array([1.0, 2.0]), "offset_m": np.array([1.5, 2.5]), "offset_cov": cov,
         "speed_error": 0.01, "gains": np.array([1.0, 0.98]), "diameter_m": 0.3, "chi2_per_sample": 1.02,
         "known": [], "linear": None, "diameter_profile": np.zeros(0)}
    f = EventFit(d)
    for k in d:
        assert f[k] is d[k] and getattr(f, k) is d[k]
    np.testing.assert_allclose(f.offset_sigma_m, [0.3, 0.2])
    back = EventFit.from_json(f.to_json())
    np.testing.assert_array_equal(back.offset_cov, cov)
    assert back.linear is None and back.known == []
    s = SilhouetteFit(loss=0.5, chi2_per_sample=1.1, losses=[0.5, 0.7])
    assert s.loss == s["loss"] == 0.5 and dict(s) == {"loss": 0.5, "chi2_per_sample": 1.1, "losses": [0.5, 0.7]}
    assert {**s} == dict(s) and json.loads(s.to_json()) == dict(s)


def test_estimate_period_returns_a_result_whose_model_is_the_curve():
    """estimate_period's own result: attributes and keys agree, and ``.model(t)`` is the noiseless
    curve it was given (a two-harmonic series on a slope, in two channels of their own zero
    points) to well under the noise, at times the fit never saw."""
    import numpy as np

    from cssat.inversion import estimate_period
    from cssat.inversion.results import PeriodResult

    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 900, 1200))
    ch = rng.integers(0, 2, t.size)
    truth = lambda u: 0.4 * np.sin(2 * np.pi * u / 53.0) + 0.15 * np.cos(4 * np.pi * u / 53.0) + 2e-4 * u  # noqa: E731
    y = truth(t) + 0.07 * ch + rng.normal(0, 0.01, t.size)
    r = estimate_period(t, y, zero_points=ch)
    assert isinstance(r, PeriodResult) and r.verdict == r["verdict"] == "periodic"
    assert abs(r.period_s / 53.0 - 1) < 1e-3
    u = np.linspace(100, 800, 333)  # not the samples' times
    assert np.max(np.abs(r.model(u, channels=np.zeros(u.size, int)) - truth(u))) < 0.01
