"""The spin state of a principal-axis rotator from its light curve: the pole
and the sidereal period by the convex-inversion search over the EGI (:func:`estimate_spin`), its
solution (:class:`~cssat.inversion.results.SpinSolution`: a read-only mapping of its keys with
attributes). The light curve's own (synodic) period and its verdict are
:mod:`cssat.inversion.period`'s; a tumbler's two frequencies are
:mod:`cssat.inversion.frequencies`' (both re-exported here).

The period of the light curve is the *synodic* one. While the Sun and the observer move around
the object (a GEO satellite: once a sidereal day), it differs from the sidereal rotation period
by about ``P²/P_geometry`` (0.5 % for 437 s at GEO); the sidereal period comes with the pole
from the EGI fit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.inversion.egi import fibonacci_sphere, geometry_matrix, split_lobes
from cssat.inversion.frequencies import estimate_tumbling_periods
from cssat.inversion.period import estimate_period
from cssat.inversion.period_verdict import MODEL_FITS_CHI2
from cssat.inversion.results import SpinSolution
from cssat.inversion.spin_errors import (_night_split, _refined, _separation_deg, _spin_errors, _turned, alternatives, ambiguity,
                                         rivals)
from cssat.inversion.spin_search import (_bootstrap_spin, _coarse_scan, _distinct_poles, _local_multistart, _pole_rotation,
                                         _refine_spin)

__all__ = ["estimate_period", "estimate_tumbling_periods", "estimate_spin", "SpinSolution", "MODEL_FITS_CHI2"]


def _as_floats(v: Any, field: str) -> np.ndarray:
    """``v`` as a float64 array; a :class:`FieldError` naming ``field`` where it is not numbers."""
    try:
        return np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise FieldError(field, f"expected numbers, got {type(v).__name__} {str(v)[:60]!r}") from err


def _check_light_curve(times_s, flux, sun, obs, sigma, brdf=None, fitted=True):
    """``t (T,), y (T,), S, O (T, 3), w = 1/σ (T,), σ (T,) or None`` as float64, checked — where
    ``fitted`` (not held-out samples) at least 4 samples and some light: a curve with no sample
    above 0 has nothing to invert; ``brdf`` None or a model with ``evaluate`` (:mod:`cssat.optics`'
    BRDFs)."""
    if brdf is not None and not callable(getattr(brdf, "evaluate", None)):
        raise FieldError("brdf", f"expected None (Lambert) or a BRDF model such as cssat.optics.brdf.Lambert(0.5), "
                                 f"got {brdf!r}")
    t = _as_floats(times_s, "times_s").reshape(-1)
    y = _as_floats(flux, "flux").reshape(-1)
    S, O = _as_floats(sun, "sun"), _as_floats(obs, "obs")
    T = len(t)
    if y.shape != t.shape or S.shape != (T, 3) or O.shape != (T, 3):
        raise FieldError("flux", f"expected times (T,), flux (T,) and sun/obs (T, 3), got {t.shape}, {y.shape}, {S.shape}, "
                                 f"{O.shape}")
    if fitted and T < 4:
        raise FieldError("flux", f"expected at least 4 samples, got {T}")
    for name, arr in (("times_s", t), ("flux", y), ("sun", S), ("obs", O)):
        if not np.isfinite(arr).all():
            raise FieldError(name, f"must be finite: {int((~np.isfinite(arr)).sum())} NaN or infinite values")
    if np.any(np.diff(t) <= 0):
        raise FieldError("times_s", "the times must increase")
    if fitted and not (y > 0).any():
        raise FieldError("flux", "no sample is above 0: a light curve without light has no shape or spin to find")
    sig = None if sigma is None else np.broadcast_to(_as_floats(sigma, "sigma"), (T,))
    if sig is not None and not (np.isfinite(sig).all() and (sig > 0).all()):
        raise FieldError("sigma", "the uncertainties must be finite and > 0")
    return t, y, S, O, (np.ones(T) if sig is None else 1.0 / sig), sig


def _weighted_nnls(G: np.ndarray, w: np.ndarray, yw: np.ndarray) -> tuple[np.ndarray, float]:
    """The search loops' EGI: NNLS of ``diag(w) G a ≈ yw``, and its χ²."""
    from scipy.optimize import nnls  # heavy: scipy.optimize, only for _weighted_nnls()

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
                  max_samples: int = 2000, split_nights: bool = False, heldout: Any = None, interval: str = "profile",
                  profile_grids: int = 1, error_grids: int = 1, bootstrap: int = 0, local_starts: int = 0) -> SpinSolution:
    """The spin state of an object rotating about a fixed axis — its pole and sidereal period —
    and its EGI, from its light curve ``flux (T,)`` at ``times_s (T,)`` with the Sun and
    observer directions ``sun``, ``obs (T, 3)`` from the object in the inertial frame (GCRS
    unit vectors), ``sigma`` the flux's 1σ (scalar or ``(T,)``), ``brdf`` the surface's BRDF
    (default Lambert; a :class:`~cssat.inversion.egi.Lobes`: an EGI per scattering lobe, for
    glinting, mixed materials): the convex-inversion search of Kaasalainen, Torppa & Muinonen (2001)
    with the EGI model of :func:`~cssat.inversion.egi_operator` (no shadowing).

    1. The synodic period ``P₀`` (``period_s``, or :func:`estimate_period` between
       ``min_period_s`` and ``max_period_s``); both ``P₀`` and ``2 P₀`` are candidates, and
       ``P₀/2``, ``P₀/4`` when ``P₀`` is a multiple of the periodogram's peak (down to the peak's
       period): over nights of drifting geometry a multiple can fit a high-SNR curve's drift better
       than its true period, and the spin model, which follows the geometry, decides.
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
       ``local_starts = K > 0`` (default 0): the solution refined again from ``K`` poles 2° and
       4° from it (:func:`~cssat.inversion.spin_search._local_multistart`), the lowest kept — the
       NNLS-profiled χ² has minima a few degrees apart where one refinement stops in the nearest;
       step 8's refits do the same. ``K`` more refinements (``K`` more a bootstrap replicate).
    4. 1σ: the formal Gauss–Newton covariance of ``(λ, β, f)`` and the support's areas, scaled
       by the reduced χ² when it exceeds 1 (the model's misfit counts as noise), added in
       quadrature to the shift of the solution when it is refined again on a grid of normals
       turned at random (the EGI grid's bias, which dominates at high SNR; the shift also
       carries part of the noise's valley and of nearby minima, which the formal 1σ and the
       profile miss) — the root mean square of the shifts over ``error_grids`` grids (seeds 0,
       1, …; one shift is a single draw, often far below its spread): ``formal_pole_err_deg``,
       ``grid_pole_shift_deg`` and their sum ``pole_err_deg``; the same for the period. With
       step 8's bootstrap, which measures the noise, the grid is the fine one refined instead
       (joined with its turned copy: an EGI on the grid itself moves only by the noise the extra
       normals fit). Each grid costs one Nelder–Mead refinement.

    5. ``split_nights`` (a diagnostic, not a 1σ): the search again on each contiguous stretch
       alone (a night, or its part between gaps of over 30 min) from the same synodic period and
       settings (``local_starts`` included):
       ``split_poles`` and the standard error of their mean, ``σ² = Σᵢ θᵢ²/(g(g−1))`` (``θᵢ``
       the angle of the ``i``-th pole from their mean direction; the same for the period) as
       ``split_pole_err_deg``, ``split_period_err_s``. Measured, it is no calibrated 1σ either way:
       a box-wing with real materials (pole 84° off) gives 17°, three of four stretches 6.6–12.5°
       from the truth; the same run in class (pole 0.32° off) gives 18°, a short stretch alone not
       pinning the pole. Costs ``g`` more searches (``g ≥ 2``; none with one).

    6. The verdict (``verdict``, ``verdict_why``): ``heldout = (times_s, flux, sun, obs, sigma)``,
       data not fitted (e.g. a night held out; same time origin and units), is predicted by the
       solution and its χ² compared with what a right model reaches at the stated noise — the
       held-out noise plus the fitted parameters' prediction error, a generalised χ²
       (:func:`~cssat.inversion.spin_errors.heldout_threshold`) — at its ``1 − 10⁻³`` quantile:
       above it ``"unreliable"`` (the model does not describe the object: the pole can be wrong
       by more than any 1σ), else ``"reliable"``. Without ``heldout`` the fitted samples' χ²
       against the ``χ²_{n−p}`` quantile (a test a flexible model passes by overfitting: said so
       in ``verdict_why``); without ``sigma`` ``"unreliable"`` (nothing to test against). When
       unreliable every 1σ (``pole_err_deg``, ``lon_err_deg``, ``lat_err_deg``,
       ``formal_pole_err_deg``, ``period_err_s``, ``formal_period_err_s`` and step 4's grid
       terms) is NaN: no 1σ is reported on a model that does not fit — its period may be an
       alias of the cadence or a wrong pole's, with a curvature 1σ of 1e-4 s (the synodic
       period's own, calibrated 1σ is in ``synodic``: :func:`~cssat.inversion.estimate_period`). A fit
       that passes is still called unreliable when it is ``ambiguous``: another refined minimum
       more than 10° away within Δχ² < 9 (the data do not decide between the poles).
       ``heldout_chi2``, ``heldout_n``, ``heldout_threshold`` (χ², not per sample).
    7. ``interval="profile"`` (the default; ``"laplace"``: step 4's 1σ alone), when reliable:
       the pole's profile-likelihood region — the χ² minimised over the period (bounded
       Brent) and the EGI's areas (NNLS) at poles along 8 bearings, out to where ``Δχ²`` over the
       reduced χ² (where above 1) reaches 1, 2.30 and 6.18 (the 68.27 % and 95.45 % regions of
       the pole's two numbers; :func:`~cssat.inversion.spin_errors.pole_profile_interval`). The
       profile has a kink at the minimum (the NNLS active set) that a Laplace approximation
       misreads; a Δχ² region does not. ``pole_interval`` holds the radii; its radial 1σ
       (``pole_interval["pole_err_deg"]``) is never smaller than the 68 % and 95 % regions imply
       (a shallow valley widens it; ``quadratic_pole_err_deg``: the Δχ² = 1 value). The region
       is the noise's on this grid of normals; ``pole_err_deg`` is that 1σ added in quadrature
       to step 4's grid term ``grid_pole_shift_deg`` (the grid's bias moves the minimum by about a
       region's radius: BENCHMARKS.md "Coverage of the pole and L"). ``profile_grids > 1``:
       the objective the mean χ² over that many grids of normals turned at random (the fine one first), which smooths the grid's bias;
       the pole and period reported are then that objective's minimum. About 100–200 χ²
       evaluations.
    8. ``bootstrap = B > 0`` (default 0: off), when reliable: the noise's part of ``pole_err_deg``
       and ``period_err_s`` by a warm-started parametric bootstrap, not the profile's (or
       Gauss–Newton's) — ``B`` light curves drawn from the fitted model at the stated noise (×
       the reduced χ² where above 1; a fixed seed), each refined from the solution on the fine
       fit, the RMS of their shifts (``bootstrap_pole_err_deg``, ``bootstrap_period_err_s``) ⊕
       step 4's grid term (refined when the bootstrap runs; an unreliable spin reports no 1σ and
       runs no bootstrap). The profile's 1σ misses the valley the
       NNLS support opens (in class it holds 50 / 77 % in its 68 / 95 % circles: BENCHMARKS.md).
       ``bootstrap_lr_factor``: the replicates' mean profile Δχ² at the pole they were drawn from,
       over 2 (1 where Wilks' χ²₂ holds; above 1 step 7's region is too small by its square
       root). ``B`` more refinements and profiles over the period.

    Assumptions: a principal-axis rotation (no tumbling: :func:`~cssat.scene.attitude.torque_free`
    motion has two periods), a convex body (or negligible self-shadowing), one BRDF shape.
    """
    frame = choice_param(frame, "frame", ("ecliptic", "equatorial"))
    t, y, S, O, w, sig = _check_light_curve(times_s, flux, sun, obs, sigma, brdf)
    if heldout is not None:  # checked before any work (step 6 reads it)
        _check_heldout(heldout)
    interval = choice_param(interval, "interval", ("profile", "laplace"))
    profile_grids = int_param(profile_grids, "profile_grids", 1, 64)
    error_grids = int_param(error_grids, "error_grids", 1, 64)
    bootstrap = int_param(bootstrap, "bootstrap", 0, 1000)
    local_starts = int_param(local_starts, "local_starts", 0, 8)
    T = len(t)
    n_poles, n_starts, n_refine = (int_param(v, k, 1) for v, k in ((n_poles, "n_poles"), (n_starts, "n_starts"),
                                                                   (n_refine, "n_refine")))
    n_refine = min(n_refine, n_starts)
    span = float(t[-1] - t[0])
    P0, synodic = _synodic_period(t, y, w, sigma, period_s, min_period_s, max_period_s)

    def subset(n):
        idx = np.unique(np.linspace(0, T - 1, min(n, T)).round().astype(int))
        return t[idx], y[idx], w[idx], S[idx], O[idx]

    coarse = _Fit(*subset(int_param(coarse_samples, "coarse_samples", 16)),
                  fibonacci_sphere(int_param(coarse_normals, "coarse_normals", 16)).numpy(), brdf, frame)
    fine = _Fit(*subset(int_param(max_samples, "max_samples", 16)),
                fibonacci_sphere(int_param(n_normals, "n_normals", 16)).numpy(), brdf, frame)
    cands = [1.0 / P0] + ([0.5 / P0] if 2 * P0 <= max_period_s or period_s is not None else [])
    # a period chosen as a multiple of the periodogram's peak may be a drift's: over nights of changing
    # geometry a high-SNR light curve is not strictly periodic, and 2 or 4 cycles fit its drift better.
    # The spin model, which follows the geometry, arbitrates: P₀/2 and P₀/4 down to the peak's period
    peak_P = synodic.get("f0_period_s") if period_s is None else None
    cands += [k / P0 for k in (2, 4) if peak_P and P0 / k >= 0.99 * peak_P and P0 / k >= min_period_s]
    table = _coarse_scan(coarse, t, S, O, n_poles, cands)
    # the coarse grid's bias is as large as the χ² differences between poles: each pole's best
    # spin is scored again on the fine grid of normals before the starts are chosen
    medium = _Fit(coarse.t, coarse.y, coarse.w, coarse.S, coarse.O, fine.N, brdf, frame)
    table = sorted(((medium.chi2(*r[1:]), *r[1:]) for r in table), key=lambda r: r[0])
    spacing = np.degrees(np.sqrt(4 * np.pi / n_poles))
    starts = _distinct_poles(table, spacing, n_starts)
    refined = sorted((_refine_spin(coarse, s[1:], spacing / 3, 90.0, span) for s in starts), key=lambda r: r[0])
    distinct: list[tuple] = []  # starts that converged to one minimum are refined once
    for r in refined:
        if all(_separation_deg((r[1], r[2]), (d[1], d[2])) > 10.0 or abs(r[3] - d[3]) * span > 0.5 for d in distinct):
            distinct.append(r)
    finals = sorted((_refine_spin(fine, r[1:], 2.0, 20.0, span) for r in distinct[:n_refine]), key=lambda r: r[0])
    if local_starts:  # the best's neighbouring minima (step 3)
        finals[0] = _local_multistart(fine, finals[0][1:], span, local_starts)  # never above finals[0]'s χ²
    chi2, lon, lat, f = finals[0]
    lon = float((lon + 180.0) % 360.0 - 180.0)
    # the EGI at the solution and its 1σ (Gauss–Newton on the spin and the support's areas)
    a, sup, err, red, scale2 = _spin_errors(fine, lon, lat, f, chi2, span, sigma is not None)
    formal_pole = float(np.hypot(err[1], np.cos(np.radians(lat)) * err[0]))
    alts = alternatives(finals, lon, lat, chi2, scale2)
    ambiguous = bool(rivals(alts))
    # the residual on every sample (not only the fit's subset)
    full = _Fit(t, y, w, S, O, fine.N, brdf, frame)
    resid = y - full.matrix(lon, lat, f) @ a
    normals, areas, lobe_areas, _ = split_lobes(a, fine.N, brdf)
    check = _check_spin(fine, a, sup, lon, lat, f, chi2, span, sig, heldout, brdf, frame)
    check.update(ambiguity(check, alts))
    boot = bootstrap if check["verdict"] == "reliable" else 0  # step 8 runs only on a reliable fit
    # the grid's bias (step 4) only where a 1σ is reported: an unreliable spin reports none
    grid_pole, grid_period = (_grid_bias(fine, lon, lat, f, span, error_grids, refined=boot > 0)
                              if check["verdict"] == "reliable" else (float("nan"), float("nan")))
    pole_err = float(np.hypot(formal_pole, grid_pole))
    period_err = float(np.hypot(err[2] / f ** 2, grid_period))
    check["pole_interval"] = None
    check["laplace_pole_err_deg"] = pole_err  # step 4's 1σ, kept beside the profile's
    if interval == "profile" and check["verdict"] == "reliable":
        # 7. the pole's profile-likelihood region (Δχ² on the profile over the period and the areas)
        from cssat.inversion.spin_errors import pole_profile_interval  # local: the profile, only while reliable

        fits = [fine] + [_Fit(fine.t, fine.y, fine.w, fine.S, fine.O, _turned(fine.N, 100 + g), brdf, frame)
                         for g in range(1, profile_grids)]
        chi2_fn = (lambda lo, la, ff: float(np.mean([q.chi2(lo, la, ff) for q in fits])))  # noqa: E731
        prof = pole_profile_interval(chi2_fn, lon, lat, f, span, scale2 if sig is not None else red)
        check["pole_interval"] = prof
        if prof["moved_deg"] > 0 or profile_grids > 1:  # the region's centre: the profile's own minimum
            lon, lat, f, chi2 = prof["lon"], prof["lat"], prof["f"], prof["chi2"]
            lon = float((lon + 180.0) % 360.0 - 180.0)
            a, _ = fine.solve(lon, lat, f)
            resid = y - full.matrix(lon, lat, f) @ a
            normals, areas, lobe_areas, _ = split_lobes(a, fine.N, brdf)
        # the region holds the noise on this grid; the grid's bias adds: the RMS shift of step 4
        pole_err = float(np.hypot(prof["pole_err_deg"], grid_pole))
    if boot:  # 8. the noise's part by a parametric bootstrap
        check["bootstrap_pole_err_deg"], check["bootstrap_period_err_s"], check["bootstrap_lr_factor"] = _bootstrap_spin(
            fine, fine.matrix(lon, lat, f) @ a, lon, lat, f, span, scale2, boot, local_starts)  # a: the EGI at (lon, lat, f)
        pole_err = float(np.hypot(check["bootstrap_pole_err_deg"], grid_pole))
        period_err = float(np.hypot(check["bootstrap_period_err_s"], grid_period))
    if check["verdict"] == "unreliable":  # no 1σ on a model that does not fit (the grid terms NaN: so every sum)
        # — a misfitting or aliased spin's curvature says nothing of its error: in class 457σ off on one wrong
        # pole, an alias of the cadence at 1e-4 s. The period's calibrated 1σ is the synodic search's (``synodic``)
        err, formal_pole = np.full(3, np.nan), float("nan")
    split = None
    if split_nights:
        opts = dict(sigma=sig, brdf=brdf, frame=frame, period_s=P0, min_period_s=min_period_s, max_period_s=max_period_s,
                    n_poles=n_poles, n_starts=n_starts, n_refine=n_refine, coarse_normals=coarse_normals,
                    coarse_samples=coarse_samples, n_normals=n_normals, max_samples=max_samples, local_starts=local_starts)
        split = _night_split(estimate_spin, t, y, S, O, opts, lon, lat)
    return SpinSolution(pole_lon_deg=lon, pole_lat_deg=float(lat), period_s=float(1 / f), lon_err_deg=float(err[0]),
                        lat_err_deg=float(err[1]), pole_err_deg=pole_err, period_err_s=period_err,
                        formal_pole_err_deg=formal_pole, formal_period_err_s=float(err[2] / f ** 2),
                        grid_pole_shift_deg=grid_pole, grid_period_shift_s=float(grid_period),
                        chi2=float(chi2), reduced_chi2=float(red),
                        model_fits=bool(red <= MODEL_FITS_CHI2) if sigma is not None else None, normals=normals, areas=areas, lobe_areas=lobe_areas,
                        residual=resid,
                        synodic=synodic, alternatives=alts, ambiguous=bool(ambiguous), frame=frame, brdf=brdf, **check,
                        **(split or {"split_pole_err_deg": None, "split_period_err_s": None, "split_poles": []}),
                        coarse=[{"chi2": float(r[0]), "pole_lon_deg": float(r[1]), "pole_lat_deg": float(r[2]),
                                 "period_s": float(1 / r[3])} for r in table])


