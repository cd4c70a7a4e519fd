"""Is a light curve periodic over short windows? The phase-folding test behind
:func:`cssat.inversion.estimate_tumbling_periods`' verdict: a principal-axis
spinner folds into one smooth curve over an hour or two whatever drift the geometry brings over
the night; a tumbler (two incommensurate frequencies) folds at no single period."""

from __future__ import annotations

import numpy as np

from cssat.inversion.fourier import light_curve_scatter, stretches

__all__ = ["fold_dispersion"]

#: trial frequencies per window at most (the grid coarsens past it)
MAX_TRIALS = 20_000


def _windows(t: np.ndarray, window_s: float, min_samples: int) -> list[np.ndarray]:
    """Index arrays of the windows: each contiguous stretch (night) cut into pieces of about
    ``window_s``; pieces with fewer than ``min_samples`` samples are dropped."""
    seg = stretches(t)
    out = []
    for s in np.unique(seg):
        idx = np.where(seg == s)[0]
        ts = t[idx]
        n = max(1, int(round(float(ts[-1] - ts[0]) / window_s)))
        edges = np.linspace(ts[0], ts[-1], n + 1)
        edges[-1] = np.inf
        for a, b in zip(edges[:-1], edges[1:]):
            j = idx[(ts >= a) & (ts < b)]
            if len(j) >= min_samples:
                out.append(j)
    return out


def _string(tt: np.ndarray, v: np.ndarray, var: np.ndarray, f: float) -> float:
    """Mean over phase-neighbours of ``(v_{i+1} − v_i)² / (σ_i² + σ_{i+1}²)`` folded at ``f``:
    ≈ 1 for a noise-only or perfectly periodic curve (a string-length, or phase-dispersion,
    statistic weighted by the noise)."""
    o = np.argsort((tt * f) % 1.0, kind="stable")
    d = np.diff(v[o])
    return float(np.mean(d * d / (var[o][1:] + var[o][:-1])))


def fold_dispersion(t: np.ndarray, y: np.ndarray, sigma: np.ndarray | None, min_period_s: float, max_period_s: float,
                    window_s: float = 5400.0, glint_factor: float = 4.0) -> dict[str, float]:
    """How far a light curve ``y (T,)`` at ``t (T,)`` s (noise ``sigma (T,)`` or None: from second
    differences) is from periodic over short windows. In each window of about
    ``max(window_s, 2 max_period_s)`` inside one night (≥ 40 samples), after a straight line is
    removed, the noise-weighted string length ``S(f)`` (:func:`_string`) is scanned over
    ``f ∈ [1/max_period_s, 1/min_period_s]`` (step 0.1/window, the 8 best refined to 0.005/window);
    the window's score is the aperiodic fraction of its signal variance,

        ``A = (min_f S(f) − 1) / (median_f S(f) − 1)``,

    near 0 when one period folds the window into one curve, near 1 for noise-like folds. Returns
    ``aperiodic`` (the median of ``A`` over windows; NaN when no window has a significant signal,
    ``median S − 1 ≤ 10/√n``), ``variation`` (the median of ``median_f S − 1``: the signal's
    variance over the noise's) and ``windows`` (how many counted).

    Assumptions: ``y`` of positive median is a flux: it is folded as ``ln max(y, σ)`` (glints
    and shadows on a common scale; a sample below its noise weighs as an error of order 1) and
    samples above ``glint_factor`` × the window's median are dropped as specular glints, which a
    30 s cadence samples too sparsely to fold; otherwise ``y`` is a magnitude, folded as it is. Within a window the geometry (phase angle, aspect) changes little
    (GEO: ≈ 30° an hour or two), so a principal-axis spinner's curve is periodic there up to a
    slow trend; the synodic–sidereal shift is below the grid's resolution."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    s = (np.full_like(y, light_curve_scatter(t, y)) if sigma is None
         else np.broadcast_to(np.asarray(sigma, dtype=np.float64), y.shape))
    flux = bool(np.median(y) > 0)
    yf = np.maximum(y, s)  # a flux at or below its noise: ln y's error is of order 1 (weighted as such)
    v, sv = (np.log(yf), s / yf) if flux else (y, s)
    var = np.maximum(sv, 1e-300) ** 2
    W = max(float(window_s), 2.0 * float(max_period_s))
    scores, variation = [], []
    for j in _windows(t, W, 40):
        if flux:
            j = j[y[j] < glint_factor * max(float(np.median(y[j])), float(np.median(s[j])))]
        if len(j) < 40:
            continue
        tt = t[j] - t[j][0]
        span = max(float(tt[-1]), 1e-300)
        A = np.stack([np.ones_like(tt), tt / span], 1) / sv[j][:, None]
        coef, *_ = np.linalg.lstsq(A, v[j] / sv[j], rcond=None)
        vv = v[j] - (A * sv[j][:, None]) @ coef
        step = max(0.1 / span, (1.0 / min_period_s - 1.0 / max_period_s) / MAX_TRIALS)
        fr = np.arange(1.0 / max_period_s, 1.0 / min_period_s, step)
        S = np.array([_string(tt, vv, var[j], f) for f in fr])
        med = float(np.median(S))
        if not med - 1.0 > 10.0 / np.sqrt(len(j)):
            continue
        best = float(S.min())
        for i in np.argsort(S)[:8]:
            best = min(best, *(_string(tt, vv, var[j], f) for f in fr[i] + np.linspace(-1, 1, 41) * step))
        scores.append((best - 1.0) / (med - 1.0))
        variation.append(med - 1.0)
    if not scores:
        return {"aperiodic": float("nan"), "variation": 0.0, "windows": 0}
    return {"aperiodic": float(np.median(scores)), "variation": float(np.median(variation)), "windows": len(scores)}
