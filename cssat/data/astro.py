"""astropy tables in: a ``Table``/``QTable``/``TimeSeries`` object, or an
ECSV/FITS file read by astropy, with its ``Time`` columns in any scale (``TIMESYS`` honoured)
made UTC by astropy and its units checked against the light curve's kind.

A ``Time`` column carries its own scale: a ``time_scale`` other than UTC that differs from it
is refused as a contradiction. A plain time column (ISO strings, or numbers: ``jd``, ``mjd``,
``unix``) is read in ``time_format`` and ``time_scale``; a numeric column named ``jd`` or
``mjd`` is read as such when ``time_format`` is left ``iso``. A spectral flux density per
frequency (Jy, W m⁻² Hz⁻¹) is returned in Jy with ``meta["flux_unit"] = "Jy"`` (the caller
makes it a magnitude through the band's zero point); one per wavelength is refused."""

from __future__ import annotations

import io
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.formats import _datetime64, period_or_none
from cssat.data.registry import decode_text, read_bytes, register_format
from cssat.data.text import DEFAULT_ERROR, DEFAULT_VALUE, _times, find_column

__all__ = ["read_astropy", "read_astropy_file", "identify_ecsv"]


def read_astropy(table: Any, name: str, *, time_col: str | None, value_col: str | None, error_col: str | None,
                 kind: str, time_format: str = "iso", time_scale: str = "utc") -> dict[str, Any]:
    """The columns of an astropy table: its time column (a ``Time`` column in any scale, made
    UTC by astropy; or cssat's ISO ``time_utc``), its value and error columns checked against
    their units (magnitudes in mag; a flux in W/m² — converted — or a spectral flux density,
    kept in its unit, the error in the value's), one value per row, no masked entries. A
    ``Time`` column with a ``location`` gives each sample's site."""
    from astropy import units as u  # heavy: astropy, only for read_astropy()
    from astropy.time import Time  # heavy: astropy, only for read_astropy()

    cols = list(table.colnames)
    if time_col is None:
        tcols = [c for c in cols if isinstance(table[c], Time)]
        time_col = tcols[0] if tcols else find_column(cols, ("time_utc", "time", "mjd", "jd"))
    if time_col not in cols:
        raise FieldError("observations.time_col", f"{name} has no time column {time_col!r}; its columns: {', '.join(cols)}")
    tc = table[time_col]
    _unmasked(tc, time_col)
    if isinstance(tc, Time):
        if time_scale != "utc" and tc.scale != time_scale:
            raise FieldError("observations.time_scale", f"the column {time_col!r} is a Time in {tc.scale.upper()}; "
                             f"time_scale={time_scale!r} contradicts it (leave it unset: astropy converts its own scale)")
        try:
            times = _datetime64(tc)
        except Exception as err:  # a scale astropy cannot make UTC ('local'), an out-of-range date
            raise FieldError(f"observations.{time_col}", f"not a time astropy can make UTC: {' '.join(str(err).split())}") from None
    else:
        raw = np.asarray(getattr(tc, "value", tc))
        fmt = time_format
        if fmt == "iso" and raw.dtype.kind in "iuf":
            fmt = str(time_col).lower() if str(time_col).lower() in ("jd", "mjd") else ""
            if not fmt:
                raise FieldError("observations.time_format", f"the time column {time_col!r} holds numbers, not ISO "
                                                              "date-times: give time_format='jd', 'mjd' or 'unix'")
        if fmt == "unix" and time_scale != "utc":
            raise FieldError("observations.time_scale", "Unix seconds count UTC; time_scale must be 'utc' with "
                                                        "time_format='unix'")
        times = _times(list(raw) if fmt == "iso" else raw, time_col, fmt, time_scale)

    value_col = value_col or next((c for c in (DEFAULT_VALUE[kind], "mag", "magnitude", "flux") if c in cols), None)
    if value_col not in cols:
        raise FieldError("observations.value_col", f"{name} has no column {value_col!r}; its columns: {', '.join(cols)}")
    if error_col is None:
        error_col = find_column(cols, (DEFAULT_ERROR[kind], f"{value_col}_err", "mag_err", "magerr", "flux_err", "err"))
    elif error_col not in cols:
        raise FieldError("observations.error_col", f"{name} has no column {error_col!r}; its columns: {', '.join(cols)}")
    vunit = _unit(table[value_col], value_col, kind)
    target = vunit
    if vunit is not None and vunit.is_equivalent(u.W / u.m ** 2):
        target = u.W / u.m ** 2
    elif vunit is not None and vunit.is_equivalent(u.Jy):
        target = u.Jy  # f_ν: made a magnitude by read_light_curve through the band's zero point
    elif kind == "flux" and vunit is not None:
        raise FieldError(f"observations.{value_col}", f"a flux density per wavelength ({vunit}) needs the band's "
                         "wavelength to become a magnitude: give the flux in Jy (f_ν) or in W/m², or magnitudes")
    vals = _column(table[value_col], value_col, vunit, target)
    errs = None
    if error_col:
        eunit = _unit(table[error_col], error_col, kind) or vunit
        if target is not None and eunit is not None and not eunit.is_equivalent(target):
            raise FieldError(f"observations.{error_col}", f"its unit {eunit} is not the value's ({vunit})")
        errs = _column(table[error_col], error_col, eunit, target)
    out = {"times_utc": times, "values": vals, "errors": errs, "kind": kind, "magnitude_system": "apparent"}
    for key, c in (("filters", "filter"), ("observers", "observer"), ("tracks", "track")):
        if c in cols:
            out[key] = np.array([str(v).strip() for v in table[c]])
    loc = getattr(tc, "location", None)
    if loc is not None:
        geo = loc.to_geodetic()
        lat, lon, h = (np.broadcast_to(np.asarray(q), (len(times),)) for q in
                       (geo.lat.to_value(u.deg), geo.lon.to_value(u.deg), geo.height.to_value(u.m)))
        out["sites"] = np.stack([lat, lon, h], 1).astype(np.float64)
    meta = {str(k).lower(): v for k, v in dict(table.meta or {}).items() if isinstance(v, (str, int, float))}
    obj = meta.get("norad") or meta.get("object_id") or meta.get("norad_cat_id")
    out["meta"] = {"format": "astropy", "value_col": value_col, "error_col": error_col,
                   "object_id": None if obj is None else str(obj), "cospar": meta.get("cospar"),
                   "name": meta.get("object") or meta.get("name"), "header": meta}
    if target is not None and target == u.Jy:
        out["meta"]["flux_unit"] = "Jy"
    period = period_or_none(meta.get("period_s", meta.get("period")), "observations.meta.period")
    if period is not None:
        out["meta"]["published_period_s"] = period
    return out


