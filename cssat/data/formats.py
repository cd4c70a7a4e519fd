"""Readers for the light-curve files observers publish, and the checks every
reader shares.

Each reader returns the columns of :class:`~cssat.data.observations.ObservedLightCurve` as a
dict and is registered by its own module (:mod:`cssat.data.registry`);
:func:`~cssat.data.read_light_curve` picks one by ``format=`` or by the file's content:

- ``mmt``: Mini-MegaTORTORA (MMT-9) exports, :mod:`cssat.data.mmt`.
- ``score``: the IAU CPS SatHub SCORE CSV, :mod:`cssat.data.score`.
- ``alcdef``: the Asteroid Lightcurve Data Exchange Format, :mod:`cssat.data.alcdef`.
- ``ecsv``, ``fits``, ``astropy``: an astropy ``Table``/``QTable``/``TimeSeries``, or an
  ECSV/FITS file read by astropy, :mod:`cssat.data.astro`.
- ``csv``: cssat's own CSV and any comma- or whitespace-separated table, :mod:`cssat.data.text`.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.registry import BUILTIN_FORMATS

__all__ = ["FORMATS", "to_utc", "check_dates", "check_magnitudes",
           "check_kind", "period_or_none"]



#: cssat's own formats (:func:`cssat.data.registry.registered_formats`: every registered one)
FORMATS = BUILTIN_FORMATS
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


def _period(value: Any, field: str) -> float:
    """A published period in seconds: a finite number > 0."""
    try:
        p = float(value)
    except (TypeError, ValueError):
        raise FieldError(field, f"not a period in seconds: {value!r}") from None
    if not (math.isfinite(p) and p > 0):
        raise FieldError(field, f"a period must be a finite number of seconds > 0, got {value!r}")
    return p


#: what a header writes for "no period" (MMT's Not variable and Aperiodic tracks: ``0.0``)
NO_PERIOD = ("", "0", "0.0", "0.00", "none", "null", "nan", "-")


def period_or_none(value: Any, field: str) -> float | None:
    """A published period in seconds, or None for a header's "no period" (``0``, ``0.0``,
    ``None``, empty: :data:`NO_PERIOD`); a negative or unreadable period is a FieldError."""
    if value is None:
        return None
    tok = str(value).split()
    if not tok or tok[0].lower() in NO_PERIOD:
        return None
    try:
        if float(tok[0]) == 0.0:
            return None
    except ValueError:
        pass
    return _period(tok[0], field)


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


def check_magnitudes(values: np.ndarray, col: str) -> None:
    """Refuse magnitudes no telescope records (placeholders like 99.999 or -1000; a flux read
    as a magnitude)."""
    bad = np.flatnonzero((values < MAG_RANGE[0]) | (values > MAG_RANGE[1]))
    if bad.size:
        i = int(bad[0])
        raise FieldError(f"observations.{col}[row {i + 1}]", f"{float(values[i])!r} is not a magnitude (allowed {MAG_RANGE[0]:g} "
                         f"to {MAG_RANGE[1]:g}): a placeholder for a missing value? Drop the row, or read a flux "
                         "column with kind='flux'")


_MAG_NAME = re.compile(r"mag(?!e)", re.I)  # "mag", "vmag", "apparent_magnitude"; not "image"


def check_kind(values: np.ndarray, col: str, kind: str) -> None:
    """Refuse a value column that contradicts ``kind`` (its name, or its values): a magnitude
    column named ``flux…`` or whose values are all between 0 and 1e-4 (fluxes in W/m²: a V = 0
    object gives 2.7e-8 W/m²); a flux column named ``…mag…`` or whose negative values lie in
    ±30 (magnitudes: a flux is ≥ 0). Values above 30 in a magnitude column are
    :func:`check_magnitudes`'s."""
    lower = col.lower()
    fin = values[np.isfinite(values)]
    if kind == "magnitude":
        if "flux" in lower:
            raise FieldError("observations.kind", f"the column {col!r} reads as a flux, not a magnitude: give kind='flux'")
        if fin.size and (fin >= 0).all() and (fin < 1e-4).all() and (fin > 0).any():
            raise FieldError("observations.kind", f"the column {col!r} holds values between {fin.min():.3g} and "
                             f"{fin.max():.3g}: fluxes (W/m²), not magnitudes; read it with kind='flux'")
    elif kind == "flux":
        if _MAG_NAME.search(lower):
            raise FieldError("observations.kind", f"the column {col!r} reads as a magnitude, not a flux: give "
                                                  "kind='magnitude'")
        neg = np.flatnonzero(values < 0)
        if neg.size:
            i = int(neg[0])
            mags = fin.size and (np.abs(fin) <= MAG_RANGE[1]).all()
            raise FieldError(f"observations.{col}[row {i + 1}]", f"a flux must be >= 0, got {float(values[i])!r}"
                             + ("; the column's values (all within ±30) look like magnitudes: read it with "
                                "kind='magnitude'" if mags else ""))
