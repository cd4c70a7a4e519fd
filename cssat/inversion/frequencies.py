"""The two fundamental frequencies of a tumbling (non-principal-axis) rotator's light curve, by
the 2-D Fourier series of Pravec et al. (2005): the verdict "tumbling" against
the one-period series of :func:`cssat.inversion.estimate_period`, by BIC."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.inversion.fourier import _Curve, check_grid, frame_step, stretches
from cssat.inversion.period import estimate_period
from cssat.inversion.periodicity import fold_dispersion

__all__ = ["estimate_tumbling_periods"]


def _wls_chi2(X: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """χ² of the weighted least-squares fit of the design ``X (T, p)`` to ``y`` (weights ``w = 1/σ``)."""
    Xw = X * w[:, None]
    coef, *_ = np.linalg.lstsq(Xw, y * w, rcond=None)
    r = Xw @ coef - y * w
    return float(r @ r)


def _lattice(order: int) -> np.ndarray:
    """The integer pairs ``(j, k) ≠ 0`` with ``|j| + |k| ≤ order``, one of each ``±`` pair."""
    out = [(j, k) for j in range(0, order + 1) for k in range(-order, order + 1)
           if 0 < abs(j) + abs(k) <= order and (j > 0 or k > 0)]
    return np.array(out, dtype=np.float64)


def _chi2_2d(t, y, w, f1, f2, jk) -> float:
    ph = 2 * np.pi * t[:, None] * (jk[:, 0] * f1 + jk[:, 1] * f2)[None, :]
    return _wls_chi2(np.concatenate([np.ones((len(t), 1)), np.cos(ph), np.sin(ph)], 1), y, w)


def estimate_tumbling_periods(times_s: Any, flux: Any, *, sigma: Any = None, min_period_s: float | None = None,
                              max_period_s: float | None = None, order: int = 3, n_peaks: int = 8,
                              samples_per_peak: int = 10, aperiodic_threshold: float = 0.05,
                              window_s: float = 5400.0) -> dict[str, Any]:
    """The two fundamental frequencies of a tumbling (non-principal-axis) rotator's light curve,
    ``flux (T,)`` at ``times_s (T,)``: the 2-D Fourier series of Pravec et al. (2005),

        ``y(t) = c₀ + Σ_{(j,k)} [a_jk cos 2π(j f₁ + k f₂)t + b_jk sin 2π(j f₁ + k f₂)t]``,
        ``0 < |j| + |k| ≤ order``,

    fitted by least squares for candidate pairs ``(f₁, f₂)`` built from the ``n_peaks``
    strongest Lomb–Scargle peaks and their halves (a peak may be a harmonic or a combination),
    the best pairs refined by Nelder–Mead; the single-period series of the same number of terms
    (:func:`estimate_period`'s model, ``order² + order`` harmonics) is the alternative. Returns
    ``frequencies_hz (2,)`` and ``periods_s (2,)`` (a basis of the light curve's frequency
    lattice: any unimodular integer change of it fits equally — for a short-axis-mode tumbler it
    is the precession frequency and the angular velocity's own), ``chi2``, ``chi2_single``,
    ``single_period_s``, ``delta_bic`` (the single-period BIC less the two-period one),
    ``aperiodic`` (:func:`~cssat.inversion.periodicity.fold_dispersion`: the fraction of the
    signal's variance that no single period folds, median over windows of ``window_s``),
    ``tumbling`` and ``why``. The verdict is ``aperiodic > aperiodic_threshold`` (0.05, with
    ``window_s`` 5,400 s: set on the 100 + 100 glinting and 50 + 50 Lambertian synthetic GEO spinners
    and tumblers of ``benchmarks/bench_tumbling_triage.py --seed 0``, checked on other draws):
    not ``delta_bic`` alone, which over nights of changing geometry calls most spinners tumbling (a
    spinner's harmonics drift with the phase angle and a nearly commensurate pair tracks the
    drift). A curve without
    two independent frequencies (one period, or none) is an answer, ``tumbling: False``, not an
    error. ``min_period_s``/``max_period_s`` default to the data's: twice the cadence, half the
    span.

    Assumptions: torque-free motion, whose attitude relative to the fixed angular momentum is
    periodic up to a uniform precession, so the light curve is quasi-periodic in two frequencies;
    the samples span many cycles of both. Each contiguous stretch's offset and slope are fitted
    first (a drift is not a second period). The verdict assumes a principal-axis spinner's curve
    is periodic within a window up to a straight line (GEO geometry turns ≈ 15° an hour) and that
    specular glints are samples above 4× the window's median flux (dropped; see
    :func:`~cssat.inversion.periodicity.fold_dispersion`)."""
    from astropy.timeseries import LombScargle  # heavy: astropy, only for estimate_tumbling_periods()
    from scipy.optimize import minimize  # heavy: scipy.optimize, only for estimate_tumbling_periods()

    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    y = np.asarray(flux, dtype=np.float64).reshape(-1)
    if t.shape != y.shape or not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise FieldError("flux", "expected finite times and values of one length")
    order = int_param(order, "order", 1, 10)
    thr = float_param(aperiodic_threshold, "aperiodic_threshold", 0.0, 1.0, open_lo=True)
    win = float_param(window_s, "window_s", 0.0, open_lo=True)
    jk = _lattice(order)
    n_par = 2 * len(jk) + 1
    if len(t) < 2 * n_par:
        raise FieldError("flux", f"a 2-D Fourier series of order {order} needs at least {2 * n_par} samples, got {len(t)}")
    order_ = np.argsort(t, kind="stable")
    t, y = t[order_], y[order_]
    dy = None if sigma is None else np.broadcast_to(np.asarray(sigma, dtype=np.float64), order_.shape)[order_]
    w = np.ones_like(y) if dy is None else 1.0 / dy
    t = t - t[0]
    y_raw = y
    span = float(t[-1])
    if not span > 0 or np.ptp(y) == 0:
        return _not_tumbling("the curve does not vary" if span > 0 else "the samples span no time")

    seg = stretches(t)
    nuisance = _Curve(t, y, w, seg, 1, dy is not None)  # each stretch's offset and slope: a drift is not a period
    y = nuisance.yp / w
    frame = frame_step(t, seg)
    lo = 4 * frame if min_period_s is None else float_param(min_period_s, "min_period_s", 0.0, open_lo=True)  # 2/lo: Nyquist
    hi = span / 2 if max_period_s is None else float_param(max_period_s, "max_period_s", lo, open_lo=True)
    if not hi > lo:
        raise FieldError("max_period_s", f"must exceed min_period_s ({lo:.6g} s), got {hi:.6g} s")
    spp = int_param(samples_per_peak, "samples_per_peak", 1)
    check_grid(int((2 / lo - 1 / hi) * spp * span) + 1, span, lo, "max_period_s" if min_period_s is None else "min_period_s")
    freq, power = LombScargle(t, y, dy).autopower(minimum_frequency=1 / hi, maximum_frequency=2 / lo, samples_per_peak=spp)
    peaks: list[float] = []
    for i in np.argsort(power)[::-1]:
        if all(abs(freq[i] - p) > 2 / span for p in peaks):
            peaks.append(float(freq[i]))
        if len(peaks) == int_param(n_peaks, "n_peaks", 2, 50):
            break
    cands = sorted(set(peaks + [p / 2 for p in peaks if p / 2 >= 1 / hi]))

    def degenerate(f1, f2):  # a small integer combination vanishes: the pair spans one frequency
        return any(abs(j * f1 + k * f2) < 2 / span for j, k in jk)

    scored = sorted((_chi2_2d(t, y, w, a, b, jk), a, b) for i, a in enumerate(cands) for b in cands[i + 1:]
                    if not degenerate(a, b))
    if not scored:
        return _not_tumbling("no two independent frequencies among the periodogram's peaks")
    best = None
    for c0, a, b in scored[:3]:
        scale = 1.0 / (360.0 * span)  # a frequency step of 1° of phase over the span
        res = minimize(lambda z: _chi2_2d(t, y, w, a + z[0] * scale, b + z[1] * scale, jk), np.zeros(2), method="Nelder-Mead",
                       options={"initial_simplex": [[0, 0], [30, 0], [0, 30]], "xatol": 1e-3, "fatol": 1e-12 * max(c0, 1e-300)})
        cand = (float(res.fun), a + res.x[0] * scale, b + res.x[1] * scale)
        if best is None or cand[0] < best[0]:
            best = cand
    chi2, f1, f2 = best
    single = estimate_period(t, y, sigma=dy, min_period_s=lo, max_period_s=hi, n_harmonics=min(len(jk), 50), detrend=1,
                             segments=seg, n_surrogates=2)  # its fit, not its verdict: the fewest surrogates
    T = len(t)
    bic = lambda c, k: (c if dy is not None else T * np.log(max(c, 1e-300) / T)) + k * np.log(T)  # noqa: E731
    delta = float(bic(single["rss"], 2 * single["n_harmonics"] + single["n_nuisance"] + 1) - bic(chi2, n_par + 1 + nuisance.q))
    fs = np.array(sorted((abs(f1), abs(f2)), reverse=True))
    fold = fold_dispersion(t, y_raw, dy, lo, hi, window_s=win)
    ap = fold["aperiodic"]
    tumbling = bool(ap > thr)
    why = (f"no single period folds {ap:.3g} (> {thr:.3g}) of the signal over {fold['windows']} window(s)" if tumbling else f"one period folds the curve (aperiodic fraction {ap:.3g} ≤ {thr:.3g}): not tumbling"
           if ap == ap else "no window with a significant signal: not tumbling")
    return {"frequencies_hz": fs, "periods_s": 1.0 / fs, "chi2": chi2, "chi2_single": float(single["rss"]),
            "single_period_s": float(single["best_period_s"]), "delta_bic": delta, "aperiodic": ap,
            "tumbling": tumbling, "why": why}


def _not_tumbling(why: str) -> dict[str, Any]:
    nan = float("nan")
    return {"frequencies_hz": np.full(2, nan), "periods_s": np.full(2, nan), "chi2": nan, "chi2_single": nan,
            "single_period_s": nan, "delta_bic": 0.0, "aperiodic": nan, "tumbling": False, "why": why}


# --- the pole and the sidereal period ----------------------------------------------------------