def _unmasked(col: Any, name: str) -> None:
    """Refuse a column with masked (missing) entries, naming the first."""
    mask = getattr(col, "mask", None)
    if mask is not None and np.any(mask):
        i = int(np.flatnonzero(np.asarray(mask).reshape(len(col), -1).any(1))[0])
        raise FieldError(f"observations.{name}[row {i + 1}]", "a masked (missing) entry: drop the row")


def read_astropy_file(data: bytes, fmt: str, name: str) -> Any:
    """An ECSV or FITS file's bytes as an astropy Table (FITS time columns as ``Time``)."""
    from astropy.table import Table  # heavy: astropy, only for read_astropy_file()

    try:
        with warnings.catch_warnings():  # astropy's verification warnings: the error below says it once
            warnings.simplefilter("ignore")
            if fmt == "ecsv":
                return Table.read(data.decode("utf-8"), format="ascii.ecsv")
            return Table.read(io.BytesIO(data), format="fits", astropy_native=True)
    except Exception as err:  # astropy raises many kinds on a malformed file
        raise FieldError("observations", f"{name}: not a readable {fmt.upper()} table ({' '.join(str(err).split())})") from None


def _unit(col: Any, name: str, kind: str) -> Any:
    """The column's unit (None when it has none), checked against ``kind``: magnitudes in mag, a
    flux in W/m² or a spectral flux density (Jy, W m⁻² Hz⁻¹, erg s⁻¹ cm⁻² Å⁻¹)."""
    from astropy import units as u  # heavy: astropy, only for _unit()

    unit = getattr(col, "unit", None)
    if unit is None or unit == u.dimensionless_unscaled:
        return None
    unit = u.Unit(unit)
    is_mag = "mag" in str(unit)
    if kind == "magnitude" and not is_mag:
        raise FieldError(f"observations.{name}", f"the unit {unit} is not a magnitude (kind='magnitude'); read a flux "
                                                  "with kind='flux'")
    if kind == "flux":
        if is_mag:
            raise FieldError(f"observations.{name}", f"the unit {unit} is a magnitude (kind='flux'); read it with "
                                                      "kind='magnitude'")
        spectral = unit.is_equivalent(u.W / u.m ** 2 / u.Hz, equivalencies=u.spectral_density(1 * u.um))
        if not (unit.is_equivalent(u.W / u.m ** 2) or spectral):
            raise FieldError(f"observations.{name}", f"the unit {unit} is not a flux (W/m², or a spectral flux density "
                                                      "such as Jy)")
    return unit


def _column(col: Any, name: str, unit: Any, target: Any) -> np.ndarray:
    """``(T,)`` float64 of a one-value-per-row real column, without masked entries, in ``target``."""
    _unmasked(col, name)
    if getattr(col, "ndim", 1) != 1:
        raise FieldError(f"observations.{name}", f"one value per row expected, the column has shape {col.shape}")
    raw = np.asarray(getattr(col, "value", col))
    if raw.dtype.kind not in "iuf":
        raise FieldError(f"observations.{name}", f"not a column of real numbers (dtype {raw.dtype})")
    x = raw.astype(np.float64)
    if unit is not None and target is not None and unit != target:
        x = (x * unit).to_value(target)
    return x


def identify_ecsv(path: Any, first_lines: list[str]) -> bool:
    """An ECSV file starts with ``# %ECSV``."""
    return bool(first_lines) and first_lines[0].startswith("# %ECSV")


def _reader(fmt: str) -> Any:
    """The registered ``read`` of an ECSV (``astropy`` a path: as ECSV) or FITS file."""

    def read(path: Any, *, time_col: str | None = None, value_col: str | None = None, error_col: str | None = None,
             kind: str = "magnitude", time_format: str = "iso", time_scale: str = "utc", **options: Any) -> dict[str, Any]:
        name = Path(path).name
        data = read_bytes(path)
        if fmt != "fits":
            decode_text(data, name)  # not UTF-8: the text formats' error
        return read_astropy(read_astropy_file(data, fmt if fmt == "fits" else "ecsv", name), name, time_col=time_col,
                            value_col=value_col, error_col=error_col, kind=kind, time_format=time_format,
                            time_scale=time_scale)

    return read


register_format("fits", None, _reader("fits"), extensions=("fits", "fit", "fts"), priority=60, binary=True,
                overwrite=True)
register_format("ecsv", identify_ecsv, _reader("ecsv"), extensions=("ecsv",), priority=50, overwrite=True)
#: an astropy Table/QTable/TimeSeries object (read_light_curve reads one itself), or a path read as ECSV
register_format("astropy", lambda path, first_lines: False, _reader("astropy"), overwrite=True)
