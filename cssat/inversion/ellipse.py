"""A direction's error ellipse: the 2-D uncertainty of a pole or of an angular momentum's
direction, where a circle is the wrong shape.

The refits that measure a direction's 1σ (a parametric bootstrap's replicates, the grid's shifts)
spread along the χ² valley, which is often long and narrow; the radial 1σ (the root mean square of
their separations) then draws a circle that is too wide across the valley and too short along it.
For a spread along one line the circle of radius ``1.0714 ×`` the radial 1σ holds 71.6 % (not
68.27 %) and that of ``1.7579 ×`` holds 92.1 % (not 95.45 %). The ellipse keeps the shape:

- :func:`tangent_offset`: a direction's offset from a centre in the centre's tangent plane
  (azimuthal equidistant: east, north in degrees, the length the great-circle separation);
- :func:`error_ellipse`: the 1σ ellipse ``(major, minor, position angle)`` of a set of such
  offsets, from their second moments about zero (the fit's own answer is the centre);
  :func:`ellipse_of_cov` the same of a covariance ``(2, 2)``;
- :func:`ellipse_level`: the confidence level of the smallest region that holds a direction — a
  Gaussian's, or with the covariance estimated from ``dof`` replicates Hotelling's (the F
  distribution). A direction is inside the 68.27 % region when its level is at most 0.6827;
  :func:`errors_level` reads the ellipse from an estimator's ``errors``.

Assumptions: offsets small enough that the tangent plane holds them (a few degrees: the
projection's error is of the order of the square of the offset in radians); the spread Gaussian
in that plane.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.inversion.spin_errors import _pole_vector

__all__ = ["tangent_offset", "error_ellipse", "ellipse_of_cov", "ellipse_level", "errors_level"]


def tangent_offset(center: tuple[float, float], point: tuple[float, float]) -> np.ndarray:
    """``(2,)``: the direction ``point`` seen from ``center`` (each ``(longitude, latitude)`` in
    degrees) as ``(east, north)`` in degrees — the azimuthal equidistant projection about
    ``center``: its length is the great-circle separation, its bearing the great circle's."""
    c, p = _pole_vector(*center), _pole_vector(*point)
    lo = math.radians(center[0])
    east = np.array([-math.sin(lo), math.cos(lo), 0.0])
    north = np.cross(c, east)
    e, n = float(p @ east), float(p @ north)
    s = math.hypot(e, n)
    if s == 0.0:
        return np.zeros(2)
    return np.array([e, n]) * (math.degrees(math.atan2(s, float(p @ c))) / s)


def error_ellipse(offsets: Any) -> tuple[float, float, float]:
    """The 1σ ellipse ``(major_deg, minor_deg, pa_deg)`` of the offsets ``(n, 2)`` (east, north in
    degrees, :func:`tangent_offset`) about zero — their second-moment matrix's square-rooted
    eigenvalues and the major axis's position angle from north through east in [0, 180) (a
    covariance: :func:`ellipse_of_cov`). ``major² + minor²`` is the mean square offset, the
    radial 1σ squared."""
    d = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)
    if len(d) == 0:
        raise FieldError("offsets", "expected at least one (east, north) offset, got none")
    return ellipse_of_cov(d.T @ d / len(d))


