"""Measured light curves in: a table of UTC time stamps, a magnitude or a flux, and its
uncertainty (issue 23).

:func:`read_light_curve` reads a CSV (the format survey databases export and cssat's own
``lightcurve.csv``), and an ECSV or FITS table where astropy is installed (``pip install
cssat[astro]``). Column names default to cssat's format and can name any export's. Time stamps
are ISO 8601 (UTC unless they carry an offset), or Julian dates, modified Julian dates or Unix
seconds (``time_format``), at any cadence, with gaps; they must increase. A bad file gets a
:class:`~cssat._checks.FieldError` that names the column and the row (the data row, from 1),
which the command line turns into exit 2.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from cssat._checks import FieldError, choice_param

__all__ = ["ObservedLightCurve", "read_light_curve", "write_light_curve", "KINDS", "TIME_FORMATS"]

KINDS = ("magnitude", "flux")
TIME_FORMATS = ("iso", "jd", "mjd", "unix")
#: the value column of cssat's own ``lightcurve.csv`` by kind, and the error column it may carry
DEFAULT_VALUE = {"magnitude": "magnitude", "flux": "flux_W_m2"}
DEFAULT_ERROR = {"magnitude": "magnitude_err", "flux": "flux_W_m2_err"}
_JD_UNIX = 2440587.5  # the Julian date of 1970-01-01 00:00 UTC
_MJD_UNIX = 40587.0


@dataclass
class ObservedLightCurve:
    """A measured light curve: ``times_utc (T,)`` ``datetime64[us]`` (increasing), ``values (T,)``
    float64 (V magnitudes or flux in the file's unit, W/m² for cssat's), ``errors (T,)`` (1σ, same
    unit; ``None`` when the file has none), ``kind`` (``"magnitude"`` or ``"flux"``), and
    optional ``filters``/``observers`` ``(T,)`` strings; ``source`` is the file."""

    times_utc: np.ndarray
    values: np.ndarray
    errors: np.ndarray | None
    kind: str
    filters: np.ndarray | None = None
    observers: np.ndarray | None = None
    source: str = ""

    def __len__(self) -> int:
        return len(self.times_utc)

    def magnitudes(self) -> np.ndarray:
        """The values as magnitudes (a flux in W/m² through the Sun's V magnitude)."""
        if self.kind == "magnitude":
            return self.values
        from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V

        with np.errstate(divide="ignore"):
            return SUN_MAGNITUDE_V - 2.5 * np.log10(self.values / SOLAR_IRRADIANCE_W_M2)

    def fluxes(self) -> np.ndarray:
        """The values as flux in W/m² (a V magnitude through the Sun's: ``I₀ 10^(−0.4 (V − V_☉))``)."""
        if self.kind == "flux":
            return self.values
        from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V

        return SOLAR_IRRADIANCE_W_M2 * 10.0 ** (-0.4 * (self.values - SUN_MAGNITUDE_V))

    def flux_errors(self) -> np.ndarray | None:
        """1σ errors in W/m² (a magnitude's ``σ_m F / 1.0857``)."""
        if self.errors is None or self.kind == "flux":
            return self.errors
        return self.errors * math.log(10) / 2.5 * self.fluxes()

    def magnitude_errors(self) -> np.ndarray | None:
        """1σ errors in magnitudes (a flux's ``1.0857 σ_F / F``)."""
        if self.errors is None or self.kind == "magnitude":
            return self.errors
        return 2.5 / math.log(10) * self.errors / np.abs(self.values)


def _table(path: Path, fmt: str | None) -> tuple[list[str], list[list[Any]]]:
    """``(column names, rows)`` of a CSV, ECSV or FITS table (read once, hashed as read)."""
    import io

    from cssat._record import read_input

    suffix = (fmt or path.suffix.lstrip(".")).lower()
    data = read_input(path, 1 << 30, "observations")
    if suffix in ("ecsv", "fits", "fit", "fts"):
        try:
            from astropy.table import Table
        except ImportError:
            raise FieldError("observations", f"{path.name}: reading {suffix.upper()} needs astropy "
                                             "(pip install 'cssat[astro]'), or give a CSV") from None
        try:
            src = data.decode("utf-8") if suffix == "ecsv" else io.BytesIO(data)  # ECSV: the text itself
            t = Table.read(src, format="ascii.ecsv" if suffix == "ecsv" else "fits")
        except Exception as err:  # astropy raises many kinds on a malformed file
            raise FieldError("observations", f"{path.name}: not a readable {suffix.upper()} table ({err})") from None
        cols = list(t.colnames)
        return cols, [[t[c][i] for c in cols] for i in range(len(t))]
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise FieldError("observations", f"{path.name}: not a UTF-8 text table (a CSV with a header row)") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    rows = list(csv.reader(lines))
    if not rows:
        raise FieldError("observations", f"{path.name}: no header row and no data")
    return [c.strip() for c in rows[0]], [r for r in rows[1:]]


def _times(raw: Sequence[Any], col: str, time_format: str) -> np.ndarray:
    from cssat.scene.orbit import _start_datetime

    out = np.empty(len(raw), dtype="datetime64[us]")
    for i, v in enumerate(raw):
        where = f"observations.{col}[row {i + 1}]"
        if time_format == "iso":
            text = v.decode() if isinstance(v, bytes) else str(v)
            out[i] = np.datetime64(_start_datetime(text.strip(), where), "us")
            continue
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise FieldError(where, f"not a number ({time_format}): {v!r}") from None
        if not math.isfinite(x):
            raise FieldError(where, f"not a finite time: {v!r}")
        days = {"jd": x - _JD_UNIX, "mjd": x - _MJD_UNIX, "unix": x / 86400.0}[time_format]
        out[i] = np.datetime64(0, "us") + np.timedelta64(int(round(days * 86400e6)), "us")
    step = np.diff(out).astype(np.int64)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise FieldError(f"observations.{col}[row {i + 1}]", f"times must increase: {out[i]} does not come after "
                                                            f"{out[i - 1]} (sort the file, or drop the duplicate)")
    return out


def _numbers(raw: Sequence[Any], col: str, *, positive: bool = False) -> np.ndarray:
    out = np.empty(len(raw))
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
        out[i] = x
    return out


def read_light_curve(path: str | Path, *, time_col: str = "time_utc", value_col: str | None = None,
                     error_col: str | None = None, kind: str = "magnitude", time_format: str = "iso",
                     filter_col: str | None = "filter", observer_col: str | None = "observer",
                     format: str | None = None) -> ObservedLightCurve:
    """Read a measured light curve: a table with a header of column names.

    ``time_col`` (default ``time_utc``), in ``time_format`` (``iso``: ISO 8601, UTC unless an
    offset is given; ``jd``/``mjd``: Julian / modified Julian dates in UTC; ``unix``: seconds since
    1970). ``value_col`` (default: cssat's ``magnitude`` or ``flux_W_m2`` for ``kind``), a V
    magnitude or a flux. ``error_col``: its 1σ (default: ``magnitude_err``/``flux_W_m2_err`` when
    the file has it, else none). ``filter_col``/``observer_col``: read when the file has them.
    ``format``: ``csv``, ``ecsv`` or ``fits`` (default: the file's suffix; ECSV and FITS need
    astropy). Returns an :class:`ObservedLightCurve`.

    Errors (:class:`~cssat._checks.FieldError`, exit 2 on the CLI) name the column and the data
    row: a missing column (with the file's columns), an unparsable time, a NaN or infinite value,
    an uncertainty ≤ 0, times that do not increase, an empty file.
    """
    kind = choice_param(kind, "kind", KINDS)
    time_format = choice_param(time_format, "time_format", TIME_FORMATS)
    p = Path(path)
    if not p.is_file():
        raise FieldError("observations", f"no such file: {p}")
    cols, rows = _table(p, format)
    value_col = value_col or DEFAULT_VALUE[kind]
    if error_col is None and DEFAULT_ERROR[kind] in cols:
        error_col = DEFAULT_ERROR[kind]
    for name, col in (("time_col", time_col), ("value_col", value_col), ("error_col", error_col)):
        if col is not None and col not in cols:
            raise FieldError(f"observations.{name}", f"{p.name} has no column {col!r}; its columns: {', '.join(cols)}")
    if not rows:
        raise FieldError("observations", f"{p.name}: a header and no data rows")
    short = [i for i, r in enumerate(rows) if len(r) != len(cols)]
    if short:
        raise FieldError(f"observations[row {short[0] + 1}]", f"{len(rows[short[0]])} fields, the header has {len(cols)}")

    def column(name: str) -> list[Any]:
        j = cols.index(name)
        return [r[j] for r in rows]

    times = _times(column(time_col), time_col, time_format)
    values = _numbers(column(value_col), value_col, positive=False)
    if kind == "flux" and (values < 0).any():
        i = int(np.flatnonzero(values < 0)[0])
        raise FieldError(f"observations.{value_col}[row {i + 1}]", f"a flux must be >= 0, got {values[i]}")
    errors = _numbers(column(error_col), error_col, positive=True) if error_col else None
    filters = np.array([str(v).strip() for v in column(filter_col)]) if filter_col in cols else None
    observers = np.array([str(v).strip() for v in column(observer_col)]) if observer_col in cols else None
    return ObservedLightCurve(times, values, errors, kind, filters, observers, str(p))


def write_light_curve(path: str | Path, lc: ObservedLightCurve) -> None:
    """Write ``lc`` as a CSV that :func:`read_light_curve` reads back with its defaults (ISO
    times to the microsecond, ``Z``; the value and error columns of its kind)."""
    from cssat.experiments.files import write_csv

    rows = []
    for i, t in enumerate(lc.times_utc):
        row = {"time_utc": f"{np.datetime_as_string(t, unit='us')}Z", DEFAULT_VALUE[lc.kind]: repr(float(lc.values[i]))}
        if lc.errors is not None:
            row[DEFAULT_ERROR[lc.kind]] = repr(float(lc.errors[i]))
        if lc.filters is not None:
            row["filter"] = lc.filters[i]
        if lc.observers is not None:
            row["observer"] = lc.observers[i]
        rows.append(row)
    write_csv(Path(path), rows)
