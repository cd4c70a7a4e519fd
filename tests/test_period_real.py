"""Issue 46, point 2: periods and verdicts that hold on real tracks.

The references are independent of cssat: MMT's own labels of the 20 real MMT-9 tracks in
``../shared/real/mmt`` (skipped when absent), analytic truths of synthetic curves, a red-noise
process whose spectrum is known, and numpy's own step statistics."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from cssat._checks import FieldError

SHARED = Path(__file__).resolve().parents[2] / "shared" / "real" / "mmt"


def _mmt(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Times (s), StdMag and channel of a real MMT file, penumbra rows dropped, parsed here by hand."""
    rows = [ln.split() for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    t = np.array([np.datetime64(f"{r[0]}T{r[1]}", "us") for r in rows])
    keep = np.array([r[5] == "0" for r in rows])
    s = (t - t.min()).astype(np.int64) / 1e6
    name = next(ln for ln in path.read_text().splitlines() if ln.startswith("# satellite:"))
    return s[keep], np.array([float(r[2]) for r in rows])[keep], np.array([r[8] for r in rows])[keep], name


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/real/mmt is absent")
def test_real_mmt_tracks_periods_and_verdicts_against_mmt_s_labels():
    """The targets of issue 46, point 3, on the development set: within 1 % of MMT's period on
    >= 85 % of the periodic tracks spanning >= 3 of MMT's periods; no period off MMT's by more
    than 1 % claimed on more than 1 file in 10; every "Not variable" track called not periodic."""
    from cssat.inversion import estimate_period

    man = list(csv.DictReader((SHARED / "manifest.csv").open()))
    right = scored = wrong = nonvar = nonvar_ok = 0
    for row in man:
        t, y, ch, head = _mmt(SHARED / row["file"])
        conv = "double_peaked" if "R/B" in head else "photometric"
        r = estimate_period(t, y, zero_points=ch, convention=conv)
        assert r["verdict"] in ("periodic", "not periodic", "undetermined")
        assert r["periodic"] is {"periodic": True, "not periodic": False, "undetermined": None}[r["verdict"]]
        assert isinstance(r["verdict_why"], str) and r["verdict_why"]
        P = float(row["period_s"]) if row["period_s"] else None
        if r["verdict"] == "periodic" and (P is None or abs(r["period_s"] / P - 1) > 0.01):
            wrong += 1
        if P is not None and float(row["span_s"]) / P >= 3:
            scored += 1
            right += r["verdict"] == "periodic" and abs(r["period_s"] / P - 1) <= 0.01
        if row["variability_code"] == "0":
            nonvar += 1
            nonvar_ok += r["verdict"] == "not periodic"
    assert scored >= 8 and right >= math.ceil(0.85 * scored), (right, scored)
    assert wrong <= len(man) // 10, wrong
    assert nonvar == 5 and nonvar_ok == nonvar, nonvar_ok


def _two_maxima(t: np.ndarray, P: float, unequal: float) -> np.ndarray:
    """Magnitudes of a body with two brightness maxima a turn of ``P`` s; the second's depth
    differs from the first's by ``unequal`` mag."""
    ph = 2 * np.pi * t / P
    return 6.0 - 0.6 * np.cos(ph) ** 2 * (1 + unequal * np.cos(ph))


@pytest.mark.parametrize("unequal, convention, expect", [
    (0.4, "photometric", 1.0), (0.4, "double_peaked", 1.0),  # unequal maxima: the full turn whatever the convention
    (0.0, "photometric", 0.5), (0.0, "double_peaked", 1.0),  # equal maxima: half a turn, or the full turn by convention
])
def test_aliases_are_symmetric_and_the_convention_is_the_full_turn(unequal, convention, expect):
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(3)
    P = 12.5
    t = np.sort(rng.uniform(0, 100, 700))
    y = _two_maxima(t, P, unequal) + 0.03 * rng.normal(size=t.size)
    r = estimate_period(t, y, convention=convention)
    assert r["verdict"] == "periodic", r["verdict_why"]
    assert r["period_s"] == pytest.approx(expect * P, rel=2e-3), (r["period_s"], r["why"])
    assert {a["relation"] for a in r["alternatives"]} >= {"P/2", "2P"}  # every relative reported with its ΔBIC
    assert all(math.isfinite(a["delta_bic"]) for a in r["alternatives"])


def _red_noise(t: np.ndarray, tau: float, rng: np.random.Generator) -> np.ndarray:
    """An Ornstein–Uhlenbeck process of unit variance and correlation time ``tau`` s, exactly
    on the irregular times ``t`` (its spectrum is Lorentzian: red below 1/(2π tau))."""
    x = np.empty_like(t)
    x[0] = rng.normal()
    for i in range(1, len(t)):
        a = math.exp(-(t[i] - t[i - 1]) / tau)
        x[i] = a * x[i - 1] + math.sqrt(1 - a * a) * rng.normal()
    return x


def test_the_fap_holds_on_red_noise_where_the_white_noise_test_does_not():
    """40 tracks of red noise and white noise without any period (MMT-like: 0.1 s frames, 30 %
    dropped, 60 s): the surrogate FAP falls under 0.1 on about 10 % of them (a binomial bound),
    while the white-noise F-test calls most of them significant."""
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(11)
    n, under, white = 40, 0, 0
    for _ in range(n):
        t = np.arange(0, 60, 0.1)
        t = t[rng.uniform(size=t.size) > 0.3]
        y = 7.0 + 0.15 * _red_noise(t, 2.0, rng) + 0.1 * rng.normal(size=t.size)
        r = estimate_period(t, y, n_surrogates=16)
        under += r["fap"] < 0.1
        white += r["fap_white"] < 0.1
        assert r["verdict"] != "periodic" or r["fap"] < 1e-3
    assert under <= 10, under  # P(X > 10 | Bin(40, 0.1)) = 0.2 %
    assert white >= 20, white  # the white-noise F-test is fooled by red noise


def test_too_few_cycles_is_undetermined_not_a_period():
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0, 30, 400))
    y = 8.0 + 0.5 * np.sin(2 * np.pi * t / 20.0) + 0.05 * rng.normal(size=t.size)  # 1.5 cycles of 20 s
    r = estimate_period(t, y, detrend=0)
    assert r["verdict"] == "undetermined" and r["periodic"] is None and math.isnan(r["period_s"])
    assert "cycles" in r["verdict_why"]
    assert r["best_period_s"] == pytest.approx(20.0, rel=0.1)


