"""The candidate periods of a light curve and their aliases, for
:func:`cssat.inversion.estimate_period`: each candidate with its own least-BIC
number of harmonics, refined in frequency; the choice among the relatives ``P/4, P/3, P/2, P,
2P, 3P`` by the least BIC alone (no margin for either side: a longer period's series nests the
shorter one's, so its extra — odd — harmonics pay their ``ln N`` each or lose); across gaps,
the cycle-count fringes and their Δχ²."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat.inversion.fourier import _Curve

__all__ = ["Aliases", "RELATIVES", "period_error", "stretch_fit"]

#: the relatives of the chosen period that compete with it and are reported (name, factor)
RELATIVES = (("P/4", 0.25), ("P/3", 1 / 3), ("P/2", 0.5), ("2P", 2.0), ("3P", 3.0))
#: the multiples of a periodogram peak's period tried as candidates (the peak may be any harmonic)
PEAK_MULTIPLES = (1, 2, 4)  # P/2, 3P, … of the chosen: its relatives (settle)
#: fringes within this Δχ² of the best are competitors (2σ for one parameter)
FRINGE_DCHI2 = 4.0
#: the most trial frequencies in the map of the fringes (a tenth of a fringe each)
MAX_FRINGE_GRID = 40_000


class Aliases:
    """The candidate periods of one curve (``cv``, :class:`~cssat.inversion.fourier._Curve`) within
    ``[lo, hi]`` s, each with its own least-BIC harmonics under the finer steps' Nyquist
    ``f_harm`` (Hz), refined to a fraction of ``step`` (Hz); ``longest`` the longest contiguous
    stretch (s)."""

    cap = 24  # harmonics of the longest candidate (49 columns)

    def __init__(self, cv: Any, lo: float, hi: float, step: float, max_harmonics: int, f_harm: float, longest: float,
                 m_fixed: int | None = None, grid_step: float | None = None):
        self.cv, self.lo, self.hi, self.step, self.max_harmonics, self.f_harm = cv, lo, hi, step, max_harmonics, f_harm
        self.longest, self.m_fixed = longest, m_fixed
        self.grid_step = step if grid_step is None else grid_step  # the periodogram's (a peak is this far off at most)
        self._own: dict[tuple, dict[str, Any]] = {}  # own()'s fits by (period, harmonics, multiple)

    def harmonics_at(self, f: float) -> int:
        """The highest harmonic of ``f`` under the finer steps' Nyquist."""
        return max(1, min(self.cap, int(self.f_harm / f)))

    def own(self, P: float, m0: int, k: float = 1.0, refine: bool = True) -> dict[str, Any] | None:
        """The period ``P`` (s) with its own least-BIC harmonics searched from ``m0``, refined within
        a step / max(k, 1) (``refine``); None outside the range."""
        if not self.lo <= P <= self.hi:
            return None
        key = (round(P, 9), m0, round(k, 6), refine)
        if key not in self._own:
            self._own[key] = self._own_fit(P, m0, k, refine)
        return dict(self._own[key])

    def _own_fit(self, P: float, m0: int, k: float, refine: bool = True) -> dict[str, Any]:
        cv = self.cv
        m_max = min(max(1, math.ceil(k)) * self.max_harmonics, self.harmonics_at(1 / P))
        c = cv.best_near(1 / P, max(1, min(m0, m_max)), m_max)  # a fixed n_harmonics starts the peaks' search
        if not refine:
            return c
        f, r = cv.refine(1 / P, c["n_harmonics"], self.step / max(k, 1.0))
        return {**c, "period_s": 1 / f, "rss": r, "bic": cv.bic(r, c["n_harmonics"])}

    def of_peaks(self, peaks: list[float]) -> list[dict[str, Any]]:
        """Candidates of each periodogram peak ``f`` (Hz): the periods ``k/f``, ``k`` in
        :data:`PEAK_MULTIPLES` of the refined peak, each with its own harmonics, not refined
        again (``peak``: the peak's rank; :meth:`settle` refines the chosen one)."""
        cands = []
        for j, f in enumerate(peaks):
            m_top = min(self.max_harmonics, self.harmonics_at(f))
            m0 = self.m_fixed or self.cv.best_near(f, min(2, m_top), m_top)["n_harmonics"]  # a local search from 2
            f_ref, _ = self.cv.refine(f, m0, self.grid_step)  # a fringe near; the chosen one's are searched at the end
            for k in PEAK_MULTIPLES:
                c = self.own(k / f_ref, max(1, int(round(k * m0))), k, refine=False)
                if c is not None:
                    cands.append({**c, "peak": j, "k": k})
        return cands

    def settle(self, best: dict[str, Any], cands: list[dict[str, Any]]) -> dict[str, Any]:
        """The least-BIC among ``best`` and its :data:`RELATIVES` (each with its own harmonics,
        refined), repeated while a relative wins (at most three times); winners join ``cands``.
        ``best`` itself is refined first (its relatives are)."""
        best = {**best, **(self.own(best["period_s"], best["n_harmonics"], best.get("k", 1)) or {})}
        for _ in range(3):
            rel = [self.own(best["period_s"] * x, max(1, int(round(best["n_harmonics"] * x))), best.get("k", 1) * x)
                   for _, x in RELATIVES]
            rel = [{**r, "peak": best.get("peak", 0), "k": best.get("k", 1) * x} for r, (_, x) in zip(rel, RELATIVES)
                   if r is not None]
            win = min(rel, key=lambda c: c["bic"], default=None)
            if win is None or win["bic"] >= best["bic"]:
                break
            cands.append(win)
            best = win
        return best

    def fringes(self, f0: float, m: int, rss0: float) -> tuple[float, float, list[tuple[float, float]]]:
        """The least-RSS frequency (Hz) of the ``m``-harmonic series within ``f0 ± 0.5/longest``
        and its RSS (else ``(f0, rss0)``), and the fringes' ``(frequency, rss)`` minima: across
        gaps the RSS in frequency is a comb of fringes ``1/span`` apart, and the periodogram's
        peak may pick a neighbour of the best (a cycle miscounted across the gap). The comb is
        mapped by astropy's two-term Lomb–Scargle of the curve less its nuisance model on a grid
        of a tenth of a fringe (at most :data:`MAX_FRINGE_GRID` points about ``f0``), its 10 deepest minima
        refined with ``m`` harmonics; only when the track spans over 1.5 stretches."""
        from astropy.timeseries import LombScargle  # heavy: astropy, only for fringes()

        cv = self.cv
        span = float(cv.t[-1] - cv.t[0])
        if span < 1.5 * self.longest:
            return f0, rss0, []
        ms = min(m, 2)
        h = 1.0 / (10 * ms * span)  # a tenth of the second harmonic's fringe
        n = min(int(0.5 / (self.longest * h)), MAX_FRINGE_GRID // 2)  # the stretch's peak width, or the fringes nearest
        grid = f0 + h * np.arange(-n, n + 1)
        grid = grid[grid > 0]
        power = LombScargle(cv.t, cv.yp / cv.w, None if not cv.known else 1.0 / cv.w, nterms=ms).power(
            grid, method="fastchi2")
        top = np.flatnonzero(np.r_[True, power[1:] >= power[:-1]] & np.r_[power[:-1] >= power[1:], True])
        best, minima = (f0, rss0), []
        for i in top[np.argsort(power[top])[::-1]][:10]:
            f, r = cv.refine(float(grid[i]), m, h)
            if self.lo <= 1 / f <= self.hi:
                minima.append((f, r))
                if r < best[1]:
                    best = (f, r)
        return best[0], best[1], minima

    def alternatives(self, best: dict[str, Any], period: float, cands: list[dict[str, Any]], n_peaks: int,
                     scat: float | None) -> list[dict[str, Any]]:
        """The chosen period's (``best``, ``period`` s) :data:`RELATIVES` and the other peaks'
        best candidates, each with its χ² (against ``scat``, the track's scatter, when there is
        no ``sigma``), χ²/ν and ΔBIC over the chosen (> 0: worse)."""
        cv = self.cv
        m, rss = best["n_harmonics"], best["rss"]
        alts = []
        for rel, x in RELATIVES:
            a = self.own(period * x, max(1, int(round(m * x))), x)
            if a is not None:
                alts.append({"relation": rel, **a})
        for j in range(n_peaks):
            cj = [c for c in cands if c.get("peak") == j]
            if j != best.get("peak") and cj:
                alts.append({"relation": "peak", **min(cj, key=lambda c: c["bic"])})
        N = len(cv.t)
        for a in alts:
            c2 = a["rss"] if scat is None else a["rss"] / scat ** 2
            a.update(chi2=float(c2), chi2_per_sample=float(c2 / max(N - 2 * a["n_harmonics"] - cv.q, 1)),
                     delta_bic=float(a["bic"] - cv.bic(rss, m)))
            for key in ("rss", "bic", "peak", "k"):
                a.pop(key, None)
        return alts


def period_error(cv: Any, best: dict[str, Any], step: float, chi2_n: float, nu: int, weighted: bool) -> float:
    """The 1σ (s) of the chosen period from the curvature of χ² in frequency (Δχ² = 1):
    ``sigma`` scaled by √(χ²/ν) when ``weighted`` and the model misfits, else the residual's
    own scatter."""
    m = best["n_harmonics"]
    fb, rss = 1.0 / best["period_s"], best["rss"]
    h = step / (50 * max(best.get("k", 1), 1))
    curv = (cv.rss(fb + h, m) - 2 * rss + cv.rss(fb - h, m)) / h ** 2
    noise2 = max(chi2_n, 1.0) if weighted else max(rss, cv.floor) / nu  # σ² per unit of RSS
    sig_f = max(math.sqrt(2.0 * noise2 / curv) if curv > 0 else float("inf"), step * 1e-5)
    return sig_f / fb ** 2


def stretch_fit(cv: Any, f: float, m: int, step: float, detrend: int) -> tuple[float, float]:
    """The frequency (Hz) and its 1σ from the stretches alone: each contiguous stretch
    (``cv.seg``) fitted with its own phases (its own series and nuisance model), their RSS summed
    and minimised within ``f ± 3 step``, its curvature in frequency giving the 1σ (Δχ² = 1, the
    scale from the summed residual). Across gaps the cycle count is fixed only where this 1σ is
    well under a fringe (``1/span``); otherwise this, the fringes' envelope, is the estimate."""
    from scipy.optimize import minimize_scalar  # heavy: scipy.optimize, only for stretch_fit()

    parts = []
    for k in np.unique(cv.seg):
        on = cv.seg == k
        if on.sum() >= 2 * m + 2 * (detrend + 1) + 3:
            parts.append(_Curve(cv.t[on], cv.y[on], cv.w[on], np.zeros(int(on.sum()), dtype=np.int64), detrend, cv.known))
    if not parts:
        return f, float("inf")
    total = lambda x: sum(p.rss(x, m) for p in parts)  # noqa: E731
    res = minimize_scalar(total, bounds=(f - 3 * step, f + 3 * step), method="bounded", options={"xatol": step * 1e-4})
    f_inc = float(res.x) if res.fun <= total(f) else f
    h = step / 10
    rss = [total(f_inc + d) for d in (-h, 0.0, h)]
    curv = (rss[0] - 2 * rss[1] + rss[2]) / h ** 2
    nu = max(sum(p.N - 2 * m - p.q for p in parts), 1)
    noise2 = max(rss[1] / nu, 1.0) if cv.known else max(rss[1], cv.floor) / nu
    return f_inc, math.sqrt(2.0 * noise2 / curv) if curv > 0 else float("inf")
