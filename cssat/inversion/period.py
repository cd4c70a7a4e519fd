"""The period of a light curve, and whether it has one.

:func:`estimate_period` is built for real tracks (Mini-MegaTORTORA, SCORE, a telescope's own
photometry) with its defaults:

1. **Nuisance model.** Each contiguous stretch (track) has its own quadratic trend
   (``detrend=2``: the pass's phase-angle and range drift, as MMT's own pipeline removes) and
   each camera channel its own zero point (``zero_points``: channels interleaved ms apart).
2. **Bounds from the data.** From the Nyquist period of the cadence, ``2 d`` (``d`` the
   median frame step within one channel and stretch: dropped frames do not slow it and
   interleaved channels do not speed it up), to the longest contiguous stretch, unless
   ``min_period_s``/``max_period_s`` are given.
3. **Periodogram and candidates.** astropy's Lomb–Scargle (``nterms=1``, fast) of the
   curve less its nuisance model gives the ``n_peaks`` strongest distinct frequencies; each
   peak's periods ``k/f`` (``k = ½, 1, 2, 3, 4``: a rotating body puts power in harmonics) are
   candidates, each with its own least-BIC number of harmonics, refined by least squares.
4. **Aliases, symmetric.** The least ``BIC = N ln(RSS/N) + p ln N`` (``χ²/ĉ + p ln N`` with
   ``sigma``; ``ĉ`` the best candidate's χ²/ν when > 1) among the candidates and the chosen
   period's ``P/4, P/3, P/2, 2P, 3P`` (each with its own harmonics) wins, with no margin for
   either side: a longer period's series nests the shorter one's, so it wins only when its
   extra harmonics pay their ``ln N`` each. That is the *photometric* period (the shortest over
   which the curve repeats). Every relative is reported with its χ² and ΔBIC
   (``alternatives``).
5. **Convention.** ``convention="photometric"`` reports it; ``"double_peaked"`` (rocket
   bodies: two maxima a turn, MMT's and the asteroid convention) reports the full turn: twice
   the photometric period when its fold shows one significant maximum
   (:func:`~cssat.inversion.period_null.count_maxima`), the photometric period when it shows
   two or more.
6. **The false-alarm probability from the track's own noise** (:func:`~cssat.inversion.period_null.surrogate_fap`):
   the data's largest periodogram power against ``n_surrogates`` stationary-bootstrap
   surrogates of the chosen model's residual (red noise kept on the scale of the period,
   periodicity destroyed), a Gumbel tail fitted to their maxima; over the periods of at least
   ``min_cycles`` cycles (``fap``) and over all periods searched (``fap_all``). Seeded
   (``seed``): same data, same numbers.
7. **Verdict** (``verdict``, ``periodic``, ``verdict_why``): ``"periodic"`` when ``fap <
   fap_max``, the period spans at least ``min_cycles`` cycles of the longest stretch and its
   fold covers the phase (no empty stretch over :data:`MAX_PHASE_GAP` of a cycle);
   ``"undetermined"`` (``periodic`` None) when the curve varies significantly (either FAP below
   ``fap_max``) but the period spans too few cycles or too sparse a fold; ``"not periodic"``
   otherwise: no significant period is an answer. ``period_s`` and ``period_err_s`` are NaN
   unless periodic; ``best_period_s`` keeps the best candidate.
8. **Uncertainties.** ``period_err_s`` from the curvature of χ² in frequency (Δχ² = 1), with
   ``sigma`` scaled by √(χ²/ν) when the model does not fit to the noise, else with the
   residual's own scatter; across gaps, the cycle-count fringes within Δχ² 4 of the best are
   reported (``fringes``) and the 1σ widened to reach the farthest; and where the stretches
   alone (each with its own phase) pin the frequency to no better than a quarter of a fringe,
   the cycle count is not fixed (``cycle_count``): the period and its 1σ are theirs (the
   envelope of the fringes: the least-χ² fringe is one of many alike). ``chi2_per_sample`` is
   χ²/ν against ``sigma``, or, without it, against the point-to-point scatter of the track;
   > 3 sets ``model_fits`` false and warns (a glinting or changing curve the series misses).
   ``repeat`` (the even cycles' series predicting the odd ones) is reported as a diagnostic;
   ``min_repeat`` makes it a condition of the verdict.

The period found is the *synodic* one, that of the light curve (see :mod:`cssat.inversion.spin`).
Assumptions: a periodic signal whose shape changes slowly over the track, plus noise that is
stationary over a period (red or white); magnitudes and fluxes both work (the series fits either).
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.inversion.fourier import _Curve, _design, check_grid, frame_step, light_curve_scatter, stretches
from cssat.inversion.period_inputs import MIN_SAMPLES, _astropy_inputs, _check_track
from cssat.inversion.period_aliases import FRINGE_DCHI2, Aliases, period_error, stretch_fit
from cssat.inversion.period_null import count_maxima, stretch_power, surrogate_fap
from cssat.inversion.results import PeriodResult
from cssat.inversion.period_verdict import _constant, _verdict, _warnings, _why

__all__ = ["estimate_period", "light_curve_scatter", "CONVENTIONS", "convention_for"]

#: the period conventions: the light curve's own period, or the full turn of a two-maxima body
CONVENTIONS = ("photometric", "double_peaked")
#: a fold with an empty stretch of phase over this fraction of a cycle does not show its period
MAX_PHASE_GAP = 0.25
#: the surrogates' periodograms sample each peak this often (the data's statistic on the same grid)
SURROGATE_SPP = 3
#: the surrogates' mean run, as a fraction of the longest period detected (``longest / min_cycles``)
RUN_FRACTION = 1.0
#: across gaps the cycle count is fixed when the stretches alone pin the frequency to under this
#: fraction of a fringe (1σ); else the 1σ is theirs (the fringes are not told apart)
FRINGE_FIXED = 0.25


def estimate_period(times_s: Any, flux: Any, *, sigma: Any = None, min_period_s: Any = None,
                    max_period_s: Any = None, n_harmonics: int | None = None, max_harmonics: int = 12,
                    n_peaks: int = 3, samples_per_peak: int = 10, detrend: int = 2, segments: Any = None,
                    zero_points: Any = None, convention: str = "photometric", fap_max: float = 1e-3,
                    min_cycles: float = 3.0, n_surrogates: int = 24, seed: int = 0,
                    min_repeat: float | None = None) -> dict[str, Any]:
    """The period of the light curve ``flux (T,)`` (a flux or a magnitude) at ``times_s (T,)``
    (seconds, any cadence, any order; an astropy ``Time`` or a time ``Quantity`` is converted,
    a ``Quantity`` flux keeps its unit for ``sigma``), and whether it is periodic at all: the
    method of the module's docstring. ``sigma``: the 1σ of ``flux`` (scalar or ``(T,)``;
    default: none, the track's own scatter). ``min_period_s``/``max_period_s``: the search range
    (s or a time ``Quantity``; default from the data). ``n_harmonics``: fix the base model's
    harmonics (default: BIC up to ``max_harmonics``). ``detrend``: the order of each stretch's
    polynomial (0 an offset, 1 a slope, 2 the default quadratic). ``segments``: ``(T,)`` the
    track of each sample (default: contiguous stretches split at gaps). ``zero_points``: ``(T,)``
    labels of samples sharing a zero point (camera channels). ``convention``: ``photometric`` or
    ``double_peaked``. ``fap_max``, ``min_cycles``: the verdict's thresholds; ``n_surrogates``,
    ``seed``: the null's draws.

    Returns a :class:`~cssat.inversion.results.PeriodResult` (a read-only mapping, its keys also
    attributes; ``.model(t)`` the fitted series and trend at times ``t``): ``verdict``
    (``"periodic"``, ``"not periodic"``, ``"undetermined"``),
    ``periodic`` (True, False, None), ``verdict_why`` (one sentence), ``period_s`` and
    ``period_err_s`` (1σ; NaN unless periodic), ``photometric_period_s``, ``convention``,
    ``n_maxima`` (significant maxima a photometric cycle), ``fap`` and ``fap_all`` (surrogates;
    ``fap_surrogates_exceeding``: how many of the ``n_surrogates`` reached the data), ``fap_white``
    (the white-noise F-test, for comparison), ``repeat``, ``best_period_s``/``best_period_err_s``,
    ``alternatives`` (dicts: ``relation`` — ``"P/4"``, ``"P/3"``, ``"P/2"``, ``"2P"``, ``"3P"``
    or ``"peak"`` —, ``period_s``, ``n_harmonics``, ``chi2``, ``chi2_per_sample``,
    ``delta_bic``), ``fringes`` (cycle counts across gaps within Δχ² 4: ``period_s``,
    ``delta_chi2``), ``cycle_count`` (``one stretch``, ``fixed``, ``ambiguous (…)``, or that the stretches do not
    agree on one period: then ``undetermined``), ``why``, ``n_harmonics``, ``chi2``, ``chi2_per_sample``, ``model_fits``,
    ``n_cycles``, ``min_period_s``/``max_period_s``, ``cadence_s``, ``f0_period_s``,
    ``doubled``, ``warnings`` (list of str), ``noise_sigma`` and ``periodogram``
    (``frequency_hz``, ``power``)."""
    times_s, flux, sigma, min_period_s, max_period_s = _astropy_inputs(times_s, flux, sigma, min_period_s, max_period_s)
    t, y, w, seg_given, zp = _check_track(times_s, flux, sigma, segments, zero_points)
    t = t - t[0]
    span = float(t[-1])
    if not span > 0:
        raise FieldError("times_s", "the samples span no time (all stamps equal)")
    convention = choice_param(convention, "convention", CONVENTIONS)
    if np.ptp(y) == 0:
        return PeriodResult(_constant(t, convention))
    seg = stretches(t) if segments is None else seg_given
    lo, hi, d_frame, longest = _search_range(t, seg, zp, min_period_s, max_period_s)
    max_harmonics, m_fixed, n_peaks, spp, detrend, fap_max, min_cycles, n_sur, seed, min_repeat = _options(
        max_harmonics, n_harmonics, n_peaks, samples_per_peak, detrend, fap_max, min_cycles, n_surrogates, seed, min_repeat)
    cv = _Curve(t, y, w, seg, detrend, sigma is not None, zp)
    dts = np.diff(t)
    f_harm = 0.5 / max(float(np.percentile(dts[dts > 0], 10)), 1e-300)  # the harmonics' ceiling: the finer steps' Nyquist
    f_lo, f_hi = 1.0 / hi, 1.0 / lo
    step = 1.0 / (spp * span)  # the refinement's scale: a tenth of the whole span's peak width
    multi = span >= 1.5 * longest  # stretches far apart: the grid resolves one stretch's peak, fringes() the comb
    grid_step = 1.0 / (spp * longest) if multi else step
    check_grid(int((f_hi - f_lo) / grid_step) + 1, longest, lo, "max_period_s" if min_period_s is None else "min_period_s")
    freq = f_lo + grid_step * np.arange(int((f_hi - f_lo) / grid_step) + 1)
    if len(freq) < 2:  # a range of periods far longer than the track: one trial frequency, no periodogram
        raise FieldError("max_period_s" if min_period_s is None else "min_period_s",
                         f"[{lo:.6g}, {hi:.6g}] s holds one trial frequency over stretches of {longest:.6g} s: periods "
                         "this long are not resolved by the track; give a range of periods shorter than its stretches")
    power, peaks = _periodogram_peaks(t, cv.yp / w, None if sigma is None else 1.0 / w, freq, span, n_peaks,
                                      seg if multi else None)
    search = Aliases(cv, lo, hi, step, max_harmonics, f_harm, longest, m_fixed, grid_step)
    cands = search.of_peaks(peaks)
    if not cands:
        raise FieldError("flux" if min_period_s is None and max_period_s is None else "min_period_s",
                         f"no candidate period within [{lo:.6g}, {hi:.6g}] s")
    for c in sorted(cands, key=lambda c: c["bic"])[:3 if sigma is not None else 0]:  # the leaders refined: ĉ is
        c.update(search.own(c["period_s"], c["n_harmonics"], c.get("k", 1)) or {})     # the best refined fit's
    cv.overdispersion(cands)  # quasi-likelihood: χ² in units of the best candidate's χ²/ν when no series fits to σ
    best = search.settle(min(cands, key=lambda c: c["bic"]), cands)
    f_b, r_b, minima = search.fringes(1.0 / best["period_s"], best["n_harmonics"], best["rss"])
    if r_b < best["rss"]:
        best = {**best, "period_s": 1.0 / f_b, "rss": r_b, "bic": cv.bic(r_b, best["n_harmonics"])}
    m = best["n_harmonics"]
    fb, rss = 1.0 / best["period_s"], best["rss"]
    N = len(t)
    nu = max(N - 2 * m - cv.q, 1)
    scat = max(light_curve_scatter(t, y), 1e-9 * float(np.std(y)), 1e-150)
    chi2 = rss if sigma is not None else rss / scat ** 2
    chi2_n = chi2 / nu
    err_phot = period_error(cv, best, step, chi2_n, nu, sigma is not None)
    noise2 = max(chi2_n, 1.0) if sigma is not None else max(rss, cv.floor) / nu  # RSS units per χ² unit
    p_phot, err_phot, fringes, cycle_count = _across_gaps(cv, fb, m, rss, err_phot, minima, noise2,
                                                          1.0 / (spp * longest) if multi else None, span, detrend)
    coef, cov, trend, resid = _fit(cv, fb, m)
    n_max = count_maxima(coef, cov, fb, m, magnitudes=_is_magnitude(flux, y))
    k_conv = 2 if convention == "double_peaked" and n_max == 1 else 1
    period, period_err = k_conv * p_phot, k_conv * err_phot
    # the false-alarm probability from the track's own noise (surrogates), over all periods and over the well-sampled ones
    fnull, pnull = _null_grid(freq, power, spp)
    detect = fnull >= min_cycles / longest
    # the null's noise: the residual of the chosen series where its period is one the detection
    # covers (>= min_cycles), else of the trend alone (a series of 1-2 cycles and many harmonics
    # absorbs red noise: its residual is whiter than the noise, and the null too weak)
    noise_part = (_stretch_resid(cv, fb, m, detrend) if multi else resid) if p_phot * min_cycles <= longest else y - trend
    null = surrogate_fap(t, y, w, cv.Q, trend, noise_part, fnull, detect, pnull,
                         mean_run_s=max(RUN_FRACTION * longest / max(min_cycles, 1.0), 10 * d_frame),
                         cadence_s=d_frame, n=n_sur, seed=seed, fap_max=fap_max, seg=seg if multi else None,
                         dy=None if sigma is None else 1.0 / w, data=cv.yp / w)
    fap_white = cv.fap(rss, m, span * (f_hi - f_lo))
    rep = cv.repeat(fb, m)
    n_cycles = float(longest / period)
    gap = _phase_gap(t, 1.0 / period)
    noise = float(np.median(1.0 / w)) if sigma is not None else scat
    variation_snr = float(np.std(_design(t, fb, m) @ coef)) / noise
    verdict, why_v = _verdict(null, fap_white, fap_max, n_cycles, min_cycles, gap, MAX_PHASE_GAP, period, rep, min_repeat,
                              lo, hi, variation_snr)
    if verdict == "periodic" and cycle_count.startswith("the stretches do not agree"):
        verdict, why_v = "undetermined", (f"a signal stands out (FAP {null['fap']:.2g}) but {cycle_count}: each track "
                                          "alone may say more (the characterise experiment's tracks.csv)")
    periodic = {"periodic": True, "not periodic": False}.get(verdict)
    alts = search.alternatives(best, p_phot, cands, len(peaks), None if sigma is not None else scat)
    warns, model_fits = _warnings(period, lo, hi, longest, step, alts, chi2_n, m)
    warns += _gap_warnings(cycle_count, fringes, err_phot)
    nan = float("nan")
    ok = verdict == "periodic"
    return PeriodResult({"verdict": verdict, "periodic": periodic, "verdict_why": why_v,
                         "period_s": period if ok else nan, "period_err_s": period_err if ok else nan,
                         "photometric_period_s": p_phot, "convention": convention, "n_maxima": int(n_max),
                         "fap": null["fap"], "fap_all": null["fap_all"], "fap_surrogates_exceeding": null["exceeding"],
                         "n_surrogates": null["n"], "fap_white": fap_white, "repeat": rep, "variation_snr": variation_snr,
                         "best_period_s": period, "best_period_err_s": period_err, "alternatives": alts, "fringes": fringes, "cycle_count": cycle_count,
                         "why": _why(best, alts, k_conv, n_max), "n_harmonics": m, "chi2": float(chi2),
                         "chi2_per_sample": float(chi2_n), "model_fits": model_fits, "n_cycles": n_cycles,
                         "min_period_s": float(lo), "max_period_s": float(hi), "cadence_s": float(d_frame),
                         "f0_period_s": 1.0 / peaks[0], "doubled": bool(k_conv == 2 or best.get("k", 1) > 1), "warnings": warns,
                         "noise_sigma": float(scat) if sigma is None else None, "n_samples": int(N), "rss": float(rss),
                         "n_nuisance": int(cv.q), "periodogram": {"frequency_hz": freq, "power": power}}).with_model(
        times_s, flux, sigma=sigma, segments=segments, zero_points=zero_points, detrend=detrend)


def _options(max_harmonics: Any, n_harmonics: Any, n_peaks: Any, samples_per_peak: Any, detrend: Any, fap_max: Any,
             min_cycles: Any, n_surrogates: Any, seed: Any, min_repeat: Any) -> tuple:
    """:func:`estimate_period`'s options checked, each a FieldError naming it."""
    return (int_param(max_harmonics, "max_harmonics", 1, 50),
            None if n_harmonics is None else int_param(n_harmonics, "n_harmonics", 1, 50),
            int_param(n_peaks, "n_peaks", 1, 20), int_param(samples_per_peak, "samples_per_peak", 1, 1000),
            int_param(detrend, "detrend", 0, 3), float_param(fap_max, "fap_max", 0.0, 1.0),
            float_param(min_cycles, "min_cycles", 0.0), int_param(n_surrogates, "n_surrogates", 2, 10_000),
            int_param(seed, "seed", 0), None if min_repeat is None else float_param(min_repeat, "min_repeat", -1.0, 1.0))


