"""Fourier-series models of light curves, for :mod:`cssat.inversion.period`: the design matrix,
the contiguous stretches (tracks, nights) of a time series, the white-noise scatter from second
differences, and :class:`_Curve` — a light curve with each stretch's offset and polynomial
trend projected out, scored by BIC, refined in frequency, tested for significance (F-test) and
repetition (even cycles against odd ones)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.observations import stretches

__all__ = ["light_curve_scatter", "stretches"]


def _vector(x: Any, field: str, *, times: bool = False, scalar_ok: bool = False) -> np.ndarray:
    """``x`` as a 1-D float64 array (a list, numpy, a torch tensor; datetime64 times as seconds
    from the first), else a FieldError naming ``field``."""
    if hasattr(x, "detach") and hasattr(x, "cpu"):  # a torch tensor
        x = x.detach().cpu().numpy()
    try:
        a = np.asarray(x)
    except Exception:  # noqa: BLE001 - ragged lists and the like
        raise FieldError(field, "expected a 1-D array of numbers") from None
    if times and np.issubdtype(a.dtype, np.datetime64):
        a = (a.astype("datetime64[us]") - a.astype("datetime64[us]").min()).astype(np.int64) / 1e6
    if a.dtype.kind not in "biuf" or a.dtype.kind == "b":
        raise FieldError(field, f"expected real numbers, got {a.dtype} (complex, text or objects)")
    if a.ndim > 1 or (a.ndim == 0 and not scalar_ok):
        raise FieldError(field, f"expected a 1-D array, got shape {a.shape}")
    return a.astype(np.float64).reshape(-1)


def _design(t: np.ndarray, f: float, m: int) -> np.ndarray:
    """``(T, 2m)``: cos 2πkft, sin 2πkft for k = 1…m."""
    W = (2 * np.pi * f) * t[:, None] * np.arange(1, m + 1)[None, :]
    return np.concatenate([np.cos(W), np.sin(W)], 1)


def _harmonics_t(t: np.ndarray, f: float, m: int, w: np.ndarray | None = None) -> np.ndarray:
    """``(2m, T)``: the transpose of :func:`_design` (times the weights ``w (T,)`` when given), by
    the recurrence ``e^{ikθ} = e^{i(k−1)θ} e^{iθ}`` (one complex exponential a sample instead of
    ``m`` sines and cosines; round-off grows as ``k ε``, 1e-14 at ``m = 50``). Rows: the samples
    of one harmonic, contiguous (the products with the nuisance basis run on long rows)."""
    n = len(t)
    Z = np.empty((m, n), dtype=np.complex128)
    Z[0] = np.exp((2j * np.pi * f) * t)
    for k in range(1, m):
        np.multiply(Z[k - 1], Z[0], out=Z[k])
    X = np.empty((2 * m, n))
    if w is None:
        X[:m], X[m:] = Z.real, Z.imag
    else:
        np.multiply(Z.real, w, out=X[:m])
        np.multiply(Z.imag, w, out=X[m:])
    return X


def light_curve_scatter(times_s: Any, values: Any) -> float:
    """The white-noise 1σ of a densely sampled light curve from its second differences:
    ``1.4826 · median|Δ²y − median Δ²y| / √6`` over triples inside one contiguous stretch
    (:func:`stretches`): blind to a signal smooth on the cadence's scale, robust to glints."""
    t = np.asarray(times_s, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    if len(t) < 5:
        return float(np.std(y))
    seg = stretches(t)
    same = (seg[2:] == seg[:-2])
    d2 = (y[2:] - 2 * y[1:-1] + y[:-2])[same]
    if d2.size < 3:
        return float(np.std(y))
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6))


