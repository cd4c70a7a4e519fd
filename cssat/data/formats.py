"""Readers for the light-curve files observers publish (issue 34, point 1).

Each reader returns the columns of :class:`~cssat.data.observations.ObservedLightCurve` as a
dict; :func:`~cssat.data.read_light_curve` picks one by ``format=`` or by the file's content:

- ``mmt``: Mini-MegaTORTORA (MMT-9, Karpov et al. 2015) track and whole-object exports: a
  ``# key: value`` header (``satellite: <NORAD> <NAME> / <country>``, ``variability: 0|1|2``,
  ``variability_period``, ``track``), the column names in the last ``#`` line (``Date Time
  StdMag Mag Filter Penumbra Distance Phase Channel [Track]``), whitespace-separated rows with
  the UTC date and time as two fields. ``Mag`` is apparent; ``StdMag`` is reduced to 1000 km
  and a phase angle of 90° (``value_col="StdMag"``).
- ``score``: the IAU CPS SatHub SCORE CSV: one row per report with its observer's site, RA/Dec,
  range, filter and object; a file of several objects needs ``object=`` (a NORAD id or name).
- ``alcdef``: the Asteroid Lightcurve Data Exchange Format (Warner et al. 2011):
  ``STARTMETADATA … ENDMETADATA`` blocks (one per session: a track) and ``DATA=JD|MAG|MAGERR``
  lines (UTC Julian dates; the block's ``MAGBAND``, ``DELIMITER``, object and observers).
- ``astropy``: an astropy ``Table``/``QTable``/``TimeSeries``, or an ECSV/FITS file read by
  astropy with its ``Time`` columns (any scale — ``TIMESYS`` honoured — converted to UTC by
  astropy) and units (a magnitude column must be in mag, a flux column in a spectral or
  bolometric flux unit).
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.scene.orbit import _start_datetime

__all__ = ["FORMATS", "sniff_format", "read_mmt", "read_score", "read_alcdef", "to_utc", "check_dates", "check_magnitudes"]

FORMATS = ("csv", "mmt", "score", "alcdef", "ecsv", "fits", "astropy")
TIME_SCALES = ("utc", "tt", "tdb", "tai")
MMT_VARIABILITY = {0: "nonvariable", 1: "aperiodic", 2: "periodic"}
MAG_RANGE = (-30.0, 30.0)  # apparent magnitudes of anything a telescope sees (the Sun is -26.7)


#: the dates a light curve may carry: the ephemeris and the survey era, with room (UTC)
DATE_RANGE = (np.datetime64("1900-01-01", "us"), np.datetime64("2100-01-01", "us"))
_NUMERIC_RANGE = {"jd": (2415020.5, 2488069.5), "mjd": (15020.0, 88069.0), "unix": (-2208988800.0, 4102444800.0)}


def to_utc(values: Any, fmt: str, scale: str, field: str) -> np.ndarray:
    """``(T,)`` ``datetime64[us]`` UTC of times in astropy's ``fmt`` (``jd``, ``mjd``, ``unix``,
    ``isot``…) and ``scale`` (``utc``, ``tt``, ``tdb``, ``tai``), converted by astropy; a number
    outside 1900–2100 (a JD of 0, a placeholder) is refused naming its row."""
    from astropy.time import Time  # heavy: astropy, only for to_utc()

    if fmt in _NUMERIC_RANGE:
        x = np.asarray(values, dtype=np.float64)
        lo, hi = _NUMERIC_RANGE[fmt]
        bad = np.flatnonzero(~((x >= lo) & (x <= hi)))
        if bad.size:
            i = int(bad[0])
            raise FieldError(f"{field}[row {i + 1}]", f"{float(x[i])!r} is not a {fmt} time between 1900 and 2100")
    try:
        return _datetime64(Time(values, format=fmt, scale=scale))
    except Exception as err:  # astropy's many kinds (ValueError, ScaleValueError, erfa warnings as errors)
        raise FieldError(field, f"not {fmt} times in {scale.upper()}: {' '.join(str(err).split())}") from None


def _datetime64(tm: Any) -> np.ndarray:
    """An astropy ``Time`` as UTC ``datetime64[us]`` (microseconds rounded, not truncated)."""
    utc = tm.utc
    days = (np.asarray(utc.jd1) - 2440587.5) + np.asarray(utc.jd2)  # astropy's own two-part JD, split exactly
    us = np.round(days * 86400e6).astype(np.int64)
    return np.asarray(us, dtype="datetime64[us]").reshape(-1)


def check_dates(times: np.ndarray, field: str, rows: np.ndarray | None = None) -> None:
    """Refuse a time stamp outside :data:`DATE_RANGE` (``rows``: each sample's file row)."""
    bad = np.flatnonzero(np.isnat(times) | (times < DATE_RANGE[0]) | (times > DATE_RANGE[1]))
    if bad.size:
        i = int(bad[0])
        row = int(rows[i]) + 1 if rows is not None else i + 1
        raise FieldError(f"{field}[row {row}]", f"{times[i]} is not a time between 1900 and 2100 (a placeholder?)")


def sniff_format(head: str, suffix: str) -> str:
    """The format of a file from its first kilobytes and its suffix."""
    s = suffix.lower()
    if s in ("fits", "fit", "fts"):
        return "fits"
    if s == "ecsv" or head.startswith("# %ECSV"):
        return "ecsv"
    first = head.lstrip("\ufeff").lstrip()
    if first.upper().startswith("STARTMETADATA"):
        return "alcdef"
    if re.search(r"^#\s*(satellite|track|variability)\s*:", head, re.M) or re.search(r"^#\s*Date\s+Time\s", head, re.M):
        return "mmt"
    header = next((ln for ln in head.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), "")
    cols = {c.strip().lower() for c in header.split(",")}
    if {"observation_time_utc", "apparent_magnitude"} <= cols:
        return "score"
    return "csv"


def _floats(tokens: list[str], where: str, name: str) -> np.ndarray:
    """Floats of ``tokens`` (vectorised), else a FieldError naming the first bad row."""
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        for i, v in enumerate(tokens):
            try:
                float(v)
            except ValueError:
                raise FieldError(f"{where}.{name}[row {i + 1}]", f"not a number: {v!r}") from None
        raise


def read_mmt(text: str, name: str, value_col: str | None = None) -> dict[str, Any]:
    """The columns of an MMT-9 export (the module's docstring)."""
    meta: dict[str, Any] = {}
    cols: list[str] = []
    rows: list[list[str]] = []
    for ln in text.splitlines():
        s = ln.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s.lstrip("#").strip()
            m = re.match(r"([A-Za-z_]+)\s*:\s*(.*)$", body)
            if m:
                meta[m.group(1).lower()] = m.group(2).strip()
            elif body:
                cols = body.split()
            continue
        rows.append(s.split())
    if not cols or cols[:2] != ["Date", "Time"]:
        raise FieldError("observations", f"{name}: an MMT file names its columns in a '# Date Time ...' comment line; "
                                         f"found {' '.join(cols) or 'none'}")
    if not rows:
        raise FieldError("observations", f"{name}: an MMT header and no data rows")
    bad = next((i for i, r in enumerate(rows) if len(r) != len(cols)), None)
    if bad is not None:
        raise FieldError(f"observations[row {bad + 1}]", f"{len(rows[bad])} fields, the header names {len(cols)}: "
                                                         f"{' '.join(cols)}")
    col = {c: [r[j] for r in rows] for j, c in enumerate(cols)}
    stamps = [f"{d}T{t}" for d, t in zip(col["Date"], col["Time"])]
    try:
        times = np.array(stamps, dtype="datetime64[us]")
    except ValueError:
        times = None
    if times is None or np.isnat(times).any():
        i = next((k for k, v in enumerate(stamps) if _bad_iso(v)), 0)
        raise FieldError(f"observations.Time[row {i + 1}]", f"not a UTC date and time: {stamps[i]!r}")
    vcol = value_col or "Mag"
    if vcol not in col:
        raise FieldError("observations.value_col", f"{name} has no column {vcol!r}; its columns: {', '.join(cols)}")
    out: dict[str, Any] = {"times_utc": times, "values": _floats(col[vcol], "observations", vcol), "errors": None,
                           "kind": "magnitude"}
    out["magnitude_system"] = "normalised: 1000 km, phase 90°" if vcol == "StdMag" else "apparent"
    info_col = vcol
    if "Filter" in col:
        out["filters"] = np.array(col["Filter"])
    for key, c, lo, hi, open_lo in (("ranges_km", "Distance", 0.0, 1e7, True), ("phase_deg", "Phase", 0.0, 180.0, False)):
        if c in col:
            out[key] = _checked(_floats(col[c], "observations", c), f"observations.{c}", lo, hi, open_lo=open_lo)
    if "Channel" in col:
        out["channels"] = np.array(col["Channel"])
    if "Track" in col:
        out["tracks"] = np.array(col["Track"])
    elif meta.get("track", "").split():
        out["tracks"] = np.full(len(rows), meta["track"].split()[0])
    if "Penumbra" in col:
        out["penumbra"] = np.array([v not in ("0", "0.0") for v in col["Penumbra"]])
    info: dict[str, Any] = {"format": "mmt", "value_col": info_col}
    sat = meta.get("satellite", "")
    m = re.match(r"(\d+)\s+(.*?)(?:\s+/\s+(.*))?$", sat)
    if m:
        info.update(object_id=m.group(1), name=m.group(2).strip(), country=(m.group(3) or "").strip() or None)
    if meta.get("variability", "").split():
        code = meta["variability"].split()[0]
        info["variability"] = MMT_VARIABILITY.get(int(code), meta["variability"]) if code.isdigit() else meta["variability"]
    per = meta.get("variability_period", meta.get("period"))
    if per not in (None, "", "None", "none"):
        info["published_period_s"] = _period(per.split()[0] if per.split() else per, "observations.variability_period")
    info["header"] = meta
    out["meta"] = info
    return out


def _period(value: Any, field: str) -> float:
    """A published period in seconds: a finite number > 0."""
    try:
        p = float(value)
    except (TypeError, ValueError):
        raise FieldError(field, f"not a period in seconds: {value!r}") from None
    if not (math.isfinite(p) and p > 0):
        raise FieldError(field, f"a period must be a finite number of seconds > 0, got {value!r}")
    return p


def _checked(x: np.ndarray, field: str, lo: float, hi: float, *, open_lo: bool = False) -> np.ndarray:
    """``x`` when every value is finite and in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``), else a
    FieldError naming the row."""
    ok = np.isfinite(x) & ((x > lo) if open_lo else (x >= lo)) & (x <= hi)
    bad = np.flatnonzero(~ok)
    if bad.size:
        i = int(bad[0])
        raise FieldError(f"{field}[row {i + 1}]", f"{float(x[i])!r} is outside {'(' if open_lo else '['}{lo:g}, {hi:g}]")
    return x


def _bad_iso(v: str) -> bool:
    try:
        return bool(np.isnat(np.datetime64(v, "us")))
    except ValueError:
        return True


SCORE_COLUMNS = {"time": "observation_time_utc", "value": "apparent_magnitude", "error": "apparent_magnitude_uncertainty",
                 "lat": "observer_latitude_deg", "lon": "observer_longitude_deg", "alt": "observer_altitude_m",
                 "ra": "satellite_right_ascension_deg", "dec": "satellite_declination_deg",
                 "range": "range_to_satellite_km", "filter": "observing_filter", "norad": "norad_cat_id",
                 "name": "satellite_name"}


def read_score(header: list[str], rows: list[list[str]], name: str, obj: Any = None) -> dict[str, Any]:
    """The columns of a SCORE CSV (``header``, ``rows`` as the CSV reader split them). A row
    shorter than the header has its missing trailing fields empty (SCORE's optional columns)."""
    h = [c.strip() for c in header]
    if not rows:
        raise FieldError("observations", f"{name}: a SCORE header and no data rows")
    idx = {c: h.index(c) for c in h}
    for key in ("time", "value", "norad"):
        if SCORE_COLUMNS[key] not in idx:
            raise FieldError("observations", f"{name}: a SCORE file needs the column {SCORE_COLUMNS[key]!r}")
    long_ = next((i for i, r in enumerate(rows) if len(r) > len(h)), None)
    if long_ is not None:
        raise FieldError(f"observations[row {long_ + 1}]", f"{len(rows[long_])} fields, the header has {len(h)}")
    rows = [r + [""] * (len(h) - len(r)) for r in rows]

    def get(key: str) -> list[str]:
        c = SCORE_COLUMNS[key]
        return [r[idx[c]].strip() for r in rows] if c in idx else [""] * len(rows)

    norad, names = get("norad"), get("name")
    objects = sorted(set(zip(norad, names)))
    if obj is not None:
        want = str(obj).strip().upper()
        keep = [i for i in range(len(rows)) if norad[i] == want or names[i].upper() == want]
        if not keep:
            raise FieldError("observations.object", f"{want!r} is not in {name}; its objects: "
                                                   + ", ".join(f"{n} {s}" for n, s in objects))
        rows = [rows[i] for i in keep]
        norad, names = get("norad"), get("name")
    elif len({n for n, _ in objects}) > 1:
        raise FieldError("observations.object", f"{name} holds {len({n for n, _ in objects})} objects; choose one "
                                               "(NORAD id or name): " + ", ".join(f"{n} {s}" for n, s in objects))
    stamps = get("time")

    times = np.array([np.datetime64(_start_datetime(s, f"observations.{SCORE_COLUMNS['time']}[row {i + 1}]"), "us")
                      for i, s in enumerate(stamps)], dtype="datetime64[us]")

    def numbers(key: str, required: bool = False) -> np.ndarray | None:
        raw = get(key)
        if not required and all(v in ("", "None", "none", "null") for v in raw):
            return None
        vals = [v if v not in ("", "None", "none", "null") else "nan" for v in raw]
        return _floats(vals, "observations", SCORE_COLUMNS[key])

    out: dict[str, Any] = {"times_utc": times, "values": numbers("value", True), "kind": "magnitude",
                           "magnitude_system": "apparent"}
    err = numbers("error")
    out["errors"] = err
    lat, lon, alt = numbers("lat"), numbers("lon"), numbers("alt")
    for v, key, lo, hi in ((lat, "lat", -90.0, 90.0), (lon, "lon", -360.0, 360.0), (alt, "alt", -1000.0, 1e5)):
        if v is not None:
            _checked(v, f"observations.{SCORE_COLUMNS[key]}", lo, hi)
    if lat is not None and lon is not None:
        out["sites"] = np.stack([lat, lon, np.zeros_like(lat) if alt is None else alt], 1)
    for key, col in (("ra_deg", "ra"), ("dec_deg", "dec"), ("ranges_km", "range")):
        v = numbers(col)
        if v is not None:
            out[key] = v
    if "ranges_km" in out and np.isfinite(out["ranges_km"]).all():
        _checked(out["ranges_km"], f"observations.{SCORE_COLUMNS['range']}", 0.0, 1e7, open_lo=True)
    f = get("filter")
    if any(f):
        out["filters"] = np.array(f)
    out["meta"] = {"format": "score", "object_id": norad[0], "name": names[0], "value_col": SCORE_COLUMNS["value"],
                   "error_col": SCORE_COLUMNS["error"]}
    return out


def read_alcdef(text: str, name: str) -> dict[str, Any]:
    """The columns of an ALCDEF file: each ``STARTMETADATA`` block a track."""
    times: list[float] = []
    mags: list[float] = []
    errs: list[float] = []
    tracks: list[str] = []
    filters: list[str] = []
    blocks: list[dict[str, str]] = []
    meta: dict[str, str] = {}
    in_meta = False
    for n, ln in enumerate(text.splitlines(), 1):
        s = ln.strip()
        if not s:
            continue
        key, _, val = s.partition("=")
        key = key.strip().upper()
        if key == "STARTMETADATA":
            if in_meta:
                raise FieldError(f"observations[line {n}]", "STARTMETADATA inside a metadata block (its ENDMETADATA is missing)")
            meta, in_meta = {}, True
        elif key == "ENDMETADATA":
            in_meta = False
            blocks.append(meta)
        elif in_meta:
            meta.setdefault(key, val.strip())
        elif key == "DATA":
            sep = {"PIPE": "|", "TAB": "\t", "COMMA": ","}.get(meta.get("DELIMITER", "PIPE").upper(), "|")
            f = val.split(sep)
            try:
                vals = (float(f[0]), float(f[1]), float(f[2]) if len(f) > 2 and f[2].strip() else math.nan)
                if not (math.isfinite(vals[0]) and math.isfinite(vals[1])):
                    raise ValueError
                times.append(vals[0])
                mags.append(vals[1])
                errs.append(vals[2])
            except (ValueError, IndexError):
                raise FieldError(f"observations[line {n}]", f"not an ALCDEF data line JD{sep}MAG{sep}MAGERR: {s!r}") from None
            tracks.append(meta.get("LCBLOCKID", str(len(blocks))))
            filters.append(meta.get("MAGBAND", ""))
        elif key not in ("ENDDATA",):
            raise FieldError(f"observations[line {n}]", f"not ALCDEF: {s[:60]!r} outside a metadata block")
    if in_meta:
        raise FieldError("observations", f"{name}: a metadata block without its ENDMETADATA")
    if not times:
        raise FieldError("observations", f"{name}: an ALCDEF file without DATA lines")
    e = np.array(errs)
    if np.isnan(e).any() and not np.isnan(e).all():
        i = int(np.flatnonzero(np.isnan(e))[0])
        raise FieldError(f"observations.MAGERR[row {i + 1}]", "a missing error where the other rows give theirs")
    first = blocks[0] if blocks else {}
    info = {"format": "alcdef", "value_col": "MAG", "error_col": "MAGERR", "object_id": first.get("OBJECTNUMBER") or first.get("MPCDESIG") or None,
            "name": first.get("OBJECTNAME") or None, "observers": sorted({b.get("OBSERVERS", "") for b in blocks} - {""}),
            "blocks": blocks}
    reduced = first.get("REDUCEDMAGS", "NONE").upper()
    return {"times_utc": to_utc(np.array(times), "jd", "utc", "observations.JD"), "values": np.array(mags),
            "errors": None if np.isnan(e).any() else e, "kind": "magnitude", "tracks": np.array(tracks),
            "filters": np.array(filters), "magnitude_system": "apparent" if reduced == "NONE" else f"reduced ({reduced})",
            "meta": info}


def check_magnitudes(values: np.ndarray, col: str) -> None:
    """Refuse magnitudes no telescope records (placeholders like 99.999 or -1000; a flux read
    as a magnitude)."""
    bad = np.flatnonzero((values < MAG_RANGE[0]) | (values > MAG_RANGE[1]))
    if bad.size:
        i = int(bad[0])
        raise FieldError(f"observations.{col}[row {i + 1}]", f"{float(values[i])!r} is not a magnitude (allowed {MAG_RANGE[0]:g} "
                         f"to {MAG_RANGE[1]:g}): a placeholder for a missing value? Drop the row, or read a flux "
                         "column with kind='flux'")