def _grid_bias(fine: _Fit, lon: float, lat: float, f: float, span: float, grids: int,
               refined: bool = False) -> tuple[float, float]:
    """``estimate_spin`` step 4's grid term: the RMS shift of the pole (degrees) and of the period
    (s) when the solution ``(lon, lat, f)`` is refined again on ``grids`` grids of normals (seeds
    ``0 … grids − 1``): ``fine``'s turned (:func:`_turned`), or ``refined`` (:func:`_refined`)."""
    g_pole, g_period = [], []
    for g in range(grids):
        N = _refined(fine.N, g) if refined else _turned(fine.N, g)
        turned = _Fit(fine.t, fine.y, fine.w, fine.S, fine.O, N, fine.brdf, fine.frame)
        _, lon_g, lat_g, f_g = _refine_spin(turned, (lon, lat, f), 1.0, 5.0, span)
        g_pole.append(_separation_deg((lon, lat), (lon_g, lat_g)))
        g_period.append(1 / f_g - 1 / f)
    return float(np.sqrt(np.mean(np.square(g_pole)))), float(np.sqrt(np.mean(np.square(g_period))))


def _check_spin(fine: _Fit, a: np.ndarray, sup: np.ndarray, lon: float, lat: float, f: float, chi2: float, span: float,
                sig: Any, heldout: Any, brdf: Any, frame: str) -> dict[str, Any]:
    """``estimate_spin`` step 6: the verdict on the solution ``(lon, lat, f)`` with the EGI ``a``
    (support ``sup``) fitted on ``fine``, from the ``heldout`` data or, without them, from the
    fitted samples' χ² (the keys ``verdict``, ``verdict_why``, ``heldout_chi2``, ``heldout_n``,
    ``heldout_threshold``)."""
    from cssat.inversion.spin_errors import _spin_jacobian, verdict_keys  # local: the verdict's

    J_fit = _spin_jacobian(fine, lon, lat, f, a, sup, span)
    held = None
    if heldout is not None and sig is not None:
        th, yh, Sh, Oh, wh = _check_heldout(heldout)
        fit_h = _Fit(th, yh, wh, Sh, Oh, fine.N, brdf, frame)
        held = ((yh - fit_h.matrix(lon, lat, f) @ a) * wh, _spin_jacobian(fit_h, lon, lat, f, a, sup, span))
    return verdict_keys(J_fit, len(fine.t), chi2, sig is not None, held, "the pole")


