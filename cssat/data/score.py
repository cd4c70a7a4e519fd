"""The IAU CPS SatHub SCORE reader: one row per report with its observer's
site, RA/Dec, range, filter and object, the upload format and the database export (which adds
SatChecker's computed columns, ``range_to_sat_km_satchecker``, ``phase_angle_deg_satchecker``…).

A placeholder is "unknown", not an error: an empty field, ``None``/``null``, and a ``0`` where
no real value is 0 (a range, an uncertainty). Where the observer's range is unknown the
SatChecker range of the same row is used; ``meta["range_source"]`` says which: ``"observer"``,
``"satchecker"`` or ``"mixed"`` (then ``meta["range_satchecker_rows"]``: the file's data rows,
from 1, that use SatChecker's). The phase angle is SatChecker's (the upload format has none):
``meta["phase_source"] = "satchecker"``. A negative range, or a row with neither range where
others have one, is a FieldError naming the column and the row.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.formats import _checked
from cssat.data.registry import read_text, register_format
from cssat.data.text import _is_number, text_rows
from cssat.scene.orbit import start_datetime

__all__ = ["read_score", "identify_score", "SCORE_COLUMNS", "SATCHECKER_COLUMNS", "SCORE_FIXED_OPTIONS"]

SCORE_COLUMNS = {"time": "observation_time_utc", "value": "apparent_magnitude", "error": "apparent_magnitude_uncertainty",
                 "lat": "observer_latitude_deg", "lon": "observer_longitude_deg", "alt": "observer_altitude_m",
                 "ra": "satellite_right_ascension_deg", "dec": "satellite_declination_deg",
                 "range": "range_to_satellite_km", "filter": "observing_filter", "norad": "norad_cat_id",
                 "name": "satellite_name"}
#: SatChecker's computed columns in a SCORE database export (the first present is used)
SATCHECKER_COLUMNS = {"range": ("range_to_sat_km_satchecker",), "phase": ("phase_angle_deg_satchecker", "phase_angle")}
#: the reading options a SCORE file accepts (``None``: unset); any other value contradicts it
SCORE_FIXED_OPTIONS = {"kind": ("magnitude",), "time_col": (None, "time_utc", SCORE_COLUMNS["time"]),
                       "value_col": (None, SCORE_COLUMNS["value"]), "error_col": (None, SCORE_COLUMNS["error"]),
                       "time_format": ("iso",), "time_scale": ("utc",)}
#: fields that stand for "no value"
MISSING = ("", "none", "null", "nan", "n/a", "na")


def read_score(header: list[str], rows: list[list[str]], name: str, obj: Any = None) -> dict[str, Any]:
    """The columns of a SCORE CSV (``header``, ``rows`` as the CSV reader split them): ``times_utc
    (T,)``, ``values (T,)`` apparent magnitudes, ``errors (T,)`` (None when a row has none — an
    empty or 0 uncertainty), ``sites (T, 3)`` (°, °, m), ``ra_deg``, ``dec_deg``, ``ranges_km``
    (km; the module's docstring), ``phase_deg`` (°), ``filters``, ``meta``. A row shorter than
    the header has its missing trailing fields empty (SCORE's optional columns)."""
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
    file_row = np.arange(len(rows))  # each kept row's data row in the file (from 0)

    def raw(c: str) -> list[str]:
        return [rows[i][idx[c]].strip() for i in range(len(rows))] if c in idx else [""] * len(rows)

    def get(key: str) -> list[str]:
        return raw(SCORE_COLUMNS[key])

    norad, names = get("norad"), get("name")
    objects = sorted(set(zip(norad, names)))
    if obj is not None:
        want = str(obj).strip().upper()
        keep = [i for i in range(len(rows)) if norad[i] == want or names[i].upper() == want]
        if not keep:
            raise FieldError("observations.object", f"{want!r} is not in {name}; its objects: "
                                                   + ", ".join(f"{n} {s}" for n, s in objects))
        rows, file_row = [rows[i] for i in keep], file_row[keep]
        norad, names = get("norad"), get("name")
    elif len({n for n, _ in objects}) > 1:
        raise FieldError("observations.object", f"{name} holds {len({n for n, _ in objects})} objects; choose one "
                                               "(NORAD id or name): " + ", ".join(f"{n} {s}" for n, s in objects))

    def where(c: str, i: int) -> str:
        return f"observations.{c}[row {file_row[i] + 1}]"

    times = np.array([np.datetime64(start_datetime(s, where(SCORE_COLUMNS["time"], i)), "us")
                      for i, s in enumerate(get("time"))], dtype="datetime64[us]")

    def numbers(c: str, required: bool = False) -> np.ndarray | None:
        """Floats of column ``c`` with NaN for a missing field; None when every field is missing."""
        vals = raw(c)
        if not required and all(v.lower() in MISSING for v in vals):
            return None
        vals = ["nan" if v.lower() in MISSING else v for v in vals]
        try:
            x = np.array(vals, dtype=np.float64)
        except ValueError:
            i = next(i for i, v in enumerate(vals) if not _is_number(v))
            raise FieldError(where(c, i), f"not a number: {vals[i]!r}") from None
        if required and not np.isfinite(x).all():
            raise FieldError(where(c, int(np.flatnonzero(~np.isfinite(x))[0])), "no value (an empty field): drop the row")
        return x

    out: dict[str, Any] = {"times_utc": times, "values": numbers(SCORE_COLUMNS["value"], True), "kind": "magnitude",
                           "magnitude_system": "apparent"}
    meta: dict[str, Any] = {"format": "score", "object_id": norad[0], "name": names[0],
                            "value_col": SCORE_COLUMNS["value"], "error_col": SCORE_COLUMNS["error"]}
    err = numbers(SCORE_COLUMNS["error"])
    if err is not None:
        unknown = ~np.isfinite(err) | (err == 0)
        if unknown.any():  # a placeholder 0 or an empty field: no uncertainty for the curve
            meta["errors_note"] = (f"{SCORE_COLUMNS['error']} is empty or 0 (unknown) in {int(unknown.sum())} of "
                                   f"{len(err)} rows: no uncertainties used")
            err = None
    out["errors"] = err
    lat, lon, alt = (numbers(SCORE_COLUMNS[k]) for k in ("lat", "lon", "alt"))
    for v, key, lo, hi in ((lat, "lat", -90.0, 90.0), (lon, "lon", -360.0, 360.0), (alt, "alt", -1000.0, 1e5)):
        if v is not None:
            bad = np.flatnonzero(~np.isfinite(v))
            if bad.size and key != "alt":
                raise FieldError(where(SCORE_COLUMNS[key], int(bad[0])), "no observer position (an empty field) where "
                                 "other rows give theirs: drop the row or give its site")
            _checked(np.nan_to_num(v), f"observations.{SCORE_COLUMNS[key]}", lo, hi)
    if lat is not None and lon is not None:
        out["sites"] = np.stack([lat, lon, np.zeros_like(lat) if alt is None else np.nan_to_num(alt)], 1)
    for key, c in (("ra_deg", "ra"), ("dec_deg", "dec")):
        v = numbers(SCORE_COLUMNS[c])
        if v is not None and np.isfinite(v).all():
            out[key] = v
    _ranges(out, meta, numbers(SCORE_COLUMNS["range"]), _first(idx, "range", numbers), where, file_row)
    pc = next((c for c in SATCHECKER_COLUMNS["phase"] if c in idx), None)
    phase = numbers(pc) if pc else None
    if phase is not None and np.isfinite(phase).all():
        out["phase_deg"] = _checked(phase, f"observations.{pc}", 0.0, 180.0)
        meta["phase_source"] = "satchecker"
    f = get("filter")
    if any(f):
        out["filters"] = np.array(f)
    disc = [int(file_row[i]) + 1 for i, v in enumerate(raw("potentially_discrepant")) if v.lower() == "true"]
    if disc:
        meta["potentially_discrepant_rows"] = disc
    out["meta"] = meta
    return out


def _first(idx: dict[str, int], key: str, numbers: Any) -> tuple[str, np.ndarray | None] | None:
    """``(column, values)`` of the first SatChecker column for ``key`` in the file, else None."""
    c = next((c for c in SATCHECKER_COLUMNS[key] if c in idx), None)
    return None if c is None else (c, numbers(c))


def _ranges(out: dict[str, Any], meta: dict[str, Any], obs: np.ndarray | None, sc: tuple[str, Any] | None,
            where: Any, file_row: np.ndarray) -> None:
    """``out["ranges_km"]`` (km) from the observer's range, SatChecker's where the observer's is
    unknown (empty or 0); ``meta["range_source"]`` (and ``range_satchecker_rows`` when mixed)."""
    rc = SCORE_COLUMNS["range"]
    n = len(out["times_utc"])
    if obs is not None:
        neg = np.flatnonzero(obs < 0)
        if neg.size:
            raise FieldError(where(rc, int(neg[0])), f"a range must be > 0 km (0 or empty: none measured), got "
                                                     f"{float(obs[neg[0]])!r}")
    have = np.zeros(n, bool) if obs is None else (np.isfinite(obs) & (obs > 0))
    rng = np.where(have, obs if obs is not None else 0.0, np.nan)
    used_sc = np.zeros(n, bool)
    if sc is not None and sc[1] is not None:
        scol, sv = sc
        fill = ~have & np.isfinite(sv)
        bad = np.flatnonzero(fill & ~(sv > 0))
        if bad.size:
            raise FieldError(where(scol, int(bad[0])), f"a range must be > 0 km, got {float(sv[bad[0]])!r}")
        rng[fill], used_sc = sv[fill], fill
    if not np.isfinite(rng).any():
        return  # no range anywhere: none
    miss = np.flatnonzero(~np.isfinite(rng))
    if miss.size:
        raise FieldError(where(rc, int(miss[0])), "no range (empty or 0) and no SatChecker range "
                         f"({', '.join(SATCHECKER_COLUMNS['range'])}) in this row, where other rows give one: drop the row")
    out["ranges_km"] = _checked(rng, f"observations.{rc}", 0.0, 1e7, open_lo=True)
    meta["range_source"] = "satchecker" if used_sc.all() else ("observer" if not used_sc.any() else "mixed")
    if meta["range_source"] == "mixed":
        meta["range_satchecker_rows"] = [int(file_row[i]) + 1 for i in np.flatnonzero(used_sc)]


def identify_score(path: Any, first_lines: list[str]) -> bool:
    """A SCORE CSV's header (its first line that is not blank or a ``#`` comment) names
    ``observation_time_utc`` and ``apparent_magnitude``."""
    header = next((ln for ln in "".join(first_lines).splitlines() if ln.strip() and not ln.lstrip().startswith("#")), "")
    return {SCORE_COLUMNS["time"], SCORE_COLUMNS["value"]} <= {c.strip().lower() for c in header.split(",")}


def _read(path: Any, *, object: Any = None, **options: Any) -> dict[str, Any]:
    name = Path(path).name
    header, rows = text_rows(read_text(path), name)
    return read_score(header, rows, name, object)


register_format("score", identify_score, _read, priority=20, fixed_options=SCORE_FIXED_OPTIONS, sort=True,
                selects_object=True, overwrite=True)