def test_the_search_starts_at_the_median_in_channel_step():
    """Frames of 0.1 s with dropped ones (steps up to 0.6 s) and a second channel 4 ms after
    the first: the range starts at twice the median step of one channel (numpy's), so half a
    1.06 s turn (0.53 s) is searched."""
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(2)
    t1 = np.arange(0, 60, 0.1)
    t1 = t1[rng.uniform(size=t1.size) > 0.35]
    t = np.r_[t1, t1 + 0.004]
    ch = np.r_[np.zeros(t1.size), np.ones(t1.size)]
    y = _two_maxima(t, 1.06, 0.0) + 0.5 * ch + 0.03 * rng.normal(size=t.size)
    r = estimate_period(t, y, zero_points=ch, convention="double_peaked")
    assert r["min_period_s"] == pytest.approx(2 * np.median(np.diff(t1)), rel=1e-9)
    assert r["period_s"] == pytest.approx(1.06, rel=1e-3)


def test_astropy_time_and_quantities_keep_their_units():
    from astropy import units as u
    from astropy.time import Time

    from cssat.inversion import estimate_period

    rng = np.random.default_rng(8)
    t = np.sort(rng.uniform(0, 3000, 500))  # s
    y = 9.0 + 0.3 * np.sin(2 * np.pi * t / 300.0) + 0.02 * rng.normal(size=t.size)
    ref = estimate_period(t, y)
    tm = Time("2024-01-01T00:00:00", scale="utc") + t * u.s
    assert estimate_period(tm, y)["period_s"] == pytest.approx(ref["period_s"], rel=1e-6)
    days = estimate_period((t / 86400.0) * u.day, y * u.mag, sigma=0.02 * u.mag)
    assert days["period_s"] == pytest.approx(300.0, rel=1e-3)  # seconds, not days
    with pytest.raises(FieldError, match="times_s"):
        estimate_period(t * u.m, y)
    with pytest.raises(FieldError, match="sigma"):
        estimate_period(t, y * u.Jy, sigma=0.02 * u.m)
    assert estimate_period(t, y, max_period_s=10 * u.min)["max_period_s"] == pytest.approx(600.0)


