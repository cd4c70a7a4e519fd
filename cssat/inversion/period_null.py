"""How likely is a period found in noise alone, and how many maxima does a cycle show?
(:func:`cssat.inversion.estimate_period`'s verdict and convention).

**The false-alarm probability from the track's own noise** (:func:`surrogate_fap`). A real
track's residuals are red (seeing, tracking, a slowly changing aspect): the white-noise F-test
over-states significance by orders of magnitude on them. The null here is fitted per track:

1. the residual ``r = y − trend − series`` of the chosen model (the track's noise, red or
   white, with the periodic signal taken out);
2. ``n`` surrogates ``y* = trend + r*``, ``r*`` a *stationary bootstrap* of ``r`` (Politis &
   Romano 1994: runs of consecutive samples of geometric length, mean ``L`` s, joined in random
   order from random starts, circularly): correlations shorter than ``L`` kept, any periodicity
   destroyed;
3. each surrogate searched exactly as the data (the nuisance model projected out, Lomb–Scargle
   on the same grid): the largest harmonic sum ``z* = max_f Σ_k −ln(1 − p*(k f))``, ``k = 1…4``
   (:func:`harmonic_sum`: a glinting or double-peaked curve spreads its power over harmonics);
4. a Gumbel law fitted to the ``z*`` by moments (the maximum of many nearly independent
   periodogram ordinates: Süveges 2014, MNRAS 440, 2099), its tail at the data's own ``z``.

``L`` is the longest period detected (``longest / min_cycles``, a third of the longest stretch
by default; at least 10 frame steps): the noise is kept on every scale the detection is about
(runs as long as the chosen period: a shorter ``L`` whitened red noise and called 39 of 40
red-noise tracks significant at 0.1). Below ``1/n`` the FAP is the fitted
tail's extrapolation (reported as such: ``fap_surrogates_exceeding``); its calibration on
real non-variable tracks and on surrogates of real tracks is in BENCHMARKS.md.
Two grids are scored from the same surrogates: all periods searched, and the periods of at
least ``min_cycles`` cycles (the detection).

**Maxima per cycle** (:func:`count_maxima`): the fitted series on a fine phase grid; a maximum
of brightness counts when its prominence (the drop to the deepest point before a higher one,
on its shallower side) is at least :data:`MIN_PROMINENCE` of the largest and
:data:`MIN_SIGNIFICANCE` standard errors of the fitted difference (from the coefficients'
covariance). Rocket bodies show two maxima a turn; a fold with one is half a turn (the
``double_peaked`` convention).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["surrogate_fap", "stretch_power", "fast_power", "harmonic_sum", "count_maxima", "MIN_PROMINENCE", "MIN_SIGNIFICANCE"]

#: a secondary maximum counts when its prominence is this fraction of the largest ...
MIN_PROMINENCE = 0.25
#: ... and this many standard errors of the fitted series' difference (peak less its saddle)
MIN_SIGNIFICANCE = 4.0
EULER_GAMMA = 0.5772156649015329
#: the harmonics summed in the detection statistic (:func:`harmonic_sum`)
HARMONICS = 4
#: surrogates are drawn in rounds of this many; after the first and second round the draws stop
#: when the verdict is beyond doubt (:func:`_decided`)
EARLY = 6


def _bootstrap(r: np.ndarray, mean_run: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary bootstrap of ``r (T,)``: runs of geometric length (mean ``mean_run``
    samples) from uniform random starts, circular, concatenated to length T."""
    n = len(r)
    p = 1.0 / max(mean_run, 1.0)
    idx = np.empty(n, dtype=np.int64)
    k = 0
    while k < n:
        run = min(int(rng.geometric(p)), n - k)
        idx[k:k + run] = (int(rng.integers(n)) + np.arange(run)) % n
        k += run
    return r[idx]


def _z(p: np.ndarray | float) -> np.ndarray:
    """``−ln(1 − p)``: Lomb–Scargle power on a scale where its tail is exponential."""
    return -np.log1p(-np.clip(np.asarray(p, dtype=np.float64), 0.0, 1.0 - 1e-15))


def harmonic_sum(power: np.ndarray, freq: np.ndarray, n_harm: int = HARMONICS) -> np.ndarray:
    """``(F,)``: ``Σ_k −ln(1 − p(k f))`` for ``k = 1…n_harm`` on the regular grid ``freq (F,)``
    (Hz) of the Lomb–Scargle power ``power (F,)`` (harmonics off the grid count 0): a curve whose
    power is spread over harmonics (glints, two unequal maxima) adds up (incoherent harmonic
    summing)."""
    F = len(freq)
    if F < 2:
        return _z(power)
    h = float(freq[1] - freq[0])
    i = np.arange(F)
    z = _z(power)
    out = z.copy()
    for k in range(2, n_harm + 1):
        j = np.rint(k * i + (k - 1) * freq[0] / h).astype(np.int64)
        ok = j < F
        out[ok] += z[j[ok]]
    return out


