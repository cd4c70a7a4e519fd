"""The period of a light curve, and whether it has one (issue 34, point 3).

:func:`estimate_period` is built for real tracks (Mini-MegaTORTORA, SCORE, a telescope's own
photometry) with its defaults:

1. **Bounds from the data.** The search runs from the cadence's Nyquist period ``2 d`` (``d``
   the frame step: the 75th percentile of the steps inside contiguous stretches, so two camera
   channels interleaved milliseconds apart do not fake a faster cadence) to half the longest
   contiguous stretch (two cycles), unless ``min_period_s``/``max_period_s`` are given; the
   aliases stay in that range (a "period" as long as the track would absorb its drifts).
2. **Periodogram.** astropy's Lomb–Scargle (``nterms=1``, its fast method, on a grid of
   ``samples_per_peak`` points per peak width ``1/span``) gives the ``n_peaks`` strongest
   distinct frequencies ``f``. A rotating body's light curve puts its power in harmonics of
   the spin frequency: two maxima a turn put the peak at ``2/P``, four glints at ``4/P``.
3. **Multi-harmonic models and aliases.** For each peak the frequency is refined by least
   squares of an ``m``-harmonic Fourier series (``m`` by BIC), then the candidate periods
   ``k/f`` (``k = 1…4``) are scored with ``k m`` harmonics (all reach the same highest
   frequency, so the longer period's model nests the shorter one's) by the Bayesian information
   criterion ``BIC = N ln(RSS/N) + p ln N`` (or ``χ²/ĉ + p ln N`` when ``sigma`` is given,
   ``ĉ = max(1, χ²/ν)`` of the best peak candidate: quasi-likelihood, so a drifting or glinting
   curve does not buy harmonics with 4P): a longer period wins only when its extra (odd)
   harmonics pay for themselves. The chosen
   period's ``P/4, P/2, 2P`` and the other peaks' best periods are the ``alternatives``, each
   with its χ², χ²/N and ΔBIC; ``why`` says in words why the chosen one won.
4. **A verdict.** ``fap``: the false-alarm probability of the chosen model against a constant
   — the F-test's tail over the ``N_eff = span·Δf`` independent frequencies searched (Horne &
   Baliunas 1986). ``repeat``: the model fitted to one half of the track predicts the other
   (the even cycles predict the odd ones and back: R² of the prediction over the in-sample R²,
   the worse of the two): a periodic light curve repeats, red noise and trends do not. ``periodic``
   is ``fap < fap_max`` and ``repeat >= min_repeat`` (0.7; a track too short to compare cycles
   is not called periodic); when it is false ``period_s`` is NaN
   (``best_period_s`` keeps the best candidate): no significant period is an answer.
5. **Uncertainties.** ``period_err_s`` from the curvature of χ² in frequency (Δχ² = 1),
   with ``sigma`` scaled by √(χ²/ν) when the model does not fit to the noise, else with the
   residual's own scatter (its coverage: ``benchmarks/bench_coverage.py``; across gaps the
   least-χ² fringe is searched for, :meth:`_Aliases.fringes`). ``chi2_per_sample`` is χ²/ν
   against ``sigma``, or, without it, against the point-to-point scatter of the track
   (``1.4826 MAD(Δy)/√2``); > 3 sets ``model_fits`` false and warns (a glinting or changing
   curve the Fourier series misses).

The period found is the *synodic* one, that of the light curve (see :mod:`cssat.inversion.spin`).
Assumptions: a strictly periodic signal plus noise that is white on the scale of the cadence;
magnitudes and fluxes both work (the series fits either).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.inversion.fourier import _Curve, _vector, check_grid, frame_step, light_curve_scatter, stretches
from cssat.inversion.period_verdict import _constant, _warnings, _why

__all__ = ["estimate_period", "light_curve_scatter"]

MIN_SAMPLES = 12
#: the ΔBIC by which a period must beat its half to be chosen over it (Occam: the simpler model
#: wins a near tie; "strong evidence" on Kass & Raftery's scale is ΔBIC 6-10)
ALIAS_MARGIN = 6.0


def estimate_period(times_s: Any, flux: Any, *, sigma: Any = None, min_period_s: float | None = None,
                    max_period_s: float | None = None, n_harmonics: int | None = None, max_harmonics: int = 8,
                    n_peaks: int = 3, samples_per_peak: int = 10, detrend: int = 1, segments: Any = None,
                    fap_max: float = 1e-3,
                    min_repeat: float = 0.7) -> dict[str, Any]:
    """The period of the light curve ``flux (T,)`` (a flux or a magnitude) at ``times_s (T,)``
    (seconds, any cadence, any order), and whether it is periodic at all: the method of the
    module's docstring. ``sigma``: the 1σ of ``flux`` (scalar or ``(T,)``; default: none, the
    track's own scatter). ``min_period_s``/``max_period_s``: the search range (default: from
    the data: twice the cadence to half the longest contiguous stretch). ``n_harmonics``: fix
    the base model's harmonics (default: BIC up to ``max_harmonics``). ``detrend``: the order of
    the polynomial fitted to each contiguous stretch alongside the series (0: an offset per
    stretch — per-track magnitude offsets —, 1: and a slope, the default). ``segments``: ``(T,)``
    the track of each sample (e.g. a file's track ids; default: contiguous stretches split at gaps).

    Returns a dict: ``period_s`` and ``period_err_s`` (1σ; both NaN when not periodic),
    ``periodic`` (bool), ``fap``, ``repeat``, ``best_period_s``/``best_period_err_s`` (the best
    candidate, periodic or not), ``alternatives`` (list of dicts: ``relation`` — ``"P/4"``,
    ``"P/2"``, ``"2P"`` or ``"peak"`` —, ``period_s``, ``n_harmonics``, ``chi2``,
    ``chi2_per_sample``, ``delta_bic`` over the chosen), ``why``, ``n_harmonics``, ``chi2``,
    ``chi2_per_sample``, ``model_fits``, ``n_cycles``, ``min_period_s``/``max_period_s`` (the
    range searched), ``f0_period_s`` (the periodogram's peak), ``doubled`` (the chosen period is
    a multiple of the peak's), ``warnings`` (list of str), ``noise_sigma`` (the scatter used
    without ``sigma``) and ``periodogram`` (``frequency_hz``, ``power`` arrays)."""
    t, y, w, seg_given = _check_track(times_s, flux, sigma, segments)
    t = t - t[0]
    span = float(t[-1])
    if not span > 0:
        raise FieldError("times_s", "the samples span no time (all stamps equal)")
    if np.ptp(y) == 0:
        return _constant(t)
    seg = stretches(t) if segments is None else seg_given
    lo, hi, d_frame, longest = _search_range(t, seg, min_period_s, max_period_s)
    # the aliases stay in the range too: a "period" as long as the track absorbs its drifts (on
    # MMT-like tracks, allowing 1-2 cycles costs more periodic tracks than it gains)
    max_harmonics = int_param(max_harmonics, "max_harmonics", 1, 50)
    m_fixed = None if n_harmonics is None else int_param(n_harmonics, "n_harmonics", 1, 50)
    n_peaks = int_param(n_peaks, "n_peaks", 1, 20)
    spp = int_param(samples_per_peak, "samples_per_peak", 1, 1000)
    detrend = int_param(detrend, "detrend", 0, 3)
    fap_max = float_param(fap_max, "fap_max", 0.0, 1.0)
    min_repeat = float_param(min_repeat, "min_repeat", -1.0, 1.0)
    cv = _Curve(t, y, w, seg, detrend, sigma is not None)
    dts = np.diff(t)
    f_harm = 0.5 / max(float(np.percentile(dts[dts > 0], 10)), 1e-300)  # the harmonics' ceiling: the finer steps' Nyquist
    f_lo, f_hi = 1.0 / hi, max(min(4.0 / lo, 0.5 / d_frame), 1.0 / lo)
    step = 1.0 / (spp * span)
    check_grid(int((f_hi - f_lo) / step) + 1, span, lo, "max_period_s" if min_period_s is None else "min_period_s")
    freq, power, peaks = _periodogram_peaks(t, cv.yp / w, None if sigma is None else 1.0 / w, f_lo, f_hi, spp, span, n_peaks)
    search = _Aliases(cv, lo, hi, step, max_harmonics, f_harm, longest)
    cands = search.of_peaks(peaks, m_fixed)
    if not cands:
        raise FieldError("flux" if min_period_s is None and max_period_s is None else "min_period_s",
                         f"no candidate period within [{lo:.6g}, {hi:.6g}] s")
    cv.overdispersion(cands)  # quasi-likelihood: χ² in units of the best candidate's χ²/ν when no series fits to σ
    best = search.settle(_best_of_families(cands, len(peaks)), cands)
    f_b, r_b = search.fringes(1.0 / best["period_s"], best["n_harmonics"], best["rss"])
    if r_b < best["rss"]:
        best = {**best, "period_s": 1.0 / f_b, "rss": r_b, "bic": cv.bic(r_b, best["n_harmonics"])}
    m = best["n_harmonics"]
    fb, rss = 1.0 / best["period_s"], best["rss"]
    N = len(t)
    nu = max(N - 2 * m - cv.q, 1)
    scat = max(light_curve_scatter(t, y), 1e-9 * float(np.std(y)), 1e-150)
    chi2 = rss if sigma is not None else rss / scat ** 2
    chi2_n = chi2 / nu
    period, period_err = _period_error(cv, best, step, chi2_n, nu, sigma is not None)
    fap = cv.fap(rss, m, span * (f_hi - f_lo))
    rep = cv.repeat(fb, m)
    periodic = bool(fap < fap_max and math.isfinite(rep) and rep >= min_repeat)  # no repeat to test: no verdict of periodic
    alts = search.alternatives(best, period, cands, len(peaks), None if sigma is not None else scat)
    warns, model_fits = _warnings(period, lo, hi, longest, step, alts, chi2_n, m)
    nan = float("nan")
    return {"period_s": period if periodic else nan, "period_err_s": period_err if periodic else nan,
            "periodic": periodic, "fap": fap, "repeat": rep, "best_period_s": period, "best_period_err_s": period_err,
            "alternatives": alts, "why": _why(best, alts), "n_harmonics": m, "chi2": float(chi2),
            "chi2_per_sample": float(chi2_n), "model_fits": model_fits, "n_cycles": float(longest / period),
            "min_period_s": float(lo), "max_period_s": float(hi), "f0_period_s": 1.0 / peaks[0],
            "doubled": bool(best["peak"] == 0 and best["k"] > 1), "warnings": warns,
            "noise_sigma": float(scat) if sigma is None else None, "n_samples": int(N), "rss": float(rss),
            "n_nuisance": int(cv.q),
            "periodogram": {"frequency_hz": freq, "power": power}}


def _check_track(times_s: Any, flux: Any, sigma: Any, segments: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """The track sorted in time, checked: ``t (T,)`` (s), ``y (T,)``, the weights ``w = 1/σ (T,)``
    (ones without ``sigma``) and the track index of each sample ``(T,)`` from ``segments``
    (``None`` when not given)."""
    t = _vector(times_s, "times_s", times=True)
    y = _vector(flux, "flux")
    if t.shape != y.shape:
        raise FieldError("flux", f"expected times and values of one length, got {t.shape} and {y.shape}")
    if not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise FieldError("flux", "the times and values must be finite (drop the rows that are not)")
    if len(t) < MIN_SAMPLES:
        raise FieldError("flux", f"a period needs at least {MIN_SAMPLES} samples, got {len(t)}")
    order = np.argsort(t, kind="stable")
    t, y = t[order], y[order]
    seg_given = None
    if segments is not None:
        labels = np.asarray(segments)
        if labels.shape != order.shape:
            raise FieldError("segments", f"expected one track label per sample ({len(order)}), got {labels.shape}")
        try:
            seg_given = np.unique(labels.astype(str)[order], return_inverse=True)[1].reshape(-1)
        except (TypeError, ValueError):
            raise FieldError("segments", "track labels must be strings or numbers") from None
    if sigma is None:
        w = np.ones_like(y)
    else:
        s = _vector(sigma, "sigma", scalar_ok=True)
        if s.size not in (1, len(order)):
            raise FieldError("sigma", f"expected a scalar or one value per sample ({len(order)}), got {s.size}")
        s = np.broadcast_to(s, (len(order),))[order]
        if not (np.isfinite(s).all() and (s > 0).all()):
            raise FieldError("sigma", "the uncertainties must be finite and > 0")
        w = 1.0 / s
    return t, y, w, seg_given


def _search_range(t: np.ndarray, seg: np.ndarray, min_period_s: float | None,
                  max_period_s: float | None) -> tuple[float, float, float, float]:
    """The periods searched, ``(lo, hi)`` in s (given, or twice the frame step to half the longest
    stretch), the frame step (:func:`~cssat.inversion.fourier.frame_step`) and the longest
    contiguous stretch (s), for ``t (T,)`` in stretches ``seg (T,)``."""
    longest = max(float(t[seg == k][-1] - t[seg == k][0]) for k in np.unique(seg))
    d_frame = frame_step(t, seg)
    lo = 2 * d_frame if min_period_s is None else float_param(min_period_s, "min_period_s", 0.0, open_lo=True)
    hi = longest / 2 if max_period_s is None else float_param(max_period_s, "max_period_s", 0.0, open_lo=True)
    if not hi > lo:
        raise FieldError("max_period_s", f"must exceed min_period_s ({lo:.6g} s), got {hi:.6g} s"
                         + (" (by default half the longest stretch: the track is too short for its cadence)"
                            if max_period_s is None else ""))
    return lo, hi, d_frame, longest


def _periodogram_peaks(t: np.ndarray, resid: np.ndarray, dy: np.ndarray | None, f_lo: float, f_hi: float, spp: int,
                       span: float, n_peaks: int) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """astropy's Lomb–Scargle of ``resid (T,)`` (the curve less its nuisance model; ``dy`` its 1σ
    or ``None``) between ``f_lo`` and ``f_hi`` Hz, ``spp`` samples per peak: the frequencies, the
    power, and the ``n_peaks`` strongest local maxima more than ``1.5/span`` apart, strongest first."""
    from astropy.timeseries import LombScargle  # heavy: astropy, only for _periodogram_peaks()

    freq, power = LombScargle(t, resid, dy).autopower(minimum_frequency=f_lo, maximum_frequency=f_hi, samples_per_peak=spp)
    is_max = np.r_[True, power[1:] >= power[:-1]] & np.r_[power[:-1] >= power[1:], True]
    peaks: list[float] = []
    for i in np.flatnonzero(is_max)[np.argsort(power[is_max])[::-1]]:
        if all(abs(freq[i] - p) > 1.5 / span for p in peaks):
            peaks.append(float(freq[i]))
        if len(peaks) == n_peaks:
            break
    return freq, power, peaks


class _Aliases:
    """The candidate periods of one curve (``cv``, :class:`~cssat.inversion.fourier._Curve`) within
    ``[lo, hi]`` s: the peaks' multiples ``k/f`` and the chosen period's halves and doubles, each
    with its own least-BIC harmonics under the finer steps' Nyquist ``f_harm`` (Hz), refined to a
    fraction of ``step`` (Hz)."""

    cap = 24  # harmonics of the longest candidate (49 columns)

    def __init__(self, cv: Any, lo: float, hi: float, step: float, max_harmonics: int, f_harm: float, longest: float):
        self.cv, self.lo, self.hi, self.step, self.max_harmonics, self.f_harm = cv, lo, hi, step, max_harmonics, f_harm
        self.longest = longest  # the longest contiguous stretch (s), for fringes()

    def harmonics_at(self, f: float) -> int:
        """The highest harmonic of ``f`` under the finer steps' Nyquist."""
        return max(1, min(self.cap, int(self.f_harm / f)))

    def of_peaks(self, peaks: list[float], m_fixed: int | None) -> list[dict[str, Any]]:
        """One candidate per peak ``j`` and ``k = 1…4`` in range: the period ``k/f`` of the refined
        peak ``f``, with ``k m`` harmonics or its own least-BIC number near it (``m``: ``m_fixed``
        or the peak's own by BIC)."""
        cv, max_harmonics = self.cv, self.max_harmonics
        cands = []  # one dict per (peak, k)
        for j, f in enumerate(peaks):
            m0 = m_fixed or cv.best_m(f, min(max_harmonics, self.harmonics_at(f)))
            f_ref, r_ref = cv.refine(f, m0, self.step)
            f_ref, _ = self.fringes(f_ref, m0, r_ref)
            for k in (1, 2, 3, 4):
                P = k / f_ref
                if not self.lo <= P <= self.hi:
                    continue
                c = cv.best_near(f_ref / k, k * m0, min(k * max_harmonics, self.harmonics_at(f_ref / k)))
                c.update(peak=j, k=k)
                cands.append(c)
        return cands

    def own(self, P: float, k: float, peak: int, best: dict[str, Any]) -> dict[str, Any] | None:
        """The period ``P`` with its own least-BIC harmonics (from ``best``'s per cycle), refined
        (None outside the range)."""
        if not self.lo <= P <= self.hi:
            return None
        cv = self.cv
        c = cv.best_near(1 / P, max(1, int(round(best["n_harmonics"] * P / best["period_s"]))),
                         min(max(1, int(round(k)) if k >= 1 else 1) * self.max_harmonics, self.harmonics_at(1 / P)))
        f, r = cv.refine(1 / P, c["n_harmonics"], self.step / max(k, 1))
        return {**c, "period_s": 1 / f, "rss": r, "bic": cv.bic(r, c["n_harmonics"]), "peak": peak, "k": k}

    def settle(self, best: dict[str, Any], cands: list[dict[str, Any]]) -> dict[str, Any]:
        """``best`` refined with its own harmonics, then replaced by its half or double while one
        wins (at most four times); each winner is appended to ``cands``."""
        best = self.own(best["period_s"], best["k"], best["peak"], best) or best
        for _ in range(4):  # the chosen period's half and double compete, each with its own harmonics, refined:
            # the half wins unless the chosen one is better by ALIAS_MARGIN, the double only when better by it
            half, double = (self.own(best["period_s"] * x, best["k"] * x, best["peak"], best) for x in (0.5, 2.0))
            if half is not None and half["bic"] < best["bic"] + ALIAS_MARGIN:
                win = half
            elif double is not None and double["bic"] + ALIAS_MARGIN < best["bic"]:
                win = double
            else:
                break
            cands.append(win)
            best = win
        return best

    def fringes(self, f0: float, m: int, rss0: float) -> tuple[float, float]:
        """The least-RSS frequency (Hz) of the ``m``-harmonic series within ``f0 ± 0.5/longest``
        (``longest``: the longest stretch, s) and its RSS, else ``(f0, rss0)``: across gaps the RSS
        in frequency is a comb of fringes ``1/gap`` apart, and the periodogram's peak may pick a
        neighbour of the best (a cycle miscounted across the gap). A grid of ``step / min(m, 2)`` of
        the 2-harmonic RSS, its 5 lowest minima refined with ``m``; only when the track spans over
        1.5 stretches."""
        cv = self.cv
        if float(cv.t[-1] - cv.t[0]) < 1.5 * self.longest:
            return f0, rss0
        ms = min(m, 2)  # the comb is found with the first two harmonics, its minima refined with all m
        n = int(0.5 * ms / (self.longest * self.step))
        n_max = 600  # tracks a week apart: ~7 grid points a fringe instead of 20 (3x faster), the 5 lowest refined
        h = self.step / ms * max(1.0, n / n_max)
        n = min(n, n_max)
        grid = f0 + h * np.arange(-n, n + 1)
        rss = np.array([cv.rss(f, ms) for f in grid])
        low = np.flatnonzero(np.r_[True, rss[1:] <= rss[:-1]] & np.r_[rss[:-1] <= rss[1:], True])
        best = (f0, rss0)
        for i in low[np.argsort(rss[low])][:5]:  # the grid is coarse for a deep fringe: refine the 5 lowest
            f, r = cv.refine(float(grid[i]), m, h)
            if r < best[1] and self.lo <= 1 / f <= self.hi:
                best = (f, r)
        return best

    def alternatives(self, best: dict[str, Any], period: float, cands: list[dict[str, Any]], n_peaks: int,
                     scat: float | None) -> list[dict[str, Any]]:
        """The chosen period's (``best``, ``period`` s) ``P/4``, ``P/2``, ``2P`` and the other
        peaks' best candidates, each with its χ² (against ``scat``, the track's scatter, when there
        is no ``sigma``; else ``None``), χ²/ν and ΔBIC over the chosen."""
        cv = self.cv
        m, rss = best["n_harmonics"], best["rss"]
        alts = []
        for rel, k in (("P/4", 0.25), ("P/2", 0.5), ("2P", 2.0)):
            Pa = period * k
            a = self.own(Pa, best["k"] * k, best["peak"], best)
            if a is not None:
                alts.append({"relation": rel, **a})
        for j in range(n_peaks):
            cj = [c for c in cands if c["peak"] == j]
            if j != best["peak"] and cj:
                alts.append({"relation": "peak", **min(cj, key=lambda c: c["bic"])})
        N = len(cv.t)
        for a in alts:
            c2 = a["rss"] if scat is None else a["rss"] / scat ** 2
            a.update(chi2=float(c2), chi2_per_sample=float(c2 / max(N - 2 * a["n_harmonics"] - cv.q, 1)),
                     delta_bic=float(a["bic"] - cv.bic(rss, m)))
            for key in ("rss", "bic", "peak", "k"):
                a.pop(key, None)
        return alts


