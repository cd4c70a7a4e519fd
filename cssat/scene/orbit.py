"""Orbit, Sun, ground observer and Earth shadow over a time grid (paper: "Light curve simulation").

Every position is geocentric in one frame, the GCRS (axes of the ICRS), in km: SGP4 works in TEME
and skyfield rotates its output to the GCRS, and the Sun (JPL DE421, shipped by ``skyfield-data``)
and the observer come from skyfield in the same frame. Mixing a J2000 Sun with a TEME satellite
would misplace the Sun by 0.27°, half the 0.5° specular window of Eq. 9.

The element sets SGP4 takes are read and checked in :mod:`cssat.scene.elements`, the time stamps in
:mod:`cssat.scene.times`.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from datetime import datetime, timedelta
from functools import lru_cache
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.scene.elements import ASTRA_1KR_SYNTHETIC_TLE, R_EARTH_KM, STALE_DAYS, check_elements, check_tle, earth_satellite
from cssat.scene.times import TIMES_FORMS, start_datetime, utc_times

__all__ = [
    "ASTRA_1KR_SYNTHETIC_TLE",
    "Scenario",
    "check_tle",
    "earth_satellite",
    "skyfield_ephemeris",
    "earth_shadow_fraction",
    "make_scenario",
    "utc_times",
    "TIMES_FORMS",
]

R_SUN_KM = 695_700.0  # IAU 2015 nominal solar radius

#: the dates DE421 (skyfield-data's ephemeris) covers
EPHEMERIS_RANGE = (datetime(1899, 7, 29), datetime(2053, 10, 9))


@dataclass(frozen=True)
class Scenario:
    """The geometry of one observation, sampled at ``T`` times. Positions are GCRS, km.

    Attributes
    ----------
    times : (T,) ``datetime64[us]`` UTC
    r_sat, v_sat : (T, 3) satellite position (km) and velocity (km/s)
    r_sun : (T, 3) Sun position (km), geometric
    r_obs : (T, 3) observer position (km)
    azimuth_deg, elevation_deg : (T,) topocentric direction of the satellite (deg; azimuth from
        north through east)
    range_km : (T,) observer–satellite distance ``r_topo`` (km)
    sun_range_km : (T,) satellite–Sun distance (km)
    sunlit : (T,) fraction of the solar disk seen from the satellite (1 lit, 0 umbra)
    """

    times: np.ndarray
    r_sat: np.ndarray
    v_sat: np.ndarray
    r_sun: np.ndarray
    r_obs: np.ndarray
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    range_km: np.ndarray
    sun_range_km: np.ndarray
    sunlit: np.ndarray
    name: str = ""

    @property
    def sun_dir(self) -> np.ndarray:
        """``(T, 3)`` unit vectors from the satellite to the Sun (GCRS), the paper's S̄."""
        d = self.r_sun - self.r_sat
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    @property
    def obs_dir(self) -> np.ndarray:
        """``(T, 3)`` unit vectors from the satellite to the observer (GCRS), the paper's V̄."""
        d = self.r_obs - self.r_sat
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def __len__(self) -> int:
        return len(self.times)


@lru_cache(maxsize=1)
def skyfield_ephemeris() -> tuple[Any, Any]:
    """``(timescale, ephemeris)``: skyfield's timescale and the DE421 ephemeris, loaded offline
    from ``skyfield-data``."""
    import skyfield_data  # heavy: skyfield-data, only for skyfield_ephemeris()
    from skyfield.api import Loader  # heavy: skyfield, only for skyfield_ephemeris()

    with warnings.catch_warnings():
        # skyfield-data warns when its Earth-orientation table is past its date; DE421 and the
        # built-in ΔT table cover the years simulated here
        warnings.filterwarnings("ignore", message=".*has expired.*", category=RuntimeWarning)
        load = Loader(skyfield_data.get_skyfield_data_path(), expire=False, verbose=False)
        return load.timescale(builtin=True), load("de421.bsp")


_skyfield = skyfield_ephemeris  # the old private name, kept for old imports


