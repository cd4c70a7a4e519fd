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
from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError

__all__ = ["FORMATS", "sniff_format", "read_mmt", "read_score", "read_alcdef", "read_astropy", "to_utc"]

FORMATS = ("csv", "mmt", "score", "alcdef", "ecsv", "fits", "astropy")
TIME_SCALES = ("utc", "tt", "tdb", "tai")
MMT_VARIABILITY = {0: "nonvariable", 1: "aperiodic", 2: "periodic"}
MAG_RANGE = (-30.0, 30.0)  # apparent magnitudes of anything a telescope sees (the Sun is -26.7)


def to_utc(values: Any, fmt: str, scale: str, field: str) -> np.ndarray:
    """``(T,)`` ``datetime64[us]`` UTC of times in astropy's ``fmt`` (``jd``, ``mjd``, ``unix``,
    ``isot``…) and ``scale`` (``utc``, ``tt``, ``tdb``, ``tai``), converted by astropy."""
    from astropy.time import Time

    try:
        tm = Time(values, format=fmt, scale=scale)
        return _datetime64(tm)
    except (ValueError, TypeError) as err:
        raise FieldError(field, f"not {fmt} times in {scale.upper()}: {err}") from None


def _datetime64(tm: Any) -> np.ndarray:
    """An astropy ``Time`` as UTC ``datetime64[us]`` (microseconds rounded, not truncated)."""
    jd1, jd2 = tm.utc.jd1, tm.utc.jd2
    days = (np.asarray(jd1) - 2440587.5) + np.asarray(jd2)  # astropy's own two-part JD, split exactly
    us = np.round(days * 86400e6).astype(np.int64)
    return np.asarray(us, dtype="datetime64[us]").reshape(-1)


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
    for key, c in (("ranges_km", "Distance"), ("phase_deg", "Phase")):
        if c in col:
            out[key] = _floats(col[c], "observations", c)
    if "Channel" in col:
        out["channels"] = np.array(col["Channel"])
    if "Track" in col:
        out["tracks"] = np.array(col["Track"])
    elif "track" in meta:
        out["tracks"] = np.full(len(rows), meta["track"].split()[0])
    if "Penumbra" in col:
        out["penumbra"] = np.array([v not in ("0", "0.0") for v in col["Penumbra"]])
    info: dict[str, Any] = {"format": "mmt", "value_col": info_col}
    sat = meta.get("satellite", "")
    m = re.match(r"(\d+)\s+(.*?)(?:\s+/\s+(.*))?$", sat)
    if m:
        info.update(object_id=m.group(1), name=m.group(2).strip(), country=(m.group(3) or "").strip() or None)
    if "variability" in meta:
        code = meta["variability"].split()[0]
        info["variability"] = MMT_VARIABILITY.get(int(code), meta["variability"]) if code.isdigit() else meta["variability"]
    per = meta.get("variability_period", meta.get("period"))
    if per not in (None, "", "None", "none"):
        try:
            info["published_period_s"] = float(per.split()[0])
        except ValueError:
            raise FieldError("observations.variability_period", f"not a period in seconds: {per!r}") from None
    info["header"] = meta
    out["meta"] = info
    return out


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
    from cssat.scene.orbit import _start_datetime

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
    if lat is not None and lon is not None:
        out["sites"] = np.stack([lat, lon, np.zeros_like(lat) if alt is None else alt], 1)
    for key, col in (("ra_deg", "ra"), ("dec_deg", "dec"), ("ranges_km", "range")):
        v = numbers(col)
        if v is not None:
            out[key] = v
    f = get("filter")
    if any(f):
        out["filters"] = np.array(f)
    out["meta"] = {"format": "score", "object_id": norad[0], "name": names[0], "value_col": SCORE_COLUMNS["value"]}
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
                times.append(float(f[0]))
                mags.append(float(f[1]))
                errs.append(float(f[2]) if len(f) > 2 and f[2].strip() else math.nan)
            except (ValueError, IndexError):
                raise FieldError(f"observations[line {n}]", f"not an ALCDEF data line JD{sep}MAG{sep}MAGERR: {s!r}") from None
            tracks.append(meta.get("LCBLOCKID", str(len(blocks))))
            filters.append(meta.get("MAGBAND", ""))
        elif key not in ("ENDDATA",):
            raise FieldError(f"observations[line {n}]", f"not ALCDEF: {s[:60]!r} outside a metadata block")
    if not times:
        raise FieldError("observations", f"{name}: an ALCDEF file without DATA lines")
    e = np.array(errs)
    first = blocks[0] if blocks else {}
    info = {"format": "alcdef", "value_col": "MAG", "object_id": first.get("OBJECTNUMBER") or first.get("MPCDESIG") or None,
            "name": first.get("OBJECTNAME") or None, "observers": sorted({b.get("OBSERVERS", "") for b in blocks} - {""}),
            "blocks": blocks}
    reduced = first.get("REDUCEDMAGS", "NONE").upper()
    return {"times_utc": to_utc(np.array(times), "jd", "utc", "observations.JD"), "values": np.array(mags),
            "errors": None if np.isnan(e).any() else e, "kind": "magnitude", "tracks": np.array(tracks),
            "filters": np.array(filters), "magnitude_system": "apparent" if reduced == "NONE" else f"reduced ({reduced})",
            "meta": info}


