"""The rotation period of a spinning or tumbling object from its light curve (issue 24, point 4,
first part).

A Lomb–Scargle periodogram (astropy) finds the strongest frequency ``f₀``; a rotating body's
light curve usually has two maxima per turn, so both ``1/f₀`` and ``2/f₀`` are tried: each is
refined by minimising the weighted χ² of an ``n_harmonics`` Fourier series fitted at that
period, and the double period wins when its odd harmonics lower χ² by more than
``double_gain`` (a centrally symmetric Lambertian body has no odd harmonics: its period is then
ambiguous, and the single one is returned). The 1σ uncertainty is the period's Δχ² = 1 interval
when ``sigma`` is given, else the residual-scaled one.

The period found is the *synodic* one — that of the light curve. While the Sun and the observer
move around the object (a GEO satellite: once a sidereal day), it differs from the sidereal
rotation period by about ``P²/P_geometry`` (0.5 % for 437 s at GEO); the sidereal period comes
with the pole from the EGI fit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.inversion.period import estimate_period

__all__ = ["estimate_period", "estimate_tumbling_periods", "estimate_spin", "SpinSolution"]


def _design(t: np.ndarray, period: float, n: int) -> np.ndarray:
    w = 2 * np.pi * t / period
    cols = [np.ones_like(t)]
    for k in range(1, n + 1):
        cols += [np.cos(k * w), np.sin(k * w)]
    return np.stack(cols, 1)


def _wls_chi2(X: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """χ² of the weighted least-squares fit of the design ``X (T, p)`` to ``y`` (weights ``w = 1/σ``)."""
    Xw = X * w[:, None]
    coef, *_ = np.linalg.lstsq(Xw, y * w, rcond=None)
    r = Xw @ coef - y * w
    return float(r @ r)


def _chi2(t: np.ndarray, y: np.ndarray, w: np.ndarray, period: float, n: int) -> float:
    return _wls_chi2(_design(t, period, n), y, w)


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
                              samples_per_peak: int = 10) -> dict[str, Any]:
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
    ``single_period_s``, ``delta_bic`` (the single-period BIC less the two-period one: > 10 is
    strong evidence of tumbling), ``tumbling`` (``delta_bic > 10``) and ``why``. A curve without
    two independent frequencies (one period, or none) is an answer, ``tumbling: False``, not an
    error. ``min_period_s``/``max_period_s`` default to the data's: twice the cadence, half the
    span.

    Assumptions: torque-free motion, whose attitude relative to the fixed angular momentum is
    periodic up to a uniform precession, so the light curve is quasi-periodic in two frequencies;
    the samples span many cycles of both. Each contiguous stretch's offset and slope are fitted
    first (a drift is not a second period)."""
    from astropy.timeseries import LombScargle
    from scipy.optimize import minimize

    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    y = np.asarray(flux, dtype=np.float64).reshape(-1)
    if t.shape != y.shape or not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise FieldError("flux", "expected finite times and values of one length")
    order = int_param(order, "order", 1, 10)
    jk = _lattice(order)
    n_par = 2 * len(jk) + 1
    if len(t) < 2 * n_par:
        raise FieldError("flux", f"a 2-D Fourier series of order {order} needs at least {2 * n_par} samples, got {len(t)}")
    order_ = np.argsort(t, kind="stable")
    t, y = t[order_], y[order_]
    dy = None if sigma is None else np.broadcast_to(np.asarray(sigma, dtype=np.float64), order_.shape)[order_]
    w = np.ones_like(y) if dy is None else 1.0 / dy
    t = t - t[0]
    span = float(t[-1])
    if not span > 0 or np.ptp(y) == 0:
        return _not_tumbling("the curve does not vary" if span > 0 else "the samples span no time")
    from cssat.inversion.fourier import _Curve, stretches

    seg = stretches(t)
    nuisance = _Curve(t, y, w, seg, 1, dy is not None)  # each stretch's offset and slope: a drift is not a period
    y = nuisance.yp / w
    steps = np.diff(t)[(np.diff(seg) == 0) & (np.diff(t) > 0)]
    frame = float(np.percentile(steps, 75)) if len(steps) else span
    lo = 4 * frame if min_period_s is None else float_param(min_period_s, "min_period_s", 0.0, open_lo=True)  # 2/lo: Nyquist
    hi = span / 2 if max_period_s is None else float_param(max_period_s, "max_period_s", lo, open_lo=True)
    if not hi > lo:
        raise FieldError("max_period_s", f"must exceed min_period_s ({lo:.6g} s), got {hi:.6g} s")
    spp = int_param(samples_per_peak, "samples_per_peak", 1)
    from cssat.inversion.period import MAX_FREQUENCIES

    n_freq = int((2 / lo - 1 / hi) * spp * span) + 1
    if n_freq > MAX_FREQUENCIES:
        raise FieldError("max_period_s" if min_period_s is None else "min_period_s",
                         f"the search needs {n_freq:.3g} trial frequencies (span {span:.6g} s); the most is "
                         f"{MAX_FREQUENCIES:.0e}: give a narrower [min_period_s, max_period_s], or analyse the tracks apart")
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
                             segments=seg)
    T = len(t)
    bic = lambda c, k: (c if dy is not None else T * np.log(max(c, 1e-300) / T)) + k * np.log(T)  # noqa: E731
    delta = float(bic(single["rss"], 2 * single["n_harmonics"] + single["n_nuisance"] + 1) - bic(chi2, n_par + 1 + nuisance.q))
    fs = np.array(sorted((abs(f1), abs(f2)), reverse=True))
    return {"frequencies_hz": fs, "periods_s": 1.0 / fs, "chi2": chi2, "chi2_single": float(single["rss"]),
            "single_period_s": float(single["best_period_s"]), "delta_bic": delta, "tumbling": bool(delta > 10.0),
            "why": (f"two periods fit better than one by ΔBIC {delta:.3g} (> 10)" if delta > 10.0
                    else f"one period fits as well (ΔBIC {delta:.3g} ≤ 10): not tumbling")}


