"""The pole search of :func:`cssat.inversion.spin.estimate_spin` (steps 2, 3 and 8's refits): the
frame of a pole, the Sun's and the observer's longitude rates about it, the coarse scan of poles
and synodic offsets, the distinct starts it leaves, the Nelder–Mead refinement, its local
multi-start about a solution, and the parametric bootstrap's refits."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat.inversion.egi import fibonacci_sphere
from cssat.inversion.spin_errors import _offset_pole, _separation_deg, profile_chi2
from cssat.scene.attitude import spin_frame

__all__: list[str] = []


def _pole_rotation(lon: float, lat: float, frame: str) -> np.ndarray:
    """``(3, 3)``: inertial → the frame whose z is the pole (spin_frame at zero phase)."""
    return spin_frame(np.zeros(1), lon, lat, 1.0, 0.0, frame)[0]


def _longitude_rates(S: np.ndarray, O: np.ndarray, dt: np.ndarray, close: np.ndarray, cap: float, lon: float, lat: float,
                     frame: str) -> list[float]:
    """The Sun's and the observer's (``S``, ``O (T, 3)``) median longitude rates about the pole
    ``(lon, lat)``, in Hz, over the steps ``dt (T-1,)`` marked ``close``, at most ``cap`` rad/s
    (3× their angular rates: a direction near the pole turns fast in longitude but hardly
    modulates the light curve)."""
    M = _pole_rotation(lon, lat, frame)
    out = []
    for v in (S @ M.T, O @ M.T):
        dl = (np.diff(np.arctan2(v[:, 1], v[:, 0])) + np.pi) % (2 * np.pi) - np.pi
        out.append(float(np.clip(np.median(dl[close] / dt[close]), -cap, cap)) / (2 * np.pi) if close.any() else 0.0)
    return out


def _coarse_scan(coarse: Any, t: np.ndarray, S: np.ndarray, O: np.ndarray, n_poles: int,
                 cands: list[float]) -> list[tuple]:
    """For each of ``n_poles`` poles on a Fibonacci grid, the best ``(chi2, lon, lat, f)`` on
    ``coarse`` of a scan of sidereal frequencies about each of ``cands`` (Hz), in steps of
    ``1/(20 span)`` of ``t (T,)``, over the Sun's (``S (T, 3)``) and the observer's (``O``)
    longitude rates about that pole."""
    # The light curve's apparent (synodic) frequency is the sidereal one less a weighted rate of
    # the longitudes of the Sun and the observer about the pole (each cosine factor of a facet's
    # brightness turns with its own direction): for each pole the scan covers the sidereal
    # frequencies between those two rates, plus a margin of half a cycle over the span
    span = float(t[-1] - t[0])
    dt = np.diff(t)
    close = dt < 10 * np.median(dt)
    step = 1.0 / (20 * span)
    cap = 3.0 * max((float(np.median(np.arccos(np.clip(np.einsum("ij,ij->i", v[1:], v[:-1]), -1, 1))[close] / dt[close]))
                     if close.any() else 0.0) for v in (S, O))
    grid = fibonacci_sphere(n_poles).numpy()
    lons, lats = np.degrees(np.arctan2(grid[:, 1], grid[:, 0])), np.degrees(np.arcsin(np.clip(grid[:, 2], -1, 1)))
    table = []  # (chi2, lon, lat, f)
    for lo, la in zip(lons, lats):
        best = (np.inf, lo, la, cands[0])
        r = _longitude_rates(S, O, dt, close, cap, lo, la, coarse.frame)
        margin = 0.5 / span + 0.1 * max(abs(r[0]), abs(r[1]))
        offsets = np.arange(min(0.0, *r) - margin, max(0.0, *r) + margin + step / 2, step)
        for fc in cands:
            for f in fc + offsets:
                if f > 0:
                    c = coarse.chi2(lo, la, f)
                    if c < best[0]:
                        best = (c, lo, la, f)
        table.append(best)
    return table


def _distinct_poles(table: list[tuple], spacing: float, n_starts: int) -> list[tuple]:
    """The ``n_starts`` best rows ``(chi2, lon, lat, f)`` of the sorted ``table`` whose poles are
    more than 1.5 ``spacing`` (deg) from every better one kept."""
    starts: list[tuple] = []
    for r in table:
        if all(_separation_deg((r[1], r[2]), (s[1], s[2])) > 1.5 * spacing for s in starts):
            starts.append(r)
        if len(starts) == n_starts:
            break
    return starts


def _refine_spin(fit: Any, x0: Any, dpole: float, dphase: float, span: float) -> tuple[float, float, float, float]:
    """Nelder–Mead in ``(λ, β, f)`` from ``x0`` on ``fit``'s χ², the initial simplex ``dpole``
    degrees in the pole and ``dphase`` degrees of phase over ``span`` seconds in the frequency:
    ``(chi2, lon, lat, f)``."""
    from scipy.optimize import minimize  # heavy: scipy.optimize, only for _refine_spin()

    scale = np.array([1.0, 1.0, 1.0 / (360.0 * span)])  # the frequency in degrees of phase over the span
    fun = lambda z: fit.chi2(*(np.asarray(x0) + z * scale))  # noqa: E731
    simplex = np.array([[0, 0, 0], [dpole, 0, 0], [0, dpole, 0], [0, 0, dphase]], dtype=np.float64)
    res = minimize(fun, np.zeros(3), method="Nelder-Mead",
                   options={"initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-9 * max(fun(np.zeros(3)), 1e-300),
                            "maxfev": 400})
    x = np.asarray(x0) + res.x * scale
    return (float(res.fun), *x)


#: the local multi-start's offsets from the solution: (distance, bearing) in degrees, the k-th start the k-th pair
LOCAL_OFFSETS = [(2.0, 0.0), (4.0, 135.0), (2.0, 180.0), (4.0, 315.0), (2.0, 90.0), (4.0, 225.0), (2.0, 270.0),
                 (4.0, 45.0)]


def _local_multistart(fit: Any, x0: Any, span: float, starts: int, dpole: float = 1.0,
                      dphase: float = 5.0) -> tuple[float, float, float, float]:
    """The lowest ``(chi2, lon, lat, f)`` of :func:`_refine_spin` on ``fit`` from ``x0 = (lon,
    lat, f)`` (simplex ``dpole``, ``dphase``) and from ``starts`` poles 2° and 4° from it on
    bearings 90–180° apart (:data:`LOCAL_OFFSETS`; simplex 2° and 20° of phase, the same ``f``):
    the NNLS-profiled χ² has minima a few degrees apart (its active set changes with the pole),
    where a refinement from one start stops in the nearest."""
    best = _refine_spin(fit, x0, dpole, dphase, span)
    for dist, bearing in LOCAL_OFFSETS[:starts]:
        lo, la = _offset_pole(float(x0[0]), float(x0[1]), bearing, dist)
        best = min(best, _refine_spin(fit, (lo, la, x0[2]), 2.0, 20.0, span), key=lambda r: r[0])
    return best


def _bootstrap_spin(fine: Any, model: np.ndarray, lon: float, lat: float, f: float, span: float, scale2: float,
                    B: int, starts: int = 0) -> tuple[float, float, float]:
    """``estimate_spin`` step 8: the RMS shift of the pole (degrees) and of the period (s) over
    ``B`` refinements from the solution ``(lon, lat, f)`` of light curves ``model (T,) + ε``,
    ``ε ~ N(0, scale2 / w²)`` on ``fine``'s samples and normals (a fixed seed; each refit the
    estimator's: :func:`_local_multistart` with ``starts``, as ``estimate_spin(local_starts=…)``); and the
    replicates' mean profile ``Δχ²`` at the pole they were drawn from over its two degrees of
    freedom (``bootstrap_lr_factor``: 1 where Wilks' χ²₂ holds; above 1 the profile region of
    step 7 is too small by its square root — a bootstrap calibration of the likelihood ratio)."""
    rng = np.random.default_rng(0)
    sd = np.sqrt(scale2) / fine.w
    pole, period, lr = [], [], []
    for _ in range(B):
        rep = type(fine)(fine.t, model + sd * rng.standard_normal(len(model)), fine.w, fine.S, fine.O, fine.N, fine.brdf,
                         fine.frame)
        c_b, lon_b, lat_b, f_b = _local_multistart(rep, (lon, lat, f), span, starts)
        pole.append(_separation_deg((lon, lat), (lon_b, lat_b)))
        period.append(1 / f_b - 1 / f)
        lr.append(max(profile_chi2(rep.chi2, lon, lat, f, span)[0] - c_b, 0.0) / scale2)
    return (float(np.sqrt(np.mean(np.square(pole)))), float(np.sqrt(np.mean(np.square(period)))),
            float(np.mean(lr) / 2))