def read_astropy(table: Any, name: str, *, time_col: str | None, value_col: str | None, error_col: str | None,
                 kind: str) -> dict[str, Any]:
    """The columns of an astropy table: its time column (a ``Time`` column in any scale, made
    UTC by astropy; or cssat's ISO ``time_utc``), its value column checked against its unit."""
    from astropy import units as u
    from astropy.time import Time

    cols = list(table.colnames)
    if time_col is None:
        tcols = [c for c in cols if isinstance(table[c], Time)]
        time_col = tcols[0] if tcols else ("time_utc" if "time_utc" in cols else ("time" if "time" in cols else None))
    if time_col not in cols:
        raise FieldError("observations.time_col", f"{name} has no time column {time_col!r}; its columns: {', '.join(cols)}")
    tc = table[time_col]
    if isinstance(tc, Time):
        times = _datetime64(tc)
    else:
        from cssat.scene.orbit import _start_datetime

        times = np.array([np.datetime64(_start_datetime(str(v).strip(), f"observations.{time_col}[row {i + 1}]"), "us")
                          for i, v in enumerate(tc)], dtype="datetime64[us]")
    from cssat.data.observations import DEFAULT_ERROR, DEFAULT_VALUE

    value_col = value_col or next((c for c in (DEFAULT_VALUE[kind], "mag", "magnitude", "flux") if c in cols), None)
    if value_col not in cols:
        raise FieldError("observations.value_col", f"{name} has no column {value_col!r}; its columns: {', '.join(cols)}")
    if error_col is None:
        error_col = next((c for c in (DEFAULT_ERROR[kind], f"{value_col}_err", "mag_err", "flux_err") if c in cols), None)

    def values(c: str) -> np.ndarray:
        col = table[c]
        unit = getattr(col, "unit", None)
        if unit is not None and unit != u.dimensionless_unscaled:
            is_mag = unit.physical_type == "dimensionless" or "mag" in str(unit)
            if kind == "magnitude" and not is_mag:
                raise FieldError(f"observations.{c}", f"the unit {unit} is not a magnitude (kind='magnitude'); "
                                                       "read it with kind='flux'")
            if kind == "flux" and is_mag:
                raise FieldError(f"observations.{c}", f"the unit {unit} is a magnitude (kind='flux'); read it with "
                                                       "kind='magnitude'")
            if kind == "flux":
                try:
                    return np.asarray(u.Quantity(col).to_value(u.W / u.m ** 2), dtype=np.float64)
                except u.UnitConversionError:
                    pass  # a spectral flux density: kept in the file's unit
        return np.asarray(getattr(col, "value", col), dtype=np.float64).reshape(-1)

    out = {"times_utc": times, "values": values(value_col), "errors": values(error_col) if error_col else None,
           "kind": kind, "magnitude_system": "apparent"}
    for key, c in (("filters", "filter"), ("observers", "observer"), ("tracks", "track")):
        if c in cols:
            out[key] = np.array([str(v).strip() for v in table[c]])
    meta = {str(k).lower(): v for k, v in dict(table.meta or {}).items() if isinstance(v, (str, int, float))}
    obj = meta.get("norad") or meta.get("object_id") or meta.get("norad_cat_id")
    out["meta"] = {"format": "astropy", "value_col": value_col, "object_id": None if obj is None else str(obj),
                   "name": meta.get("object") or meta.get("name"), "header": meta}
    if "period" in meta or "period_s" in meta:
        out["meta"]["published_period_s"] = float(meta.get("period_s", meta.get("period")))
    return out


def read_astropy_file(data: bytes, fmt: str, name: str) -> Any:
    """An ECSV or FITS file's bytes as an astropy Table (FITS time columns as ``Time``)."""
    import io

    from astropy.table import Table

    try:
        if fmt == "ecsv":
            return Table.read(data.decode("utf-8"), format="ascii.ecsv")
        return Table.read(io.BytesIO(data), format="fits", astropy_native=True)
    except Exception as err:  # astropy raises many kinds on a malformed file
        raise FieldError("observations", f"{name}: not a readable {fmt.upper()} table ({err})") from None


def check_magnitudes(values: np.ndarray, col: str) -> None:
    """Refuse magnitudes no telescope records (placeholders like 99.999 or -1000; a flux read
    as a magnitude)."""
    bad = np.flatnonzero((values < MAG_RANGE[0]) | (values > MAG_RANGE[1]))
    if bad.size:
        i = int(bad[0])
        raise FieldError(f"observations.{col}[row {i + 1}]", f"{float(values[i])!r} is not a magnitude (allowed {MAG_RANGE[0]:g} "
                         f"to {MAG_RANGE[1]:g}): a placeholder for a missing value? Drop the row, or read a flux "
                         "column with kind='flux'")