def _not_tumbling(why: str) -> dict[str, Any]:
    nan = float("nan")
    return {"frequencies_hz": np.full(2, nan), "periods_s": np.full(2, nan), "chi2": nan, "chi2_single": nan,
            "single_period_s": nan, "delta_bic": 0.0, "tumbling": False, "why": why}


# --- the pole and the sidereal period (issue 24, point 4, second part) ---------------------------

class SpinSolution:
    """What :func:`estimate_spin` returns. The spin of :func:`cssat.scene.attitude.spin_frame`
    (body +z along the pole, phase 0 at ``times_s = 0``): ``pole_lon_deg``, ``pole_lat_deg``
    (ecliptic λ, β or equatorial α, δ — ``frame``), the sidereal ``period_s`` (> 0: the pole is
    the one the body turns counter-clockwise about), their 1σ (``lon_err_deg``, ``lat_err_deg``,
    ``pole_err_deg`` — the pole's angular 1σ —, ``period_err_s``), the EGI in that body frame
    (``normals (K, 3)``, ``areas (K,)``, only those with area), ``chi2`` (weighted; unweighted
    without ``sigma``), ``residual (T,)`` (flux − fit), the light curve's synodic period
    (``synodic``, :func:`estimate_period`'s output) and ``alternatives``: the other local minima
    refined at full resolution (``pole_lon_deg``, ``pole_lat_deg``, ``period_s``, ``chi2``,
    ``delta_chi2`` over the best in units of the reduced χ², ``separation_deg`` from the best
    pole); ``ambiguous`` is true when one of them, more than 10° away, is within Δχ² < 9 (3σ)."""

    def __init__(self, **kw: Any):
        self.__dict__.update(kw)

    def frames(self, times_s: Any) -> np.ndarray:
        """The body frames ``(T, 3, 3)`` of this spin at ``times_s`` (same origin as the fit's)."""
        from cssat.scene.attitude import spin_frame

        return spin_frame(np.asarray(times_s, dtype=np.float64), self.pole_lon_deg, self.pole_lat_deg, self.period_s,
                          0.0, self.frame)

    def predict(self, times_s: Any, sun: Any, obs: Any) -> np.ndarray:
        """The fitted model's light curve ``(T,)`` (flux units of the fit) at ``times_s`` for
        inertial ``sun``/``obs (T, 3)`` directions: e.g. a night held out of the fit."""
        from cssat.inversion.egi import egi_operator
        from cssat.scene.attitude import to_body

        R = self.frames(times_s)
        G = egi_operator(to_body(R, np.asarray(sun, dtype=np.float64)), to_body(R, np.asarray(obs, dtype=np.float64)),
                         self.normals, self.brdf).matrix().numpy()
        return G @ self.areas

    def describe(self) -> dict[str, Any]:
        keys = ("pole_lon_deg", "pole_lat_deg", "period_s", "lon_err_deg", "lat_err_deg", "pole_err_deg", "period_err_s",
                "formal_pole_err_deg", "grid_pole_shift_deg", "chi2", "reduced_chi2", "ambiguous", "frame")
        return {f"spin_{k}": getattr(self, k) for k in keys}

    def __repr__(self) -> str:
        return (f"SpinSolution(pole ({self.pole_lon_deg:.2f}°, {self.pole_lat_deg:.2f}°) ± {self.pole_err_deg:.2g}°, "
                f"period {self.period_s:.6f} ± {self.period_err_s:.2g} s, reduced χ² {self.reduced_chi2:.3g}"
                f"{', ambiguous' if self.ambiguous else ''})")