def _same_everywhere(z: float) -> float:
    """``z`` to 10 significant digits: a statistic, hence a FAP, that does not depend on the
    last bits a BLAS's thread count leaves (a catalogue's rows equal across launchers)."""
    return float(f"{z:.10g}")


def _gumbel_sf(z: float, zs: np.ndarray) -> float:
    """``P(Z ≥ z)`` of the Gumbel law with the mean and variance of ``zs``, its scale taken at
    the upper end of its 1σ (``× (1 + 1/√n)``: a scale fitted to a few draws would make the
    extrapolated tail too thin)."""
    sd = float(np.std(zs, ddof=1)) if len(zs) > 1 else 0.0
    if not sd > 0:
        return 0.0 if z > float(np.max(zs)) else 1.0
    beta = sd * math.sqrt(6.0) / math.pi * (1.0 + 1.0 / math.sqrt(len(zs)))
    mu = float(np.mean(zs)) - EULER_GAMMA * beta
    return float(-math.expm1(-math.exp(-(z - mu) / beta)))


def surrogate_fap(t: np.ndarray, y: np.ndarray, w: np.ndarray, Q: np.ndarray, trend: np.ndarray, resid: np.ndarray,
                  freq: np.ndarray, detect: np.ndarray, data_power: np.ndarray, mean_run_s: float,
                  cadence_s: float, n: int, seed: int, fap_max: float = 1e-3,
                  seg: np.ndarray | None = None, dy: np.ndarray | None = None,
                  data: np.ndarray | None = None) -> dict[str, Any]:
    """The false-alarm probabilities of the data's largest harmonic sum (:func:`harmonic_sum`
    of its power ``data_power (F,)``) over all of ``freq (F,)`` and over ``freq[detect]``,
    under ``n`` stationary-bootstrap surrogates ``trend + r*`` of the residual ``resid (T,)``
    (mean run ``mean_run_s`` s; ``cadence_s`` the frame step; ``t, y, w (T,)`` the data and
    weights, ``Q (T, q)`` the orthonormal weighted nuisance basis). The draws stop after 6 (or
    12) when both FAPs are over 30× ``fap_max``, after 12 when both are under 1/30 of it with
    the data above every surrogate (after 6 when under 1e-6 of it). ``seg
    (T,)``: stretches far apart, each searched alone and their powers summed
    (:func:`stretch_power`); ``dy (T,)``: the 1σ the data's own periodogram was weighted by.
    ``data (T,)``: the data less its nuisance model — given, its power is computed here on
    ``freq`` exactly as the surrogates' (:func:`stretch_power`), in place of ``data_power``. Returns ``fap`` (detection grid),
    ``fap_all``, how many surrogates reached each (``exceeding``, ``exceeding_all``), how many
    were drawn (``n``) and the data's statistics (``z_all``, ``z_det``)."""
    rng = np.random.default_rng(seed)
    run = max(mean_run_s / max(cadence_s, 1e-300), 1.0)
    hs = harmonic_sum(data_power if data is None else stretch_power(t, data, freq, seg, dy), freq)
    z_all = _same_everywhere(float(hs.max()))
    z_det = _same_everywhere(float(hs[detect].max())) if detect.any() else 0.0
    zs_all: list[float] = []
    zs_det: list[float] = []
    while len(zs_all) < n:
        for _ in range(min(EARLY, n - len(zs_all))):
            ys = (trend + _bootstrap(resid, run, rng)) * w
            hs = harmonic_sum(stretch_power(t, (ys - Q @ (Q.T @ ys)) / w, freq, seg, dy), freq)
            zs_all.append(_same_everywhere(float(hs.max())))
            zs_det.append(_same_everywhere(float(hs[detect].max())) if detect.any() else 0.0)
        if len(zs_all) in (EARLY, 2 * EARLY) and _decided(z_det, z_all, zs_det, zs_all, fap_max, len(zs_all) >= 2 * EARLY):
            break
    za, zd = np.array(zs_all), np.array(zs_det)
    return {"fap": _gumbel_sf(z_det, zd) if detect.any() else 1.0, "fap_all": _gumbel_sf(z_all, za),
            "exceeding": int((zd >= z_det).sum()), "exceeding_all": int((za >= z_all).sum()), "n": len(za),
            "z_all": z_all, "z_det": z_det}


