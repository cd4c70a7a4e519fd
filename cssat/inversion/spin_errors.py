"""The spin's 1σ (:func:`cssat.inversion.spin.estimate_spin`, steps 4 and 5): the Gauss–Newton
covariance of the pole, the period and the support's areas, and the spread of the nights' own spins."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.observations import stretches


def _pole_vector(lon_deg: float, lat_deg: float) -> np.ndarray:
    lo, la = np.radians(lon_deg), np.radians(lat_deg)
    return np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])


def separation_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    """The angle (degrees) between the poles ``a`` and ``b``, each ``(longitude, latitude)`` in degrees."""
    return float(np.degrees(np.arccos(np.clip(_pole_vector(*a) @ _pole_vector(*b), -1.0, 1.0))))


_separation_deg = separation_deg  # the old private name, kept for old imports


def _spin_errors(fine: Any, lon: float, lat: float, f: float, chi2: float, span: float,
                 weighted: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """The EGI ``a (K,)`` at the spin ``(lon, lat, f)`` on ``fine``, its support ``(K,)`` (bool),
    the formal Gauss–Newton 1σ ``(3,)`` of ``(λ, β, f)`` with the support's areas, the reduced χ²
    and the covariance's scale (the reduced χ², at least 1 when ``weighted``)."""
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
    scale2 = max(red, 1.0) if weighted else red
    try:
        cov = np.linalg.pinv(J.T @ J)[:3, :3] * scale2
        err = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:  # pragma: no cover - pinv converges on finite input
        err = np.full(3, np.inf)
    return a, sup, err, red, scale2


def _night_split(search: Any, t: np.ndarray, y: np.ndarray, S: np.ndarray, O: np.ndarray, opts: dict[str, Any], lon: float,
                 lat: float) -> dict[str, Any] | None:
    """The spin searched on each contiguous stretch alone (``estimate_spin`` step 5) by ``search``
    (``estimate_spin`` with ``opts``), and the standard error of their mean, ``σ² = Σᵢ θᵢ² /
    (g (g−1))`` (``θᵢ`` the angle of the ``i``-th pole from their mean direction; the same for the
    period): ``None`` with fewer than two stretches of at least 16 samples that the search takes."""
    seg = stretches(t)
    sols = []
    for g in np.unique(seg):
        keep = seg == g
        if keep.sum() < 16:
            continue
        sig = opts["sigma"]
        try:
            sols.append(search(t[keep], y[keep], S[keep], O[keep], **{**opts, "sigma": None if sig is None else np.asarray(sig)[keep]}))
        except FieldError:  # a stretch the search refuses (too short for the periods): not a group
            continue
    g = len(sols)
    if g < 2:
        return None
    V = np.array([_pole_vector(s_.pole_lon_deg, s_.pole_lat_deg) for s_ in sols])
    mean = V.sum(0) / max(float(np.linalg.norm(V.sum(0))), 1e-300)
    theta = np.degrees(np.arccos(np.clip(V @ mean, -1.0, 1.0)))
    P = np.array([s_.period_s for s_ in sols])
    return {"split_pole_err_deg": float(np.sqrt(np.sum(theta ** 2) / (g * (g - 1)))),
            "split_period_err_s": float(np.sqrt(np.sum((P - P.mean()) ** 2) / (g * (g - 1)))),
            "split_poles": [{"pole_lon_deg": s_.pole_lon_deg, "pole_lat_deg": s_.pole_lat_deg, "period_s": s_.period_s,
                             "separation_deg": _separation_deg((lon, lat), (s_.pole_lon_deg, s_.pole_lat_deg))} for s_ in sols]}
