"""Text tables of light curves: cssat's CSV and any comma- or whitespace-separated table:
the header in the first line or in the last ``#`` line, time from one or two
columns in any astropy time format and scale, values checked row by row; and the size check
before any file is read."""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from cssat._checks import FieldError
from cssat._tmpfiles import atomic_csv
from cssat.data.formats import check_kind, to_utc
from cssat.data.registry import read_text, register_format
from cssat.scene.orbit import start_datetime

__all__ = ["check_size", "read_csv", "text_rows", "write_light_curve", "find_column", "DEFAULT_VALUE", "DEFAULT_ERROR"]

#: the value column of cssat's own ``lightcurve.csv`` by kind, and the error column it may carry
DEFAULT_VALUE = {"magnitude": "magnitude", "flux": "flux_W_m2"}
DEFAULT_ERROR = {"magnitude": "magnitude_err", "flux": "flux_W_m2_err"}
#: the columns recognised when none is named, in order (case-insensitive): time, value by kind, error by kind
TIME_NAMES = ("time_utc", "time", "mjd", "jd")
VALUE_NAMES = {"magnitude": ("magnitude", "mag"), "flux": ("flux_W_m2", "flux")}
ERROR_NAMES = {"magnitude": ("magnitude_err", "mag_err", "magerr", "err"), "flux": ("flux_W_m2_err", "flux_err", "err")}


def find_column(cols: Sequence[str], names: Sequence[str]) -> str | None:
    """The first of ``names`` among ``cols`` (case-insensitive), as ``cols`` spells it; else None."""
    lower = {c.lower(): c for c in reversed(list(cols))}
    return next((lower[n.lower()] for n in names if n.lower() in lower), None)


#: the bytes of memory a text table's byte may take once parsed (rows of Python strings, then arrays)
BYTES_PER_BYTE = 40


def check_size(p: Path) -> None:
    """Refuse a file whose parsed table would not fit in the memory available now."""
    size = p.stat().st_size
    try:
        avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # not Linux: the 1 GiB cap alone
        avail = 1 << 62
    need = size * BYTES_PER_BYTE
    if size > (1 << 30) or need > avail // 2:
        raise FieldError("observations", f"{p.name} is {size / 2**20:.0f} MiB: reading it needs about "
                                         f"{need / 2**30:.1f} GiB, {avail / 2**30:.1f} GiB are free; split it "
                                         "(by track or night) and read the parts")


def text_rows(text: str, name: str) -> tuple[list[str], list[list[str]]]:
    """``(header, rows)`` of a comma- or whitespace-separated table; the header is the first
    non-comment line, or the last comment line when the first line is data (MMT-like)."""
    lines = text.splitlines(keepends=True)
    k = 0
    while k < len(lines) and (not lines[k].strip() or lines[k].lstrip().startswith("#")):
        k += 1
    comments = [ln.strip() for ln in lines[:k] if ln.strip()]
    if k == len(lines):
        raise FieldError("observations", f"{name}: no header row and no data")
    comma = "," in lines[k]
    try:
        if comma:  # the csv module over the text itself: a quoted field may hold a line end
            rows = [r for r in csv.reader(io.StringIO("".join(lines[k:])))
                    if r and any(v.strip() for v in r) and not r[0].lstrip().startswith("#")]
        else:
            rows = [ln.split() for ln in lines[k:] if ln.strip() and not ln.lstrip().startswith("#")]
    except csv.Error as err:
        raise FieldError("observations", f"{name}: not a readable CSV ({err})") from None
    first = rows[0]
    # a data line has a number or a date in it (a column name does not start with a digit)
    looks_data = any(_is_number(v) or v.strip()[:1].isdigit() for v in first if v.strip())
    if looks_data and comments:
        head = comments[-1].lstrip().lstrip("#").strip()
        header = next(csv.reader([head])) if comma else head.split()
        if comma and len(header) == 1 and len(head.split()) == len(first):  # '# jd mag err' over comma-separated rows
            header = head.split()
    else:
        header, rows = first, rows[1:]
    header = [c.strip() for c in header]
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup:
        raise FieldError("observations", f"{name}: the header names {', '.join(map(repr, dup))} more than once")
    return header, rows