def earth_shadow_fraction(r_sat_km: np.ndarray, r_sun_km: np.ndarray) -> np.ndarray:
    """Fraction of the solar disk visible from the satellite past a spherical Earth (conical
    umbra/penumbra model): 1 in sunlight, 0 in the umbra, between in the penumbra.

    ``r_sat_km``, ``r_sun_km``: ``(T, 3)`` geocentric positions (km). The Sun and the Earth are
    disks of apparent radii ``asin(R/d)``; the visible fraction is one minus their overlap area over
    the Sun's disk area (circle–circle intersection on the sky, small-angle geometry).
    """
    r_sat = np.asarray(r_sat_km, dtype=np.float64)
    to_sun = np.asarray(r_sun_km, dtype=np.float64) - r_sat
    d_sun = np.linalg.norm(to_sun, axis=-1)
    d_earth = np.linalg.norm(r_sat, axis=-1)
    a = np.arcsin(np.clip(R_SUN_KM / d_sun, 0, 1))  # Sun's apparent radius
    b = np.arcsin(np.clip(R_EARTH_KM / d_earth, 0, 1))  # Earth's apparent radius
    cosc = np.einsum("...i,...i->...", to_sun, -r_sat) / (d_sun * d_earth)
    c = np.arccos(np.clip(cosc, -1, 1))  # separation of the two disk centres
    frac = np.ones_like(c)
    full = c <= b - a  # Sun entirely behind the Earth
    frac[full] = 0.0
    # partial overlap: area of the lens of two circles with radii a, b at distance c
    part = (c < a + b) & ~full
    if np.any(part):
        ap, bp, cp = a[part], b[part], c[part]
        x = np.clip((cp**2 + ap**2 - bp**2) / (2 * cp * ap), -1, 1)
        y = np.clip((cp**2 + bp**2 - ap**2) / (2 * cp * bp), -1, 1)
        lens = ap**2 * np.arccos(x) + bp**2 * np.arccos(y) - 0.5 * np.sqrt(
            np.clip((-cp + ap + bp) * (cp + ap - bp) * (cp - ap + bp) * (cp + ap + bp), 0, None)
        )
        # Earth disk inside the Sun's (annular; impossible for GEO, kept for completeness)
        inside = cp <= ap - bp
        lens = np.where(inside, np.pi * bp**2, lens)
        frac[part] = 1.0 - lens / (np.pi * ap**2)
    return np.clip(frac, 0.0, 1.0)