def _best_of_families(cands: list[dict[str, Any]], n_peaks: int) -> dict[str, Any]:
    """The least-BIC of the peaks' picks: per peak, its multiples ``k = 1…4`` in turn, a longer
    one winning only by :data:`ALIAS_MARGIN`."""
    family = []  # per peak, its multiples k = 1…4 in turn: a longer one wins only by ALIAS_MARGIN
    for j in range(n_peaks):
        pick = None
        for c in sorted((c for c in cands if c["peak"] == j), key=lambda c: c["k"]):
            if pick is None or c["bic"] + ALIAS_MARGIN < pick["bic"]:
                pick = c
        if pick is not None:
            family.append(pick)
    return min(family, key=lambda c: c["bic"])


def _period_error(cv: Any, best: dict[str, Any], step: float, chi2_n: float, nu: int, weighted: bool) -> tuple[float, float]:
    """The chosen period (s) and its 1σ from the curvature of χ² in frequency (Δχ² = 1): ``sigma``
    scaled by √(χ²/ν) when ``weighted`` and the model misfits, else the residual's own scatter."""
    m = best["n_harmonics"]
    fb, rss = 1.0 / best["period_s"], best["rss"]
    h = step / (50 * max(best["k"], 1))
    curv = (cv.rss(fb + h, m) - 2 * rss + cv.rss(fb - h, m)) / h ** 2
    noise2 = max(chi2_n, 1.0) if weighted else max(rss, cv.floor) / nu  # σ² per unit of RSS
    sig_f = max(math.sqrt(2.0 * noise2 / curv) if curv > 0 else float("inf"), step * 1e-5)  # ≥ the refinement's tolerance
    period = 1.0 / fb
    return period, sig_f * period ** 2