def _pole_vector(lon_deg: float, lat_deg: float) -> np.ndarray:
    lo, la = np.radians(lon_deg), np.radians(lat_deg)
    return np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])


def _separation_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    return float(np.degrees(np.arccos(np.clip(_pole_vector(*a) @ _pole_vector(*b), -1.0, 1.0))))


def _pole_rotation(lon: float, lat: float, frame: str) -> np.ndarray:
    """``(3, 3)``: inertial → the frame whose z is the pole (spin_frame at zero phase)."""
    from cssat.scene.attitude import spin_frame

    return spin_frame(np.zeros(1), lon, lat, 1.0, 0.0, frame)[0]


def _check_light_curve(times_s, flux, sun, obs, sigma):
    """``t (T,), y (T,), S, O (T, 3), w = 1/σ (T,), σ (T,) or None`` as float64, checked."""
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    y = np.asarray(flux, dtype=np.float64).reshape(-1)
    S, O = (np.asarray(v, dtype=np.float64) for v in (sun, obs))
    T = len(t)
    if y.shape != t.shape or S.shape != (T, 3) or O.shape != (T, 3):
        raise FieldError("flux", f"expected times (T,), flux (T,) and sun/obs (T, 3), got {t.shape}, {y.shape}, {S.shape}, {O.shape}")
    if not (np.isfinite(t).all() and np.isfinite(y).all() and np.isfinite(S).all() and np.isfinite(O).all()):
        raise FieldError("flux", "the times, fluxes and directions must be finite")
    if np.any(np.diff(t) <= 0):
        raise FieldError("times_s", "the times must increase")
    sig = None if sigma is None else np.broadcast_to(np.asarray(sigma, dtype=np.float64), (T,))
    if sig is not None and not (np.isfinite(sig).all() and (sig > 0).all()):
        raise FieldError("sigma", "the uncertainties must be finite and > 0")
    return t, y, S, O, (np.ones(T) if sig is None else 1.0 / sig), sig


def _weighted_nnls(G: np.ndarray, w: np.ndarray, yw: np.ndarray) -> tuple[np.ndarray, float]:
    """The search loops' EGI: NNLS of ``diag(w) G a ≈ yw``, and its χ²."""
    from scipy.optimize import nnls

    A = G * w[:, None]
    a, rnorm = nnls(A, yw, maxiter=max(30 * A.shape[1], 1000))
    return a, float(rnorm) ** 2


class _Fit:
    """The EGI fit's χ² as a function of the spin ``(λ, β, f)`` on a subset of samples and a
    grid of normals: NNLS in the EGI for each spin. The pole's fixed rotation is cached, so a
    scan of frequencies at one pole only turns the vectors about the pole."""

    def __init__(self, t, y, w, S, O, normals, brdf, frame):
        self.t, self.y, self.w, self.S, self.O, self.N, self.brdf, self.frame = t, y, w, S, O, normals, brdf, frame
        self.yw = y * w
        self._pole: tuple | None = None

    def _at_pole(self, lon, lat):
        if self._pole != (lon, lat):
            M = _pole_rotation(lon, lat, self.frame)
            self._sp, self._op, self._pole = self.S @ M.T, self.O @ M.T, (lon, lat)
        return self._sp, self._op

    def matrix(self, lon, lat, f):
        sp, op = self._at_pole(lon, lat)
        ph = 2 * np.pi * f * self.t
        c, s_ = np.cos(ph), np.sin(ph)

        def turn(v):  # R_z(φ) v, spin_frame's passive rotation
            return np.stack([c * v[:, 0] + s_ * v[:, 1], c * v[:, 1] - s_ * v[:, 0], v[:, 2]], 1)

        from cssat.inversion.egi import geometry_matrix

        return geometry_matrix(turn(sp), turn(op), self.N, self.brdf)

    def solve(self, lon, lat, f):
        return _weighted_nnls(self.matrix(lon, lat, f), self.w, self.yw)

    def chi2(self, lon, lat, f):
        if not -90.0 <= lat <= 90.0 or not f > 0:
            return np.inf
        return self.solve(lon, lat, f)[1]