def _check_heldout(heldout: Any) -> tuple[np.ndarray, ...]:
    """``heldout = (times_s, flux, sun, obs, sigma)`` checked: ``t, y (T,), S, O (T, 3), w = 1/σ (T,)``."""
    try:
        th, yh, Sh, Oh, sh = heldout
    except (TypeError, ValueError) as e:
        raise FieldError("heldout", "expected (times_s, flux, sun, obs, sigma): the held-out samples, their Sun and "
                                    "observer directions and the flux's 1σ") from e
    if sh is None:
        raise FieldError("heldout", "the held-out samples need their sigma (the flux's 1σ) to be tested")
    try:
        th, yh, Sh, Oh, wh, _ = _check_light_curve(th, yh, Sh, Oh, sh, fitted=False)
    except FieldError as e:
        raise FieldError("heldout", f"the held-out samples: {e.detail}") from e
    return th, yh, Sh, Oh, wh


def _synodic_period(t: np.ndarray, y: np.ndarray, w: np.ndarray, sigma: Any, period_s: float | None, min_period_s: float,
                    max_period_s: float) -> tuple[float, dict[str, Any]]:
    """The search's synodic period ``P₀`` (s) and the verdict on it: ``period_s`` when given, else
    :func:`estimate_period`'s best candidate on ``t, y (T,)`` (weights ``w = 1/σ``), whatever its
    verdict."""
    if period_s is None:
        synodic = estimate_period(t, y, sigma=None if sigma is None else 1.0 / w, min_period_s=min_period_s,
                                  max_period_s=max_period_s, detrend=1)  # each night's offset and slope
        P0 = synodic["best_period_s"]  # the search wants the best candidate, whatever the verdict
    else:
        P0 = float_param(period_s, "period_s", 0.0, open_lo=True)
        synodic = {"period_s": P0, "given": True}
    return P0, synodic
