"""Element sets: a satellite's mean orbital elements in any form a scenario takes (TLE lines or
text, an OMM/GP record, a skyfield ``EarthSatellite``, an sgp4 ``Satrec``), checked before SGP4
propagates them (:func:`cssat.scene.orbit.make_scenario`).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from cssat._checks import FieldError, FieldTypeError
from cssat.scene.times import start_datetime

__all__ = ["ASTRA_1KR_SYNTHETIC_TLE", "OMM_DEFAULTS", "OMM_REQUIRED", "SATELLITE_FORMS", "check_elements", "check_tle",
           "earth_satellite"]

#: Astra 1KR (NORAD 29055, 19.2°E), re-epoched to 2020-04-01 00:00 UTC from the real 2020-09-30
#: element set with the mean anomaly set so the longitude is 19.2°E. **Synthetic**: no real TLE near
#: that date exists, and SGP4 from one months away drifts by tens of degrees (DESIGN.md).
ASTRA_1KR_SYNTHETIC_TLE = (
    "1 29055U 06012A   20092.00000000  .00000104  00000-0  00000-0 0  9998",
    "2 29055   0.0291 247.7716 0004915 319.3582   1.8831  1.00273365 24812",
)

R_EARTH_KM = 6378.137  # WGS84 equatorial radius


def check_tle(line1: str, line2: str, field: str = "tle") -> None:
    """Validate a two-line element set; raise ``ValueError`` naming ``field.line1``/``field.line2``.

    Checks the line numbers, the 69-column length, the modulo-10 checksums (sgp4's
    ``compute_checksum``: digits count their value, ``-`` counts 1) and that both lines carry the
    same catalogue number.
    """
    from sgp4.io import compute_checksum  # heavy: sgp4, only for check_tle()

    for k, line in ((1, line1), (2, line2)):
        name = f"{field}.line{k}"
        if not isinstance(line, str):
            raise FieldError(name, f"expected a string, got {type(line).__name__}")
        line = line.rstrip()
        if len(line) != 69:
            raise FieldError(name, f"a TLE line has 69 columns, got {len(line)}")
        if line[0] != str(k) or line[1] != " ":
            raise FieldError(name, f"must start with '{k} ', got {line[:2]!r}")
        if not line[68].isdigit() or int(line[68]) != compute_checksum(line):
            raise FieldError(name, f"checksum {line[68]!r} does not match the computed {compute_checksum(line)}")
    if line1[2:7] != line2[2:7]:
        raise FieldError(field, f"catalogue numbers differ between the lines ({line1[2:7]!r} vs {line2[2:7]!r})")
    epoch = line1[18:32]
    try:
        day = float(epoch[2:])
        ok = epoch[:2].isdigit() and 1.0 <= day < 367.0
    except ValueError:
        ok = False
    if not ok:
        raise FieldError(f"{field}.line1", f"the epoch (columns 19-32, YYDDD.DDDDDDDD) is not a date: {epoch!r}")


#: OMM/GP keys without which no orbit can be initialised (CCSDS 502.0-B, CelesTrak's GP format)
OMM_REQUIRED = ("EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE",
                "ARG_OF_PERICENTER", "MEAN_ANOMALY", "NORAD_CAT_ID")
#: bookkeeping OMM keys, and the values assumed when a record lacks them
OMM_DEFAULTS = {"CLASSIFICATION_TYPE": "U", "OBJECT_ID": "", "EPHEMERIS_TYPE": 0, "ELEMENT_SET_NO": 999,
                "REV_AT_EPOCH": 0, "BSTAR": 0.0, "MEAN_MOTION_DOT": 0.0, "MEAN_MOTION_DDOT": 0.0}

SATELLITE_FORMS = ("two TLE lines (line1, line2)", "three (name, line1, line2)", "a 2- or 3-line TLE string",
                   "a skyfield EarthSatellite", "an sgp4 Satrec", "an OMM/GP record (a dict of CCSDS keys)")


def earth_satellite(tle: Any, ts: Any, field: str = "scenario.tle") -> tuple[Any, str]:
    """``(EarthSatellite, name)`` of any of :data:`SATELLITE_FORMS`; TLE lines are checked by
    :func:`check_tle` first (``name`` is ``""`` when the input carries none)."""
    from sgp4.api import Satrec  # heavy: sgp4, only for _satellite()
    from skyfield.api import EarthSatellite  # heavy: skyfield, only for _satellite()

    if isinstance(tle, EarthSatellite):
        return EarthSatellite.from_satrec(tle.model, ts), tle.name or ""
    if isinstance(tle, Satrec):
        return EarthSatellite.from_satrec(tle, ts), ""
    if isinstance(tle, Mapping):
        return _from_omm(tle, ts, field)
    if isinstance(tle, str):
        lines = [ln for ln in tle.splitlines() if ln.strip()]
    elif isinstance(tle, (tuple, list)) and all(isinstance(ln, str) for ln in tle):
        lines = list(tle)
    else:
        raise FieldTypeError(field, f"expected {', '.join(SATELLITE_FORMS)}; got {type(tle).__name__}")
    if len(lines) not in (2, 3):
        raise FieldError(field, f"a TLE has 2 lines, or 3 with a name line first; got {len(lines)}")
    name = ""
    if len(lines) == 3:
        name = lines[0].strip()
        name = name[2:].strip() if name.startswith("0 ") else name  # the "0 NAME" form of 3LE files
        lines = lines[1:]
    line1, line2 = (ln.rstrip() for ln in lines)
    check_tle(line1, line2, field=field)
    return EarthSatellite(line1, line2, name=name or None, ts=ts), name


_satellite = earth_satellite  # the old private name, kept for old imports


#: lowest perigee altitude (km) whose orbit SGP4 propagates as a satellite: below, it has re-entered
MIN_PERIGEE_KM = 80.0
#: propagating this many days or more from the element set's epoch is logged as a warning
STALE_DAYS = 30.0
_MU_KM3_S2 = 398600.4418


def check_elements(model: Any, field: str = "scenario.tle") -> None:
    """Refuse mean elements that are not an orbit around the Earth: inclination outside
    [0°, 180°], eccentricity outside [0, 1), a mean motion ≤ 0 or one whose perigee lies below
    :data:`MIN_PERIGEE_KM` (17 rev/day: ≈ 13 km). ``model`` is an sgp4 ``Satrec``."""
    inc = math.degrees(model.inclo)
    if not 0.0 <= inc <= 180.0:
        raise FieldError(field, f"inclination {inc:g}° is outside [0, 180]")
    if not 0.0 <= model.ecco < 1.0:
        raise FieldError(field, f"eccentricity {model.ecco:g} is outside [0, 1)")
    n = model.no_kozai / 60.0  # rad/s
    if not n > 0:
        raise FieldError(field, f"mean motion {model.no_kozai * 1440 / (2 * math.pi):g} rev/day must be > 0")
    a = (_MU_KM3_S2 / n**2) ** (1 / 3)
    perigee = a * (1 - model.ecco) - R_EARTH_KM
    if perigee < MIN_PERIGEE_KM:
        raise FieldError(field, f"mean motion {model.no_kozai * 1440 / (2 * math.pi):.6g} rev/day and eccentricity "
                                f"{model.ecco:g} put the perigee {perigee:.0f} km above the ground, below {MIN_PERIGEE_KM:g} km")


def _from_omm(rec, ts, field: str):
    from sgp4 import omm  # heavy: sgp4, only for _from_omm()
    from sgp4.api import Satrec  # heavy: sgp4, only for _from_omm()
    from skyfield.api import EarthSatellite  # heavy: skyfield, only for _from_omm()

    missing = [k for k in OMM_REQUIRED if rec.get(k) is None]
    if missing:
        raise FieldError(field, f"an OMM/GP record needs {', '.join(OMM_REQUIRED)}; missing {', '.join(missing)}")
    fields = {**OMM_DEFAULTS, **{k: v for k, v in rec.items() if v is not None}}
    epoch = start_datetime(str(fields["EPOCH"]), field=f"{field}.EPOCH")
    fields["EPOCH"] = epoch.strftime("%Y-%m-%dT%H:%M:%S.%f")  # the one form sgp4.omm parses
    fields["OBJECT_ID"] = str(fields["OBJECT_ID"])
    sat = Satrec()
    try:
        omm.initialize(sat, fields)
    except (TypeError, ValueError) as e:
        raise FieldError(field, f"not a valid OMM/GP record ({e})") from None
    return EarthSatellite.from_satrec(sat, ts), str(rec.get("OBJECT_NAME") or "")
