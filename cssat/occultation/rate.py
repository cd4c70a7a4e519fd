"""How often a satellite occults a star bright enough to image it (issue 25, point 4).

No star catalogue can be had offline here, so the star counts are an **assumption**: the mean
all-sky cumulative counts ``N(< V)`` of stars brighter than ``V`` — round numbers of the
textbook counts (Allen's *Astrophysical Quantities*; the Hipparcos and Tycho-2 totals), good to
~30 % — interpolated in ``log N``:

======  =====  ======  ======  ======  ======  ========  ========
V       6      7       8       9       10      11        12
N(<V)   4,800  14,000  41,000  1.2e5   3.3e5   8.7e5     2.2e6
======  =====  ======  ======  ======  ======  ========  ========

The density varies with Galactic latitude by ~3× about this mean (denser in the plane).

Geometry: a GEO satellite stands still in the observer's sky while the stars drift past at the
sidereal rate, ``15.04″ cos δ`` per second of time. A star is occulted when its path crosses the
satellite's silhouette, so in a night of ``night_hours`` the satellite sweeps a strip of sky of
length ``15.04°/h × night_hours × cos δ`` and of width its angular extent across the drift,
``width_m / distance_m`` — widened to ``(width_m + 2 reach_m) / distance_m`` when the array can
be placed anywhere within ``± reach_m`` of its site across the track (each star's shadow path is
predictable, so a mobile array goes to it). Events a year: that strip's area × the star density
× 365 nights (clear-sky fraction, the Moon and the satellite's station-keeping wander, which
picks new stars each night, are not modelled).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import float_param

__all__ = ["STAR_COUNTS", "stars_brighter_than", "occultation_rate"]

#: ``(V, N(<V) over the whole sky)``: the assumed mean star counts (module docstring).
STAR_COUNTS = ((6.0, 4.8e3), (7.0, 1.4e4), (8.0, 4.1e4), (9.0, 1.2e5), (10.0, 3.3e5), (11.0, 8.7e5), (12.0, 2.2e6))
SKY_DEG2 = 4 * math.pi * (180 / math.pi) ** 2  # 41,253 deg²


def stars_brighter_than(magnitude: float) -> float:
    """The assumed mean number of stars brighter than V = ``magnitude`` per square degree
    (:data:`STAR_COUNTS` interpolated in ``log N``, V 6–12)."""
    v = float_param(magnitude, "magnitude", STAR_COUNTS[0][0], STAR_COUNTS[-1][0])
    V, N = np.array(STAR_COUNTS).T
    return float(10 ** np.interp(v, V, np.log10(N)) / SKY_DEG2)


def occultation_rate(magnitude: float, width_m: float, distance_m: float, *, dec_deg: float = 0.0, night_hours: float = 8.0,
                     reach_m: float = 0.0) -> dict[str, Any]:
    """Occultations a year of stars brighter than V = ``magnitude`` by a satellite of extent
    ``width_m`` (across the stars' drift) at ``distance_m``, seen at declination ``dec_deg``, for
    ``night_hours`` of dark sky a night, by an array that can be placed within ``± reach_m`` of
    its site across the shadow's track (0: a fixed site). Returns ``per_year``, ``per_night``,
    ``strip_deg2`` (the sky swept in a night) and ``stars_per_deg2`` (the assumed density;
    module docstring)."""
    w = float_param(width_m, "width_m", 0.0, open_lo=True)
    z = float_param(distance_m, "distance_m", 0.0, open_lo=True)
    dec = float_param(dec_deg, "dec_deg", -90.0, 90.0)
    hours = float_param(night_hours, "night_hours", 0.0, 24.0)
    reach = float_param(reach_m, "reach_m", 0.0)
    length_deg = 15.041 * hours * math.cos(math.radians(dec))
    width_deg = math.degrees((w + 2 * reach) / z)
    density = stars_brighter_than(magnitude)
    per_night = length_deg * width_deg * density
    return {"per_year": 365.25 * per_night, "per_night": per_night, "strip_deg2": length_deg * width_deg,
            "stars_per_deg2": density}
