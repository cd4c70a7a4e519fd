"""The inputs of :func:`cssat.inversion.estimate_period` checked: astropy ``Time`` and
``Quantity`` made plain numbers with their units honoured, the track sorted in time, its labels
(tracks, camera channels) and its 1σ; every refusal a FieldError naming the argument."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.inversion.fourier import _vector

__all__ = ["MIN_SAMPLES"]

#: the fewest samples a period is searched in
MIN_SAMPLES = 12


def _check_track(times_s: Any, flux: Any, sigma: Any, segments: Any,
                 zero_points: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any, Any]:
    """The track sorted in time, checked: ``t (T,)`` (s), ``y (T,)``, the weights ``w = 1/σ (T,)``
    (ones without ``sigma``), the track index of each sample ``(T,)`` from ``segments`` and the
    zero-point index ``(T,)`` from ``zero_points`` (each ``None`` when not given)."""
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

    def labels(x: Any, field: str) -> Any:
        if x is None:
            return None
        a = np.asarray(x)
        if a.shape != order.shape:
            raise FieldError(field, f"expected one label per sample ({len(order)}), got {a.shape}")
        try:
            return np.unique(a.astype(str)[order], return_inverse=True)[1].reshape(-1)
        except (TypeError, ValueError):
            raise FieldError(field, "labels must be strings or numbers") from None

    seg_given, zp = labels(segments, "segments"), labels(zero_points, "zero_points")
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
    return t, y, w, seg_given, zp


def _astropy_inputs(times_s: Any, flux: Any, sigma: Any, lo: Any, hi: Any) -> tuple[Any, Any, Any, Any, Any]:
    """astropy inputs as plain numbers, units honoured: a ``Time`` as seconds from its first
    instant, a time ``Quantity`` in seconds, a flux ``Quantity``'s ``sigma`` in the flux's unit,
    period bounds as seconds. A unit that does not convert is a FieldError naming the field."""
    def seconds(q: Any, field: str) -> Any:
        if q is None or not hasattr(q, "unit") or not hasattr(q, "to_value"):
            return q
        try:
            return q.to_value("s")
        except Exception:  # noqa: BLE001 - astropy's UnitConversionError, UnitsError
            raise FieldError(field, f"expected a time (s, min, h, d…), got a quantity in {q.unit}") from None

    if hasattr(times_s, "jd1") and hasattr(times_s, "jd2"):  # an astropy Time: seconds from its first instant
        times_s = (times_s - times_s.min()).to_value("s")
    else:
        times_s = seconds(times_s, "times_s")
    if hasattr(flux, "unit") and hasattr(flux, "to_value"):
        if sigma is not None and hasattr(sigma, "unit"):
            try:
                sigma = sigma.to_value(flux.unit)
            except Exception:  # noqa: BLE001
                raise FieldError("sigma", f"expected the unit of flux ({flux.unit}), got {sigma.unit}") from None
        elif sigma is not None and not (str(flux.unit) in ("", "mag") or "mag" in str(flux.unit)):
            raise FieldError("sigma", f"flux is in {flux.unit}: give sigma as a quantity in that unit")
    elif sigma is not None and hasattr(sigma, "unit") and str(sigma.unit) not in ("", "mag"):
        raise FieldError("sigma", f"flux has no unit, sigma is in {sigma.unit}")
    return times_s, flux, sigma, seconds(lo, "min_period_s"), seconds(hi, "max_period_s")