def _gap_warnings(cycle_count: str, fringes: list[dict[str, float]], err_phot: float) -> list[str]:
    """The warnings of a period across gaps: a cycle count not fixed, the competing fringes."""
    out = []
    if cycle_count.startswith("ambiguous"):
        out.append(f"the cycle count across the gaps is not fixed: the stretches alone give P to ±{err_phot:.3g} s, "
                   f"{cycle_count}; the 1σ is theirs")
    if fringes:
        out.append("the fringes across the gaps within Δχ² 4: " + ", ".join(
            f"{fr['period_s']:.8g} s (Δχ² {fr['delta_chi2']:.2g})" for fr in fringes) + "; the 1σ reaches the farthest")
    return out


def _across_gaps(cv: Any, fb: float, m: int, rss: float, err_phot: float, minima: list[tuple[float, float]],
                 noise2: float, stretch_step: float | None, span: float,
                 detrend: int) -> tuple[float, float, list[dict[str, float]], str]:
    """The photometric period (s), its 1σ, the competing fringes and the cycle count across gaps
    (module docstring, point 8): the fringes ``minima`` (Hz, RSS) within Δχ² 4 of the best
    ``fb`` (RSS per χ² unit ``noise2``) widen the 1σ; with stretches far apart
    (``stretch_step``: the periodogram's step, Hz; None for one stretch) the stretches' own fit
    (:func:`~cssat.inversion.period_aliases.stretch_fit`) says whether the cycle count is fixed."""
    p_phot = 1.0 / fb
    fringes = [{"period_s": 1.0 / f, "delta_chi2": float((r - rss) / noise2)} for f, r in minima
               if abs(f - fb) > 1e-9 * fb and (r - rss) / noise2 < FRINGE_DCHI2]
    if fringes:  # the cycle count across the gaps is ambiguous: the 1σ reaches the farthest competitor
        err_phot = max(err_phot, max(abs(fr["period_s"] - p_phot) for fr in fringes))
    if stretch_step is None:
        return p_phot, err_phot, fringes, "one stretch"
    f_inc, sig_inc = stretch_fit(cv, fb, m, stretch_step, detrend)  # fixed only if the stretches pin f under a fringe
    per_sigma = sig_inc * span
    if not math.isfinite(sig_inc):  # the stretches' own fits have no common minimum: no one period to speak of
        return p_phot, err_phot, fringes, "the stretches do not agree on one period (no minimum of their summed χ² near it)"
    if per_sigma < FRINGE_FIXED:
        return p_phot, err_phot, fringes, "fixed"
    # the least-χ² fringe is one of many alike: the envelope's centre instead, and its 1σ
    return 1.0 / f_inc, max(err_phot, sig_inc / f_inc ** 2), fringes, f"ambiguous ({per_sigma:.3g} fringes a 1σ)"