def inner_steps(t: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """The positive time steps inside one contiguous stretch (``seg`` from :func:`stretches`)."""
    dt = np.diff(t)
    return dt[(np.diff(seg) == 0) & (dt > 0)]


def frame_step(t: np.ndarray, seg: np.ndarray, channels: Any = None) -> float:
    """The frame step (s): the median of :func:`inner_steps` taken within each camera channel
    (``channels (T,)`` labels, or ``None``: one), so two channels interleaved milliseconds
    apart do not fake a faster cadence and dropped frames do not fake a slower one; the
    span without any."""
    if channels is None:
        inside = inner_steps(t, seg)
    else:
        inside = np.concatenate([inner_steps(t[channels == c], seg[channels == c]) for c in np.unique(channels)])
    return float(np.median(inside)) if len(inside) else float(t[-1] - t[0])


#: the periodogram's largest grid (a few tens of MB in astropy's fast method)
MAX_FREQUENCIES = 2_000_000


def check_grid(n_freq: int, span: float, lo: float, field: str) -> None:
    """Refuse a periodogram of more than :data:`MAX_FREQUENCIES` trial frequencies before it is
    allocated (tracks days apart: no grid resolves every cycle count between them)."""
    if n_freq > MAX_FREQUENCIES:
        raise FieldError(field, f"the search needs {n_freq:.3g} trial frequencies (span {span:.6g} s, periods from "
                                f"{lo:.6g} s); the most is {MAX_FREQUENCIES:.0e}: give a narrower [min_period_s, "
                                "max_period_s], or analyse the tracks (nights) apart")


class _Curve:
    """A light curve with its nuisance model removed: each stretch's own mean and (``detrend``
    ≥ 1) slope, ... up to that polynomial order, projected out in the weighted space. ``rss(f,
    m)`` is then the residual of the Fourier series plus the nuisance model."""

    def __init__(self, t, y, w, seg, detrend: int, known_sigma: bool, zero_points: Any = None):
        self.t, self.y, self.w, self.seg, self.known = t, y, w, seg, known_sigma
        self.N = len(t)
        cols = []
        for s in np.unique(seg):
            on = seg == s
            tc = np.where(on, t - t[on].mean(), 0.0)
            scale = max(np.abs(tc).max(), 1e-300)
            for k in range(detrend + 1 if on.sum() > 2 * (detrend + 1) else 1):
                cols.append(np.where(on, (tc / scale) ** k, 0.0))
        if zero_points is not None:  # one offset per camera channel (each its own zero point)
            for z in np.unique(zero_points)[1:]:
                cols.append((zero_points == z).astype(np.float64))
        A = np.stack(cols, 1) * w[:, None]
        if zero_points is None:
            self.Q, _ = np.linalg.qr(A)
        else:  # channel offsets may repeat a stretch's: an orthonormal basis of the span, rank-revealing
            U, sv, _ = np.linalg.svd(A, full_matrices=False)
            self.Q = U[:, sv > sv[0] * 1e-10]
        self.q = self.Q.shape[1]
        self.QT = np.ascontiguousarray(self.Q.T)
        yw = y * w
        self.yp = yw - self.Q @ (self.Q.T @ yw)
        self.rss0 = float(self.yp @ self.yp)
        self.floor = self.rss0 * 1e-12 + 1e-300  # round-off ties, not random picks
        self.c = 1.0  # the overdispersion ĉ that divides a known-σ χ² in bic() (quasi-likelihood)

    def _xp(self, f: float, m: int) -> np.ndarray:
        """``(2m, T)``: the weighted harmonics at ``f`` with the nuisance model projected out."""
        X = _harmonics_t(self.t, f, m, self.w)
        X -= (X @ self.Q) @ self.QT
        return X

    def rss(self, f: float, m: int) -> float:
        """The residual sum of squares of the ``m``-harmonic series at ``f`` Hz (weighted, the
        nuisance model projected out): the normal equations solved, the residual formed
        directly (its square is second-order in the coefficients' round-off); least squares by
        SVD where they are singular."""
        Xp = self._xp(f, m)
        try:
            coef = np.linalg.solve(Xp @ Xp.T, Xp @ self.yp)
        except np.linalg.LinAlgError:
            coef, *_ = np.linalg.lstsq(Xp.T, self.yp, rcond=None)
        r = coef @ Xp - self.yp
        return float(r @ r)

    def bic(self, rss: float, m: int) -> float:
        p = 2 * m + self.q
        r = rss + self.floor
        return (r / self.c if self.known else self.N * math.log(r / self.N)) + p * math.log(self.N)

    def overdispersion(self, cands: list[dict[str, Any]]) -> None:
        """With known σ, set ``c`` (ĉ, the divisor of the χ² in :meth:`bic`) to the least χ²/ν of
        ``cands`` (dicts with ``rss``, ``n_harmonics``), at least 1, and rescore their ``bic``;
        without σ the BIC profiles the scale out already and nothing changes."""
        if not self.known:
            return
        self.c = max(1.0, min(c["rss"] / max(self.N - 2 * c["n_harmonics"] - self.q, 1) for c in cands))
        for c in cands:
            c["bic"] = self.bic(c["rss"], c["n_harmonics"])

    def score(self, f: float, m: int) -> dict[str, Any]:
        rss = self.rss(f, m)
        return {"period_s": 1.0 / f, "n_harmonics": m, "rss": rss, "bic": self.bic(rss, m)}

    def refine(self, f: float, m: int, step: float) -> tuple[float, float]:
        """The frequency minimising the RSS within ``f ± step`` (to 1e-5 of ``step``), and that
        RSS: Newton steps on three-point parabolas (the RSS is quadratic in frequency near its
        minimum: a few evaluations), projected into the window and held to 20 stencils a step, a
        concave stencil walked downhill; else — no progress in 8 steps — scipy's bounded Brent
        search."""
        from scipy.optimize import minimize_scalar  # heavy: scipy.optimize, only for refine()

        tol = step * 1e-5
        c0 = self.rss(f, m)
        x, rx, h = f, c0, 0.5 * step / max(m, 1)  # the m-th harmonic narrows the quadratic stretch m-fold
        for _ in range(8):
            a, c = self.rss(x - h, m), self.rss(x + h, m)
            den = a - 2.0 * rx + c
            if not den > 0:  # concave here: walk downhill to the lower neighbour, a wider stencil
                r_low, d_low = min((a, -h), (c, h))
                if r_low < rx and abs(x + d_low - f) <= step:
                    x, rx, h = x + d_low, r_low, 2.0 * h
                    continue
                break
            dx = 0.5 * h * (a - c) / den
            dx = max(-20.0 * h, min(20.0 * h, dx))  # a trust region: 20 stencils at most a step
            dx = min(max(x + dx, f - step), f + step) - x  # projected into the window
            if dx == 0.0:  # at the window's edge, the parabola pointing out of it: the edge is the least
                return x, rx
            rn = self.rss(x + dx, m)
            for _ in range(3):  # backtrack an overshoot (a start outside the quadratic stretch)
                if rn <= rx or abs(dx) <= 1e-3 * step:
                    break
                dx *= 0.5
                rn = self.rss(x + dx, m)
            if rn > rx:
                if abs(dx) <= 1e-3 * step:  # round-off: the minimum to this precision
                    return x, rx
                break
            x, rx = x + dx, rn
            if abs(dx) <= tol:
                return x, rx
            h = max(min(h, 4.0 * abs(dx)), 10.0 * tol)
        res = minimize_scalar(lambda z: self.rss(z, m), bounds=(f - step, f + step), method="bounded",
                              options={"xatol": tol})
        cands = [(f, c0), (x, rx), (float(res.x), float(res.fun))]
        return min(cands, key=lambda p: p[1])

    def best_m(self, f: float, m_max: int) -> int:
        """The number of harmonics (1…``m_max``) of least BIC at ``f``."""
        return int(np.argmin([self.score(f, m)["bic"] for m in range(1, m_max + 1)])) + 1

    def best_near(self, f: float, m0: int, m_max: int) -> dict[str, Any]:
        """The least-BIC model at ``f`` by a local search in the harmonics from ``m0`` (up,
        then down, each while the BIC falls; ``1…m_max``)."""
        best = self.score(f, max(1, min(m0, m_max)))
        for step in (1, -1):
            m = best["n_harmonics"] + step
            while 1 <= m <= m_max:
                c = self.score(f, m)
                if c["bic"] >= best["bic"]:
                    break
                best, m = c, m + step
        return best

    def fap(self, rss: float, m: int, n_eff: float) -> float:
        """The F-test's tail of the ``m``-harmonic model against the nuisance model alone, over
        ``n_eff`` independent trials."""
        from scipy.stats import f as fdist  # heavy: scipy.stats, only for fap()

        p, dof = 2 * m, self.N - 2 * m - self.q
        if dof <= 0:
            return 1.0
        rss = max(rss, self.floor)
        F = max((self.rss0 - rss) / p, 0.0) / (rss / dof)
        single = float(fdist.sf(F, p, dof))
        return float(-math.expm1(max(n_eff, 1.0) * math.log1p(-min(single, 1.0 - 1e-16)))) if single > 0 else 0.0

    def repeat(self, f: float, m: int) -> float:
        """Does the curve repeat? The series fitted to the even cycles (``⌊f t⌋`` even) predicts
        the odd ones and vice versa (the nuisance model refitted on each): the worse of the two
        ratios R²_pred / R²_in, ≤ 1, clipped at −1. Neighbouring cycles share their geometry,
        so a slowly changing periodic curve repeats; red noise does not. A direction whose
        training cycles do not cover the phase (< 2 cycles in all) is left out."""
        parity = np.floor(self.t * f).astype(np.int64) % 2
        X = _design(self.t, f, m) * self.w[:, None]
        out = []
        dt = inner_steps(self.t, self.seg)
        per_cycle = 1.0 / (f * float(np.median(dt))) if len(dt) else 20.0  # samples a cycle
        n_bins = int(np.clip(per_cycle / 2, 2, 20))  # half-integer periods: each parity sees every other phase
        phase_bin = np.floor((self.t * f % 1.0) * n_bins).astype(np.int64)
        covered = len(np.unique(phase_bin))
        for a in (0, 1):
            A, B = parity == a, parity != a
            if A.sum() < 2 * m + self.q + 2 or B.sum() < 2 * m + self.q + 2:
                return float("nan")
            if len(np.unique(phase_bin[A])) < 0.9 * covered:  # A does not hold a whole cycle: nothing to predict from
                continue
            QA, _ = np.linalg.qr(self.Q[A])
            QB, _ = np.linalg.qr(self.Q[B])
            proj = lambda Q, v: v - Q @ (Q.T @ v)  # noqa: E731
            coef, *_ = np.linalg.lstsq(proj(QA, X[A]), proj(QA, self.y[A] * self.w[A]), rcond=None)
            yb = proj(QB, self.y[B] * self.w[B])
            Xb = proj(QB, X[B])
            tot = float(yb @ yb)
            if not tot > 0:
                return float("nan")
            r_pred = yb - Xb @ coef
            cb, *_ = np.linalg.lstsq(Xb, yb, rcond=None)
            r_in = yb - Xb @ cb
            r2_pred, r2_in = 1 - float(r_pred @ r_pred) / tot, 1 - float(r_in @ r_in) / tot
            out.append(r2_pred / r2_in if r2_in > 0 else 0.0)
        return float(max(min(out), -1.0)) if out else float("nan")


#: the public names of the harmonic design matrix and of the prepared curve (the private names are kept for old imports)
Curve = _Curve
design = _design
__all__ += ["Curve", "design"]