def _is_number(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


def _times(raw: Sequence[Any], col: str, time_format: str, time_scale: str) -> np.ndarray:
    if time_format == "iso":
        out = np.array([np.datetime64(start_datetime((v.decode() if isinstance(v, bytes) else str(v)).strip(),
                                                      f"observations.{col}[row {i + 1}]"), "us")
                        for i, v in enumerate(raw)], dtype="datetime64[us]")
        if time_scale == "utc":
            return out
        return to_utc(np.datetime_as_string(out), "isot", time_scale, f"observations.{col}")
    x = _numbers(raw, col)
    return to_utc(x, {"jd": "jd", "mjd": "mjd", "unix": "unix"}[time_format], time_scale if time_format != "unix" else "utc",
                  f"observations.{col}")


def _numbers(raw: Sequence[Any], col: str, *, positive: bool = False) -> np.ndarray:
    try:
        out = np.array(raw, dtype=np.float64)
    except (TypeError, ValueError):
        out = None
    if out is None or not np.isfinite(out).all() or (positive and not (out > 0).all()):
        for i, v in enumerate(raw):
            where = f"observations.{col}[row {i + 1}]"
            try:
                x = float(v)
            except (TypeError, ValueError):
                raise FieldError(where, f"not a number: {v!r}") from None
            if not math.isfinite(x):
                raise FieldError(where, f"{v!r} is not a finite value (drop the row or give its value)")
            if positive and not x > 0:
                raise FieldError(where, f"an uncertainty must be > 0, got {v!r}")
    return out


def read_csv(text: str, name: str, *, time_col: Any, value_col: str | None, error_col: str | None, kind: str,
              time_format: str, time_scale: str, filter_col: str | None, observer_col: str | None,
              track_col: str | None) -> dict[str, Any]:
    cols, rows = text_rows(text, name)
    value_col = value_col or find_column(cols, VALUE_NAMES[kind]) or DEFAULT_VALUE[kind]
    if error_col is None:
        error_col = find_column(cols, ERROR_NAMES[kind])
    tcols = list(time_col) if isinstance(time_col, (list, tuple)) else [time_col or find_column(cols, TIME_NAMES) or "time_utc"]
    if time_format == "iso" and len(tcols) == 1 and tcols[0].lower() in ("jd", "mjd"):
        time_format = tcols[0].lower()  # a column named jd or mjd holds Julian dates (time_format left iso)
    if not 1 <= len(tcols) <= 2:
        raise FieldError("observations.time_col", f"one column, or two (date and time) to join; got {tcols}")
    if time_format == "unix" and time_scale != "utc":
        raise FieldError("observations.time_scale", "Unix seconds count UTC; time_scale must be 'utc' with time_format='unix'")
    for fld, names in (("time_col", tcols), ("value_col", [value_col]), ("error_col", [error_col])):
        for c in names:
            if c is not None and c not in cols:
                raise FieldError(f"observations.{fld}", f"{name} has no column {c!r}; its columns: {', '.join(cols)}")
    if not rows:
        raise FieldError("observations", f"{name}: a header and no data rows")
    bad = next((i for i, r in enumerate(rows) if len(r) != len(cols)), None)
    if bad is not None:
        raise FieldError(f"observations[row {bad + 1}]", f"{len(rows[bad])} fields, the header has {len(cols)}")
    check_kind(np.zeros(0), value_col, kind)  # the column's name against kind, before any value is parsed

    def column(c: str) -> list[str]:
        j = cols.index(c)
        return [r[j].strip() for r in rows]

    raw_t = column(tcols[0]) if len(tcols) == 1 else ["T".join(parts) for parts in zip(*(column(c) for c in tcols))]
    out: dict[str, Any] = {"times_utc": _times(raw_t, "+".join(tcols), time_format, time_scale),
                           "values": _numbers(column(value_col), value_col), "kind": kind,
                           "errors": _numbers(column(error_col), error_col, positive=True) if error_col else None,
                           "meta": {"format": "csv", "time_col": "+".join(tcols), "time_format": time_format,
                                    "value_col": value_col, "error_col": error_col}}
    for key, c in (("filters", filter_col), ("observers", observer_col), ("tracks", track_col)):
        if c in cols:
            out[key] = np.array(column(c))
    return out


def _read(path: Any, *, time_col: Any = None, value_col: str | None = None, error_col: str | None = None,
          kind: str = "magnitude", time_format: str = "iso", time_scale: str = "utc", filter_col: str | None = "filter",
          observer_col: str | None = "observer", track_col: str | None = "track", **options: Any) -> dict[str, Any]:
    return read_csv(read_text(path), Path(path).name, time_col=time_col, value_col=value_col, error_col=error_col,
                    kind=kind, time_format=time_format, time_scale=time_scale, filter_col=filter_col,
                    observer_col=observer_col, track_col=track_col)


#: any text table: the fallback, tried last
register_format("csv", lambda path, first_lines: True, _read, priority=-100, time_col="time_utc", overwrite=True)


def write_light_curve(path: str | Path, lc: Any) -> None:
    """Write ``lc`` as a CSV that :func:`read_light_curve` reads back with its defaults (ISO
    times to the microsecond, ``Z``; the value and error columns of its kind)."""
    rows = []
    for i, t in enumerate(lc.times_utc):
        row = {"time_utc": f"{np.datetime_as_string(t, unit='us')}Z", DEFAULT_VALUE[lc.kind]: repr(float(lc.values[i]))}
        if lc.errors is not None:
            row[DEFAULT_ERROR[lc.kind]] = repr(float(lc.errors[i]))
        if lc.filters is not None:
            row["filter"] = lc.filters[i]
        if lc.observers is not None:
            row["observer"] = lc.observers[i]
        if lc.tracks is not None:
            row["track"] = lc.tracks[i]
        rows.append(row)

    atomic_csv(Path(path), rows)