def _is_magnitude(flux: Any, y: np.ndarray) -> bool:
    """Whether ``y`` reads as magnitudes (brighter = smaller): a mag unit, else a median under 30
    with values spanning under 15 (a flux in W/m² is ~1e-15, in counts or Jy positive and large)."""
    unit = str(getattr(flux, "unit", "")).strip()
    if unit:
        return "mag" in unit
    return bool(np.all(np.abs(y) < 40) and np.ptp(y) < 15 and np.median(y) > 1e-3)


def convention_for(name: Any) -> str:
    """The period convention of an object by its catalogue name: ``double_peaked`` for a rocket
    body (``R/B``, ``ROCKET``, ``AKM``/``PKM`` stages: two maxima a turn, the full turn reported
    — MMT's convention), else ``photometric`` (payloads and debris: the light curve's own
    period, as MMT reports them too)."""
    n = str(name or "").upper()
    return "double_peaked" if ("R/B" in n or "ROCKET" in n or re.search(r"\b(AKM|PKM)\b", n)) else "photometric"


def _null_grid(freq: np.ndarray, power: np.ndarray, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """The null's grid (Hz), the search's thinned to about :data:`SURROGATE_SPP` points a peak,
    and the data's power on it (the surrogates' statistic, computed alike)."""
    sub = slice(None, None, max(1, spp // SURROGATE_SPP))
    return freq[sub], power[sub]


def _stretch_resid(cv: Any, f: float, m: int, detrend: int) -> np.ndarray:
    """``(T,)`` the residual of the ``m``-harmonic series at ``f`` fitted to each contiguous
    stretch apart (its own amplitudes and phases, its own trend: a light curve that changes from
    night to night with the geometry leaves its misfit, periodic itself, out of the null's noise)."""
    out = np.zeros_like(cv.y)
    for k in np.unique(cv.seg):
        on = cv.seg == k
        X = np.concatenate([np.stack([(cv.t[on] - cv.t[on].mean()) ** j for j in range(detrend + 1)], 1),
                            _design(cv.t[on], f, m)], 1) * cv.w[on][:, None]
        if on.sum() <= X.shape[1]:
            continue
        coef, *_ = np.linalg.lstsq(X, cv.y[on] * cv.w[on], rcond=None)
        out[on] = cv.y[on] - (X @ coef) / cv.w[on]
    return out


def _fit(cv: Any, f: float, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ``m``-harmonic series at ``f`` with the nuisance model, fitted (weighted): the series'
    coefficients ``(2m,)`` and their covariance ``(2m, 2m)`` (the residual's own scale), the
    nuisance model ``(T,)`` and the residual ``(T,)`` in the data's units."""
    X = np.concatenate([cv.Q, _design(cv.t, f, m) * cv.w[:, None]], 1)
    yw = cv.y * cv.w
    coef, *_ = np.linalg.lstsq(X, yw, rcond=None)
    r = yw - X @ coef
    nu = max(len(yw) - X.shape[1], 1)
    s2 = float(r @ r) / nu if not cv.known else max(float(r @ r) / nu, 1.0)
    cov = np.linalg.pinv(X.T @ X)[cv.q:, cv.q:] * s2
    trend = (cv.Q @ coef[:cv.q]) / cv.w
    return coef[cv.q:], cov, trend, r / cv.w


def _phase_gap(t: np.ndarray, f: float) -> float:
    """The largest empty stretch of phase (fraction of a cycle) in the fold of ``t`` at ``f``."""
    ph = np.sort((t * f) % 1.0)
    return float(np.max(np.diff(np.r_[ph, ph[0] + 1.0]))) if len(ph) else 1.0


def _search_range(t: np.ndarray, seg: np.ndarray, zp: Any, min_period_s: float | None,
                  max_period_s: float | None) -> tuple[float, float, float, float]:
    """The periods searched, ``(lo, hi)`` in s (given, or the cadence's Nyquist period twice the
    frame step to the longest stretch), the frame step (:func:`~cssat.inversion.fourier.frame_step`,
    within each channel ``zp``) and the longest contiguous stretch (s), for ``t (T,)`` in
    stretches ``seg (T,)``."""
    longest = max(float(t[seg == k][-1] - t[seg == k][0]) for k in np.unique(seg))
    d_frame = frame_step(t, seg, zp)
    lo = 2 * d_frame if min_period_s is None else float_param(min_period_s, "min_period_s", 0.0, open_lo=True)
    hi = longest if max_period_s is None else float_param(max_period_s, "max_period_s", 0.0, open_lo=True)
    if not hi > lo:
        raise FieldError("max_period_s", f"must exceed min_period_s ({lo:.6g} s), got {hi:.6g} s"
                         + (" (by default the longest stretch: the track is too short for its cadence)"
                            if max_period_s is None else ""))
    return lo, hi, d_frame, longest


def _periodogram_peaks(t: np.ndarray, resid: np.ndarray, dy: np.ndarray | None, freq: np.ndarray, span: float,
                       n_peaks: int, seg: np.ndarray | None = None) -> tuple[np.ndarray, list[float]]:
    """astropy's Lomb–Scargle of ``resid (T,)`` (the curve less its nuisance model; ``dy`` its 1σ
    or ``None``) on the regular grid ``freq (F,)`` Hz — with ``seg (T,)`` given, the stretches'
    own periodograms summed (:func:`~cssat.inversion.period_null.stretch_power`) —: the power,
    and the ``n_peaks`` strongest local maxima a peak's width apart, strongest first."""
    sep = 1.5 / span if seg is None else 1.5 * (freq[1] - freq[0]) * SURROGATE_SPP * 2  # a peak's width apart
    power = stretch_power(t, resid, freq, seg, dy, MIN_SAMPLES)
    is_max = np.r_[True, power[1:] >= power[:-1]] & np.r_[power[:-1] >= power[1:], True]
    peaks: list[float] = []
    for i in np.flatnonzero(is_max)[np.argsort(power[is_max])[::-1]]:
        if all(abs(freq[i] - p) > sep for p in peaks):
            peaks.append(float(freq[i]))
        if len(peaks) == n_peaks:
            break
    return power, peaks
