"""The pole search of :func:`cssat.inversion.spin.estimate_spin` (steps 2 and 3): the frame of a
pole, the Sun's and the observer's longitude rates about it, the coarse scan of poles and
synodic offsets, and the distinct starts it leaves."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat.inversion.egi import fibonacci_sphere
from cssat.inversion.spin_errors import _separation_deg
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