@pytest.mark.parametrize("P", [40.0, 100.7])
def test_tracks_days_apart_say_their_cycle_count_is_not_fixed_and_size_the_1sigma_by_it(P):
    """Two 10-minute tracks three days apart (the hostile pass: 39.92609 ± 0.0000033 s came back
    for 40.000 s): each track alone pins the period to several fringes (``P²/gap``) of the
    comb between them, so the cycle count across the gap is not fixed: said so, the period is
    the tracks' envelope and its 1σ theirs — the truth within 2σ, the 1σ at least half a fringe
    (not microseconds); the fringes within Δχ² 4 are listed."""
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(1)
    t = np.r_[np.arange(0, 600, 1.0), 3 * 86400 + np.arange(0, 600, 1.0)]
    y = 7 + 0.3 * np.sin(2 * np.pi * t / P) + 0.1 * np.sin(4 * np.pi * t / P + 1) + 0.05 * rng.normal(size=t.size)
    r = estimate_period(t, y)
    fringe = P * P / (3 * 86400)
    assert r["cycle_count"].startswith("ambiguous") and any("not fixed" in w for w in r["warnings"])
    assert abs(r["period_s"] - P) <= 2 * r["period_err_s"], (r["period_s"], r["period_err_s"])
    assert r["period_err_s"] > 0.5 * fringe
    assert r["fringes"] and all(fr["delta_chi2"] < 4 for fr in r["fringes"])
    spacing = np.diff(sorted(fr["period_s"] for fr in r["fringes"]))  # the comb: whole fringes apart
    assert np.allclose(spacing / fringe, np.round(spacing / fringe), atol=0.05)


def test_tracks_a_day_apart_with_a_fixed_cycle_count_keep_a_fringe_wide_1sigma_under():
    """Two 1-hour tracks a day apart of a 300 s sinusoid at high S/N: each track pins the
    frequency to a small fraction of a fringe, so the cycle count is fixed and the 1σ is the
    coherent one, far under a fringe; the truth within 3σ."""
    from cssat.inversion import estimate_period

    rng = np.random.default_rng(4)
    t = np.r_[np.arange(0, 3600, 5.0), 86400 + np.arange(0, 3600, 5.0)]
    y = 5 + 0.5 * np.sin(2 * np.pi * t / 300.0) + 0.005 * rng.normal(size=t.size)
    r = estimate_period(t, y)
    assert r["cycle_count"] == "fixed"
    assert abs(r["period_s"] - 300.0) <= 3 * r["period_err_s"] and r["period_err_s"] < 0.1 * 300.0 ** 2 / 86400


def test_ceres_is_not_given_a_period_its_sessions_cannot_hold():
    """The repository's real ALCDEF file of (1) Ceres (5 sessions of 1.7-4.9 h over days;
    Ceres turns in 9.07 h, Chamberlain et al. 2007): no session holds 3 turns, so no period may be
    claimed (the hostile pass: "periodic, P = 230.191 ± 0.0028 s"), whether the sessions are
    given as segments or found as stretches."""
    from cssat.data import read_light_curve
    from cssat.inversion import estimate_period

    lc = read_light_curve(Path(__file__).parent / "data" / "real" / "alcdef_ceres_stephens_2011.txt")
    for seg in (None, lc.track_ids()):
        r = estimate_period(lc.times_s(), lc.values, segments=seg)
        assert r["verdict"] != "periodic", (r["period_s"], r["verdict_why"])
        assert r["verdict_why"]