def estimate_spin(times_s: Any, flux: Any, sun: Any, obs: Any, *, sigma: Any = None, brdf: Any = None,
                  frame: str = "ecliptic", period_s: float | None = None, min_period_s: float = 60.0,
                  max_period_s: float = 86400.0, n_poles: int = 60, n_starts: int = 6, n_refine: int = 2,
                  coarse_normals: int = 200, coarse_samples: int = 400, n_normals: int = 1000,
                  max_samples: int = 2000) -> SpinSolution:
    """The spin state of an object rotating about a fixed axis — its pole and sidereal period —
    and its EGI, from its light curve ``flux (T,)`` at ``times_s (T,)`` with the Sun and
    observer directions ``sun``, ``obs (T, 3)`` from the object in the inertial frame (GCRS
    unit vectors), ``sigma`` the flux's 1σ (scalar or ``(T,)``), ``brdf`` the surface's BRDF
    (default Lambert): the convex-inversion search of Kaasalainen, Torppa & Muinonen (2001)
    with the EGI model of :func:`~cssat.inversion.egi_operator` (no shadowing).

    1. The synodic period ``P₀`` (``period_s``, or :func:`estimate_period` between
       ``min_period_s`` and ``max_period_s``); both ``P₀`` and ``2 P₀`` are candidates.
    2. Coarse search: for each of ``n_poles`` poles on a Fibonacci grid of the whole sphere
       (the sense of rotation is the pole's: the period stays positive), a scan of the sidereal
       frequency ``f = 1/P + δ`` in steps of ``1/(20 span)``, each spin scored by the NNLS EGI
       fit's χ² on ``coarse_samples`` samples and ``coarse_normals`` normals. A facet's
       brightness is a product of two cosines, one turning with the Sun's longitude about the
       pole and one with the observer's, so the light curve's frequency is the sidereal one less
       a weighted mean of the two longitude rates ``λ̇☉``, ``λ̇ₒ``: ``δ`` spans
       ``[min(0, λ̇☉, λ̇ₒ), max(0, λ̇☉, λ̇ₒ)]/2π`` widened by ``0.5/span + 10 %`` (for a GEO
       object the observer turns with the Earth, so ``δ`` reaches a cycle per sidereal day).
    3. The ``n_starts`` best distinct poles refined by Nelder–Mead in ``(λ, β, f)`` at that
       resolution; the ``n_refine`` best refined again on up to ``max_samples`` samples and
       ``n_normals`` normals. The best is the solution, the others its ``alternatives``.
    4. 1σ: the formal Gauss–Newton covariance of ``(λ, β, f)`` and the support's areas, scaled
       by the reduced χ² when it exceeds 1 (the model's misfit counts as noise), added in
       quadrature to the shift of the solution when the search is refined again on a grid of
       normals turned at random (the EGI grid's bias, which dominates at high SNR):
       ``formal_pole_err_deg``, ``grid_pole_shift_deg`` and their sum ``pole_err_deg``; the
       same for the period.

    Assumptions: a principal-axis rotation (no tumbling: :func:`~cssat.scene.attitude.torque_free`
    motion has two periods), a convex body (or negligible self-shadowing), one BRDF shape.
    """
    from scipy.optimize import minimize

    from cssat._checks import choice_param
    from cssat.inversion.egi import fibonacci_sphere

    frame = choice_param(frame, "frame", ("ecliptic", "equatorial"))
    t, y, S, O, w, sig = _check_light_curve(times_s, flux, sun, obs, sigma)
    T = len(t)
    n_poles, n_starts, n_refine = (int_param(v, k, 1) for v, k in ((n_poles, "n_poles"), (n_starts, "n_starts"), (n_refine, "n_refine")))
    n_refine = min(n_refine, n_starts)
    span = float(t[-1] - t[0])
    if period_s is None:
        synodic = estimate_period(t, y, sigma=None if sigma is None else 1.0 / w, min_period_s=min_period_s,
                                  max_period_s=max_period_s)
        P0 = synodic["best_period_s"]  # the search wants the best candidate, whatever the verdict
    else:
        P0 = float_param(period_s, "period_s", 0.0, open_lo=True)
        synodic = {"period_s": P0, "given": True}
    # The light curve's apparent (synodic) frequency is the sidereal one less a weighted rate of
    # the longitudes of the Sun and the observer about the pole (each cosine factor of a facet's
    # brightness turns with its own direction): for each pole the scan covers the sidereal
    # frequencies between those two rates, plus a margin of half a cycle over the span
    dt = np.diff(t)
    close = dt < 10 * np.median(dt)
    step = 1.0 / (20 * span)

    def shifts(lon, lat):
        """The Sun's and the observer's median longitude rates about the pole, in Hz, at most
        3× their angular rates (a direction near the pole turns fast in longitude but hardly
        modulates the light curve)."""
        M = _pole_rotation(lon, lat, frame)
        out = []
        for v in (S @ M.T, O @ M.T):
            dl = (np.diff(np.arctan2(v[:, 1], v[:, 0])) + np.pi) % (2 * np.pi) - np.pi
            out.append(float(np.clip(np.median(dl[close] / dt[close]), -cap, cap)) / (2 * np.pi) if close.any() else 0.0)
        return out

    cap = 3.0 * max((float(np.median(np.arccos(np.clip(np.einsum("ij,ij->i", v[1:], v[:-1]), -1, 1))[close] / dt[close]))
                     if close.any() else 0.0) for v in (S, O))

    def subset(n):
        idx = np.unique(np.linspace(0, T - 1, min(n, T)).round().astype(int))
        return t[idx], y[idx], w[idx], S[idx], O[idx]

    coarse = _Fit(*subset(int_param(coarse_samples, "coarse_samples", 16)),
                  fibonacci_sphere(int_param(coarse_normals, "coarse_normals", 16)).numpy(), brdf, frame)
    fine = _Fit(*subset(int_param(max_samples, "max_samples", 16)), fibonacci_sphere(int_param(n_normals, "n_normals", 16)).numpy(),
                brdf, frame)
    grid = fibonacci_sphere(n_poles).numpy()
    lons, lats = np.degrees(np.arctan2(grid[:, 1], grid[:, 0])), np.degrees(np.arcsin(np.clip(grid[:, 2], -1, 1)))
    cands = [1.0 / P0] + ([0.5 / P0] if 2 * P0 <= max_period_s or period_s is not None else [])
    table = []  # (chi2, lon, lat, f)
    for lo, la in zip(lons, lats):
        best = (np.inf, lo, la, cands[0])
        r = shifts(lo, la)
        margin = 0.5 / span + 0.1 * max(abs(r[0]), abs(r[1]))
        offsets = np.arange(min(0.0, *r) - margin, max(0.0, *r) + margin + step / 2, step)
        for fc in cands:
            for f in fc + offsets:
                if f > 0:
                    c = coarse.chi2(lo, la, f)
                    if c < best[0]:
                        best = (c, lo, la, f)
        table.append(best)
    # the coarse grid's bias is as large as the χ² differences between poles: each pole's best
    # spin is scored again on the fine grid of normals before the starts are chosen
    medium = _Fit(coarse.t, coarse.y, coarse.w, coarse.S, coarse.O, fine.N, brdf, frame)
    table = sorted(((medium.chi2(*r[1:]), *r[1:]) for r in table), key=lambda r: r[0])
    spacing = np.degrees(np.sqrt(4 * np.pi / n_poles))
    starts: list[tuple] = []
    for r in table:
        if all(_separation_deg((r[1], r[2]), (s[1], s[2])) > 1.5 * spacing for s in starts):
            starts.append(r)
        if len(starts) == n_starts:
            break

    def refine(fit, x0, dpole, dphase):
        scale = np.array([1.0, 1.0, 1.0 / (360.0 * span)])  # the frequency in degrees of phase over the span
        fun = lambda z: fit.chi2(*(np.asarray(x0) + z * scale))  # noqa: E731
        simplex = np.array([[0, 0, 0], [dpole, 0, 0], [0, dpole, 0], [0, 0, dphase]], dtype=np.float64)
        res = minimize(fun, np.zeros(3), method="Nelder-Mead",
                       options={"initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-9 * max(fun(np.zeros(3)), 1e-300),
                                "maxfev": 400})
        x = np.asarray(x0) + res.x * scale
        return (float(res.fun), *x)

    refined = sorted((refine(coarse, s[1:], spacing / 3, 90.0) for s in starts), key=lambda r: r[0])
    distinct: list[tuple] = []  # starts that converged to one minimum are refined once
    for r in refined:
        if all(_separation_deg((r[1], r[2]), (d[1], d[2])) > 10.0 or abs(r[3] - d[3]) * span > 0.5 for d in distinct):
            distinct.append(r)
    finals = sorted((refine(fine, r[1:], 2.0, 20.0) for r in distinct[:n_refine]), key=lambda r: r[0])
    chi2, lon, lat, f = finals[0]
    lon = float((lon + 180.0) % 360.0 - 180.0)
    # the EGI grid's bias: the same refinement on a grid of normals turned at random
    from scipy.spatial.transform import Rotation

    turned = _Fit(fine.t, fine.y, fine.w, fine.S, fine.O, fine.N @ Rotation.random(random_state=0).as_matrix().T, brdf, frame)
    _, lon_g, lat_g, f_g = refine(turned, (lon, lat, f), 1.0, 5.0)
    grid_pole = _separation_deg((lon, lat), (lon_g, lat_g))
    grid_period = abs(1 / f_g - 1 / f)
    # the EGI at the solution and its 1σ (Gauss–Newton on the spin and the support's areas)
    a, _ = fine.solve(lon, lat, f)
    A = fine.matrix(lon, lat, f) * fine.w[:, None]
    sup = a > 1e-9 * max(float(a.max()), 1e-300)
    h = np.array([1e-3, 1e-3, 1e-3 / (360.0 * span)])
    cols = []
    for i in range(3):
        x_hi, x_lo = np.array([lon, lat, f]), np.array([lon, lat, f])
        x_hi[i] += h[i]
        x_lo[i] -= h[i]
        x_hi[1], x_lo[1] = min(x_hi[1], 90.0), max(x_lo[1], -90.0)
        cols.append((fine.matrix(*x_hi) - fine.matrix(*x_lo)) @ a * fine.w / (x_hi[i] - x_lo[i]))
    J = np.column_stack(cols + [A[:, sup]])
    dof = max(len(fine.t) - J.shape[1], 1)
    red = chi2 / dof
    scale2 = max(red, 1.0) if sigma is not None else red
    try:
        cov = np.linalg.pinv(J.T @ J)[:3, :3] * scale2
        err = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:  # pragma: no cover - pinv converges on finite input
        err = np.full(3, np.inf)
    formal_pole = float(np.hypot(err[1], np.cos(np.radians(lat)) * err[0]))
    pole_err = float(np.hypot(formal_pole, grid_pole))
    period_err = float(np.hypot(err[2] / f ** 2, grid_period))
    alts = []
    for c2, lo2, la2, f2 in finals[1:]:
        lo2 = float((lo2 + 180.0) % 360.0 - 180.0)
        alts.append({"pole_lon_deg": lo2, "pole_lat_deg": float(la2), "period_s": float(1 / f2), "chi2": float(c2),
                     "delta_chi2": float((c2 - chi2) / scale2), "separation_deg": _separation_deg((lon, lat), (lo2, la2))})
    ambiguous = any(al["delta_chi2"] < 9.0 and al["separation_deg"] > 10.0 for al in alts)
    # the residual on every sample (not only the fit's subset)
    full = _Fit(t, y, w, S, O, fine.N, brdf, frame)
    resid = y - full.matrix(lon, lat, f) @ a
    return SpinSolution(pole_lon_deg=lon, pole_lat_deg=float(lat), period_s=float(1 / f), lon_err_deg=float(err[0]),
                        lat_err_deg=float(err[1]), pole_err_deg=pole_err, period_err_s=period_err,
                        formal_pole_err_deg=formal_pole, formal_period_err_s=float(err[2] / f ** 2), grid_pole_shift_deg=grid_pole,
                        grid_period_shift_s=float(grid_period),
                        chi2=float(chi2), reduced_chi2=float(red), normals=fine.N[sup], areas=a[sup], residual=resid,
                        synodic=synodic, alternatives=alts, ambiguous=bool(ambiguous), frame=frame, brdf=brdf,
                        coarse=[{"chi2": float(r[0]), "pole_lon_deg": float(r[1]), "pole_lat_deg": float(r[2]),
                                 "period_s": float(1 / r[3])} for r in table])