def make_scenario(
    tle: Any = ASTRA_1KR_SYNTHETIC_TLE,
    start_utc: Any = "2020-04-01T00:00:00",
    n_steps: int = 1437,
    step_s: float = 60.0,
    lat_deg: float = 51.17,
    lon_deg: float = 10.45,
    alt_m: float = 0.0,
    name: str | None = None,
    times: Any = None,
) -> Scenario:
    """Propagate the satellite ``tle`` with SGP4 over ``n_steps`` times ``step_s`` seconds apart
    from ``start_utc`` and compute the Sun, the observer at geodetic ``lat_deg``/``lon_deg``/``alt_m``
    (WGS84), the topocentric azimuth/elevation/range and the Earth shadow, all batched.

    ``tle`` is any of :data:`~cssat.scene.elements.SATELLITE_FORMS`: two TLE lines, three with a
    name, a TLE text, a skyfield ``EarthSatellite``, an sgp4 ``Satrec`` or an OMM/GP record
    (CelesTrak's JSON/CSV rows, ``sgp4.omm.parse_xml`` output; keys
    :data:`~cssat.scene.elements.OMM_REQUIRED`, others default to
    :data:`~cssat.scene.elements.OMM_DEFAULTS`). ``start_utc`` is any of
    :data:`~cssat.scene.times.START_FORMS`; an aware datetime is converted to UTC. ``name``
    defaults to the one the satellite carries.

    ``times``: any UTC instants (:data:`~cssat.scene.times.TIMES_FORMS`,
    :func:`~cssat.scene.times.utc_times`) — the time stamps of a measured light curve, with gaps
    and any cadence — replace ``start_utc``, ``n_steps`` and ``step_s``.

    The defaults are the paper's scenario: Astra 1KR, 1437 one-minute steps from 2020-04-01
    00:00 UTC, an observer at 51.17°N 10.45°E.
    """
    from sgp4.api import SGP4_ERRORS  # heavy: sgp4, only for make_scenario()
    from skyfield.api import wgs84  # heavy: skyfield, only for make_scenario()

    ts, eph = skyfield_ephemeris()
    sat, own_name = earth_satellite(tle, ts)
    if name is None:
        default = tle is ASTRA_1KR_SYNTHETIC_TLE
        name = "Astra 1KR (synthetic TLE)" if default else own_name or f"NORAD {sat.model.satnum}"
    stamps = None if times is None else utc_times(times)
    if stamps is not None:
        n_steps, step_s, start_utc = len(stamps), 1.0, stamps[0]
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
        raise FieldError("scenario.n_steps", f"must be a positive integer, got {n_steps!r}")
    if not (isinstance(step_s, (int, float)) and math.isfinite(step_s) and step_s > 0):
        raise FieldError("scenario.step_s", f"must be a positive number of seconds, got {step_s!r}")
    if not -90 <= lat_deg <= 90:
        raise FieldError("scenario.observer.lat_deg", f"must be in [-90, 90], got {lat_deg}")
    if not -360 <= lon_deg <= 360:
        raise FieldError("scenario.observer.lon_deg", f"must be in [-360, 360], got {lon_deg}")
    if not (isinstance(alt_m, (int, float)) and math.isfinite(alt_m) and -1000 <= alt_m <= 100_000):
        raise FieldError("scenario.observer.alt_m", f"a ground observer's altitude must be in [-1000, 100000] m, got {alt_m!r}")
    start = start_datetime(start_utc)
    check_elements(sat.model)
    epoch_days = sat.model.jdsatepoch + sat.model.jdsatepochF - 2440587.5  # days since 1970
    span = (start - datetime(1970, 1, 1)).total_seconds() / 86400 - epoch_days
    if abs(span) >= STALE_DAYS:
        logging.getLogger("cssat").warning(
            "scenario.tle: the run starts %.0f days %s the element set's epoch; SGP4's error grows by ~1-3 km a day "
            "(tens of degrees along a GEO orbit after months): use elements near the dates", abs(span),
            "after" if span > 0 else "before")

    if stamps is None:
        offsets = np.arange(n_steps) * float(step_s)
    else:  # seconds after the first stamp (exact to the microsecond for spans of centuries)
        offsets = (stamps - stamps[0]).astype(np.int64) * 1e-6
    if offsets[-1] > (EPHEMERIS_RANGE[1] - EPHEMERIS_RANGE[0]).total_seconds():
        raise FieldError("scenario.step_s", f"{n_steps} steps of {step_s:g} s span {offsets[-1] / 3.15576e7:.3g} years, "
                                            f"more than the ephemeris covers ({EPHEMERIS_RANGE[0]:%Y}–{EPHEMERIS_RANGE[1]:%Y})")
    end = start + timedelta(seconds=float(offsets[-1]))
    if not (EPHEMERIS_RANGE[0] <= start and end <= EPHEMERIS_RANGE[1]):
        raise FieldError("scenario.start_utc", f"{start} – {end} UTC is outside the ephemeris (DE421 covers "
                         f"{EPHEMERIS_RANGE[0]:%Y-%m-%d} to {EPHEMERIS_RANGE[1]:%Y-%m-%d})")
    t = ts.utc(start.year, start.month, start.day, start.hour, start.minute,
               start.second + start.microsecond * 1e-6 + offsets)
    # SGP4 error codes, checked on the raw propagator before trusting any position
    jd = np.floor(t.ut1)
    err, _, _ = sat.model.sgp4_array(jd, t.ut1 - jd)
    bad = np.flatnonzero(err)
    if bad.size:
        code = int(err[bad[0]])
        raise FieldError(
            "scenario.tle", f"SGP4 error {code} ({SGP4_ERRORS.get(code, 'unknown')}) at step {bad[0]} "
            f"({start + timedelta(seconds=float(offsets[bad[0]]))} UTC)"
        )
    geo = sat.at(t)
    r_sat = geo.position.km.T.copy()
    v_sat = geo.velocity.km_per_s.T.copy()
    if not (np.isfinite(r_sat).all() and np.isfinite(v_sat).all()):
        raise FieldError("scenario.tle", "SGP4 gives no finite position for these elements (check the epoch, "
                         "columns 19-32 of line 1, and the mean motion, columns 53-63 of line 2)")
    r_sun = (eph["sun"] - eph["earth"]).at(t).position.km.T.copy()
    topos = wgs84.latlon(lat_deg, lon_deg, elevation_m=alt_m)
    r_obs = topos.at(t).position.km.T.copy()
    alt, az, dist = (sat - topos).at(t).altaz()
    times = np.datetime64(start, "us") + (offsets * 1e6).astype("timedelta64[us]") if stamps is None else stamps
    return Scenario(
        times=times,
        r_sat=r_sat,
        v_sat=v_sat,
        r_sun=r_sun,
        r_obs=r_obs,
        azimuth_deg=np.asarray(az.degrees, dtype=np.float64),
        elevation_deg=np.asarray(alt.degrees, dtype=np.float64),
        range_km=np.asarray(dist.km, dtype=np.float64),
        sun_range_km=np.linalg.norm(r_sun - r_sat, axis=1),
        sunlit=earth_shadow_fraction(r_sat, r_sun),
        name=name,
    )
