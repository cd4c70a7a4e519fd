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

__all__ = ["estimate_period"]


def _design(t: np.ndarray, period: float, n: int) -> np.ndarray:
    w = 2 * np.pi * t / period
    cols = [np.ones_like(t)]
    for k in range(1, n + 1):
        cols += [np.cos(k * w), np.sin(k * w)]
    return np.stack(cols, 1)


def _chi2(t: np.ndarray, y: np.ndarray, w: np.ndarray, period: float, n: int) -> float:
    X = _design(t, period, n) * w[:, None]
    coef, *_ = np.linalg.lstsq(X, y * w, rcond=None)
    r = X @ coef - y * w
    return float(r @ r)


def estimate_period(times_s: Any, flux: Any, *, sigma: Any = None, min_period_s: float = 60.0,
                    max_period_s: float = 86400.0, n_harmonics: int = 4, double_gain: float = 0.9,
                    samples_per_peak: int = 20) -> dict[str, Any]:
    """``{"period_s", "period_err_s", "f0_period_s" (the periodogram's), "doubled" (bool),
    "chi2"}`` of a light curve ``flux (T,)`` at ``times_s (T,)`` (any cadence)."""
    try:
        from astropy.timeseries import LombScargle
    except ImportError:
        raise FieldError("method", "the periodogram needs astropy: pip install 'cssat[astro]'") from None
    from scipy.optimize import minimize_scalar

    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    y = np.asarray(flux, dtype=np.float64).reshape(-1)
    if t.shape != y.shape or len(t) < 4 * n_harmonics + 2 or not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise FieldError("flux", f"expected finite times and values of one length, at least {4 * n_harmonics + 2}")
    n = int_param(n_harmonics, "n_harmonics", 1, 50)
    lo = float_param(min_period_s, "min_period_s", 0.0, open_lo=True)
    hi = float_param(max_period_s, "max_period_s", lo, open_lo=True)
    dy = None if sigma is None else np.broadcast_to(np.asarray(sigma, dtype=np.float64), y.shape)
    w = np.ones_like(y) if dy is None else 1.0 / dy
    t = t - t[0]
    freq, power = LombScargle(t, y, dy).autopower(minimum_frequency=1 / hi, maximum_frequency=2 / lo,
                                                  samples_per_peak=samples_per_peak)
    f0 = float(freq[np.argmax(power)])
    span = float(t[-1] - t[0])

    def refine(period: float) -> tuple[float, float]:
        df = 1.0 / (samples_per_peak * span)  # the periodogram's grid step around 1/period
        res = minimize_scalar(lambda f: _chi2(t, y, w, 1 / f, n), bounds=(1 / period - 2 * df, 1 / period + 2 * df),
                              method="bounded", options={"xatol": 1e-12 / period})
        return 1 / res.x, float(res.fun)

    p1, c1 = refine(1 / f0)
    p2, c2 = refine(2 / f0)
    doubled = c2 < double_gain * c1 and 2 / f0 <= hi
    period, chi2 = (p2, c2) if doubled else (p1, c1)
    # 1σ: Δχ² = 1 (scaled by the reduced χ² when sigma is unknown), from χ²'s curvature in frequency
    f = 1 / period
    h = 1e-3 / span
    curv = (_chi2(t, y, w, 1 / (f + h), n) - 2 * chi2 + _chi2(t, y, w, 1 / (f - h), n)) / h ** 2
    dof = max(len(t) - (2 * n + 1) - 1, 1)
    scale = 1.0 if dy is not None else chi2 / dof
    sig_f = np.sqrt(2 * scale / curv) if curv > 0 else np.inf
    return {"period_s": period, "period_err_s": float(sig_f * period ** 2), "f0_period_s": 1 / f0, "doubled": bool(doubled),
            "chi2": chi2}