def ellipse_of_cov(cov: Any) -> tuple[float, float, float]:
    """The 1σ ellipse ``(major_deg, minor_deg, pa_deg)`` of a covariance ``(2, 2)`` of ``(east,
    north)`` in degrees²: the square roots of its eigenvalues and the major axis's position angle
    from north through east, in [0, 180)."""
    c = np.asarray(cov, dtype=np.float64)
    if c.shape != (2, 2):
        raise FieldError("cov", f"expected a (2, 2) covariance, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise FieldError("cov", f"expected finite values, got {c.tolist()}")
    scale = max(float(np.abs(c).max()), 1e-300)
    w, v = np.linalg.eigh((c + c.T) / 2)  # symmetrised: a pseudo-inverse's rounding leaves it slightly asymmetric
    if w[0] < -1e-6 * scale:  # rounding may leave a zero eigenvalue slightly below 0; a negative variance is refused
        raise FieldError("cov", f"expected a covariance (no negative variance), got eigenvalues {w.tolist()}")
    w = np.clip(w, 0.0, None)
    pa = math.degrees(math.atan2(v[0, 1], v[1, 1])) % 180.0  # the major axis (the larger eigenvalue, last)
    return math.sqrt(w[1]), math.sqrt(w[0]), pa


def ellipse_level(center: tuple[float, float], point: tuple[float, float], major_deg: float, minor_deg: float,
                  pa_deg: float, dof: int = 0) -> float:
    """The confidence level of the smallest error region about ``center`` that holds ``point``
    (``(longitude, latitude)`` in degrees), for the 1σ ellipse ``(major_deg, minor_deg, pa_deg)``
    (:func:`error_ellipse`): with ``m²`` the point's Mahalanobis distance squared, ``1 −
    exp(−m²/2)`` (the χ² of two degrees of freedom: the covariance known), or with the covariance
    estimated from ``dof ≥ 3`` zero-mean replicates Hotelling's ``F₂,dof−1(m² (dof − 1) / (2
    dof))`` (wider: at ``dof = 20`` the 68.27 % region's radius is 1.06× the Gaussian's, the
    95.45 % one's 1.12×). The point is inside the ``q`` region when the level is at most ``q``;
    1.0 for a point off a degenerate (zero-width) ellipse's line."""
    if not (minor_deg >= 0 and major_deg >= minor_deg):
        raise FieldError("minor_deg", f"expected 0 ≤ minor ≤ major, got minor {minor_deg!r}, major {major_deg!r}")
    if dof and (int(dof) != dof or dof < 3):
        raise FieldError("dof", f"expected 0 (the covariance known) or a replicate count ≥ 3, got {dof!r}")
    e, n = tangent_offset(center, point)
    pa = math.radians(pa_deg)
    u, w = e * math.sin(pa) + n * math.cos(pa), e * math.cos(pa) - n * math.sin(pa)  # along, across the major axis
    tiny = 1e-9 * math.hypot(e, n)  # the projection's rounding: a point on a flat ellipse's line is on it
    u, w = (0.0 if abs(u) <= tiny else u), (0.0 if abs(w) <= tiny else w)
    if (w and not minor_deg) or (u and not major_deg):
        return 1.0  # off a zero-width ellipse's line (or its point)
    m2 = (u * u / major_deg**2 if u else 0.0) + (w * w / minor_deg**2 if w else 0.0)
    if not dof:
        return 1.0 - math.exp(-m2 / 2)
    from scipy.stats import f  # heavy: scipy.stats, only for an estimated covariance

    return float(f.cdf(m2 * (dof - 1) / (2 * dof), 2, dof - 1))


def errors_level(errors: dict[str, float], name: str, center: tuple[float, float], point: tuple[float, float]) -> float:
    """:func:`ellipse_level` of ``point`` for the ellipse an estimator's ``errors`` give the
    direction ``name`` at ``center`` (the keys ``{name}_major_deg``, ``{name}_minor_deg``,
    ``{name}_pa_deg``, ``{name}_dof``); NaN where they are NaN (a 1σ withheld by an unreliable
    verdict)."""
    keys = [f"{name}_{k}" for k in ("major_deg", "minor_deg", "pa_deg", "dof")]
    missing = [k for k in keys if k not in errors]
    if missing:
        raise FieldError("errors", f"expected the ellipse's keys {', '.join(keys)}; missing {', '.join(missing)}")
    major, minor, pa, dof = (float(errors[k]) for k in keys)
    if not all(math.isfinite(v) for v in (major, minor, pa, dof)):
        return float("nan")
    return ellipse_level(center, point, major, minor, pa, int(dof))