def fast_power(t: np.ndarray, y: np.ndarray, freq: np.ndarray, dy: np.ndarray | None = None) -> np.ndarray:
    """``(F,)`` astropy's Lomb–Scargle power (``standard`` normalisation, a fitted mean) of ``y (T,)``
    at ``t (T,)`` on the regular grid ``freq (F,)`` by Press & Rybicki's extirpolation and FFT
    (``fasper``: ~1e-4 of the power off the exact sums, 3-5× faster than astropy 8's default
    low-rank ``lra``; named, so every astropy version computes the same: before 8 it was the only
    fast algorithm). numpy's FFT runs on one thread: the same bits whatever the BLAS threads."""
    from astropy.timeseries import LombScargle  # heavy: astropy, only for fast_power()

    ls = LombScargle(t, y, dy)
    try:
        return ls.power(freq, method="fast", assume_regular_frequency=True, method_kwds={"algorithm": "fasper"})
    except TypeError:  # astropy < 8: no choice of algorithm, fasper
        return ls.power(freq, method="fast", assume_regular_frequency=True)


def stretch_power(t: np.ndarray, y: np.ndarray, freq: np.ndarray, seg: np.ndarray | None = None,
                  dy: np.ndarray | None = None, min_samples: int = 12) -> np.ndarray:
    """``(F,)`` astropy's Lomb–Scargle power of ``y (T,)`` at ``t (T,)`` on the regular grid
    ``freq (F,)``; with ``seg (T,)`` the stretches' own powers summed, weighted by their samples
    (stretches days apart: the envelope of the fringes between them, which a grid of one
    stretch's resolution cannot sample)."""
    if seg is None:
        return fast_power(t, y, freq, dy)
    power, n = np.zeros(len(freq)), 0
    for k in np.unique(seg):
        on = seg == k
        if on.sum() >= min_samples and np.ptp(y[on]) > 0:
            power += on.sum() * fast_power(t[on], y[on], freq, None if dy is None else dy[on])
            n += int(on.sum())
    return power / max(n, 1)


def _decided(z_det: float, z_all: float, zs_det: list[float], zs_all: list[float], fap_max: float,
             below_too: bool = True) -> bool:
    """Whether the surrogates drawn so far settle the verdict at ``fap_max`` beyond doubt: both
    FAPs over 30× of it, or under 1/30 of it with the data above every surrogate (``below_too``:
    after two rounds; after one, under 1e-6 of it)."""
    fd, fa = _gumbel_sf(z_det, np.array(zs_det)), _gumbel_sf(z_all, np.array(zs_all))
    far_above = all(f > 30 * fap_max for f in (fd, fa))
    above_all = z_det > max(zs_det) and z_all > max(zs_all)
    margin = fap_max / 30 if below_too else fap_max * 1e-6  # after one round only a detection six decades out
    far_below = all(f < margin for f in (fd, fa)) and above_all
    return far_above or far_below


def count_maxima(coef: np.ndarray, cov: np.ndarray, f: float, m: int, magnitudes: bool, n_phase: int = 360) -> int:
    """The number of significant brightness maxima in one cycle of the ``m``-harmonic series
    ``coef (2m,)`` (cos then sin; ``cov (2m, 2m)`` their covariance) at ``f`` Hz; a magnitude's
    maxima of brightness are its minima (``magnitudes``). See the module's docstring."""
    from cssat.inversion.fourier import _design  # heavy: cssat.inversion.fourier imports torch

    ph = np.arange(n_phase) / n_phase
    G = _design(ph / f, f, m)
    s = -1.0 if magnitudes else 1.0
    v = s * (G @ coef)
    is_max = (v >= np.roll(v, 1)) & (v > np.roll(v, -1))
    found = []
    for i in np.flatnonzero(is_max):
        sides = []
        for d in (1, -1):  # walk each way to the deepest point before a higher one
            j, low, jl = i, v[i], i
            for _ in range(n_phase):
                j = (j + d) % n_phase
                if v[j] < low:
                    low, jl = v[j], j
                if v[j] > v[i]:
                    break
            sides.append((v[i] - low, jl))
        prom, jl = min(sides)
        g = G[i] - G[jl]
        se = math.sqrt(max(float(g @ cov @ g), 0.0))
        found.append((prom, prom / se if se > 0 else math.inf))
    if not found:
        return 1
    top = max(p for p, _ in found)
    return max(1, sum(1 for p, z in found if p >= MIN_PROMINENCE * top and z >= MIN_SIGNIFICANCE))
