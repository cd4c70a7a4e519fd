"""Measured light curves in: a table of time stamps, a magnitude or a flux, and its uncertainty.

:func:`read_light_curve` reads the files observers publish, chosen by ``format=`` or by the
file's content (:mod:`cssat.data.formats`): Mini-MegaTORTORA (MMT-9) exports, SCORE/SatHub
CSVs, ALCDEF, astropy tables (``Table``/``QTable``/``TimeSeries`` objects, ECSV and FITS files
with ``Time`` columns in any scale) and cssat's own CSV (``lightcurve.csv``; any column names).
Time stamps are ISO 8601 (UTC unless they carry an offset), or Julian dates, modified Julian
dates or Unix seconds (``time_format``) in UTC, TT, TDB or TAI (``time_scale``), converted to
UTC by astropy, at any cadence, with gaps. A bad file gets a :class:`~cssat._checks.FieldError`
that names the column and the row (the data row, from 1), which the command line turns into
exit 2; the file's size is checked against the memory available before it is read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from cssat._checks import FieldError, FieldTypeError, choice_param
from cssat.data import formats as F
from cssat.data.astro import read_astropy
from cssat.data.finish import FIXED_OPTIONS, fixed_format, finish, jansky_to_magnitudes  # noqa: F401
from cssat.data.registry import get_format, identify_format
from cssat.data.text import DEFAULT_ERROR, DEFAULT_VALUE, write_light_curve  # noqa: F401  (cssat's own CSV)
from cssat.data.text import check_size

__all__ = ["ObservedLightCurve", "read_light_curve", "write_light_curve", "stretches", "KINDS", "TIME_FORMATS", "DUPLICATES"]

KINDS = ("magnitude", "flux")
TIME_FORMATS = ("iso", "jd", "mjd", "unix")
DUPLICATES = ("refuse", "merge")



_ROW_FIELDS = ("times_utc", "values", "errors", "filters", "observers", "tracks", "channels", "sites", "ranges_km",
               "phase_deg", "ra_deg", "dec_deg", "exposure_s", "penumbra")


@dataclass
class ObservedLightCurve:
    """A measured light curve: ``times_utc (T,)`` ``datetime64[us]`` UTC (increasing; samples of
    different camera ``channels`` may share a stamp), ``values
    (T,)`` float64 (magnitudes, or flux in the file's unit — W/m² for cssat's), ``errors (T,)``
    (1σ, same unit; ``None`` when the file has none), ``kind`` (``"magnitude"`` or ``"flux"``).

    Per-sample metadata where the file gives it (else ``None``): ``filters``, ``observers``,
    ``tracks`` (track or session ids), ``channels`` (camera channels) ``(T,)`` strings;
    ``sites (T, 3)`` (observer latitude °, longitude ° east, altitude m); ``ranges_km``,
    ``phase_deg``, ``ra_deg``, ``dec_deg``, ``exposure_s (T,)``; ``penumbra (T,)`` bool.
    ``magnitude_system``: ``"apparent"`` or how the values are normalised (MMT's StdMag);
    ``meta``: the file's own metadata (``format``, ``object_id`` — the NORAD number —,
    ``name``, ``variability``, ``published_period_s``, the raw ``header``); ``source``."""

    times_utc: np.ndarray
    values: np.ndarray
    errors: np.ndarray | None
    kind: str
    filters: np.ndarray | None = None
    observers: np.ndarray | None = None
    source: str = ""
    tracks: np.ndarray | None = None
    channels: np.ndarray | None = None
    sites: np.ndarray | None = None
    ranges_km: np.ndarray | None = None
    phase_deg: np.ndarray | None = None
    ra_deg: np.ndarray | None = None
    dec_deg: np.ndarray | None = None
    exposure_s: np.ndarray | None = None
    penumbra: np.ndarray | None = None
    magnitude_system: str = "apparent"
    meta: dict = field(default_factory=dict)
    band: Any = None  # (Passband, system) of cssat.optics.passbands.resolve_band; None: V with m_Sun = -26.74

    def rows(self, index: Any) -> ObservedLightCurve:
        """The light curve of the samples ``index`` (a mask or indices), metadata kept."""
        kw = {k: (None if getattr(self, k) is None else getattr(self, k)[index]) for k in _ROW_FIELDS}
        return replace(self, **kw)

    def times_s(self, origin: Any = None) -> np.ndarray:
        """``(T,)`` float seconds since ``origin`` (default: the first sample)."""
        t0 = self.times_utc[0] if origin is None else np.datetime64(origin, "us")
        return (self.times_utc - t0).astype("timedelta64[us]").astype(np.int64) / 1e6

    def track_ids(self) -> np.ndarray:
        """``(T,)`` the track of each sample: the file's ids, else contiguous stretches (a new
        one after a gap: :func:`cssat.inversion.period.stretches`)."""
        if self.tracks is not None:
            return np.asarray(self.tracks).astype(str)
        return stretches(self.times_s()).astype(str)

    def select(self, tracks: Any = None, *, start: Any = None, stop: Any = None) -> ObservedLightCurve:
        """The samples of the given ``tracks`` (ids; default all) between ``start`` and ``stop``
        (UTC, inclusive; default the whole curve). Unknown ids are a FieldError that lists the ids."""
        keep = np.ones(len(self), bool)
        if tracks is not None:
            ids = self.track_ids()
            want = [str(x) for x in (tracks if isinstance(tracks, (list, tuple, np.ndarray)) else [tracks])]
            missing = sorted(set(want) - set(ids))
            if missing:
                raise FieldError("observations.tracks", f"no track {', '.join(missing)}; the tracks: {', '.join(dict.fromkeys(ids))}")
            keep &= np.isin(ids, want)
        if start is not None:
            keep &= self.times_utc >= np.datetime64(start, "us")
        if stop is not None:
            keep &= self.times_utc <= np.datetime64(stop, "us")
        if not keep.any():
            raise FieldError("observations", "the selection holds no sample")
        return self.rows(keep)

    def split(self) -> list[ObservedLightCurve]:
        """One light curve per track (in order of first appearance)."""
        ids = self.track_ids()
        return [self.rows(ids == k) for k in dict.fromkeys(ids)]

    def nights(self, utc_offset_h: float = 0.0) -> np.ndarray:
        """``(T,)`` the local night of each sample as ``YYYY-MM-DD`` of its evening (a night
        runs from local noon to noon; ``utc_offset_h`` the site's offset, e.g. lon/15)."""
        local = self.times_utc + np.timedelta64(int(round((utc_offset_h - 12.0) * 3600e6)), "us")
        return np.datetime_as_string(local.astype("datetime64[D]"))

    @staticmethod
    def merge(curves: Sequence[ObservedLightCurve]) -> ObservedLightCurve:
        """One light curve of several (of one kind), sorted by time, each sample keeping its
        track (a curve without track ids gets ``"<k>"`` by position)."""
        curves = list(curves)
        if not curves or len({c.kind for c in curves}) != 1:
            raise FieldError("observations", "merge needs light curves of one kind")
        parts = {}
        for k in _ROW_FIELDS:
            vals = [getattr(c, k) for c in curves]
            if k == "tracks":
                vals = [c.track_ids() if c.tracks is not None else np.full(len(c), str(i)) for i, c in enumerate(curves)]
            parts[k] = None if any(v is None for v in vals) else np.concatenate(vals)
        order = np.argsort(parts["times_utc"], kind="stable")
        kw = {k: (None if v is None else v[order]) for k, v in parts.items()}
        return replace(curves[0], **kw, source=";".join(c.source for c in curves))

    def light_time_corrected(self) -> ObservedLightCurve:
        """The curve at the instants the light left the object: ``t − range/c`` (needs ``ranges_km``)."""
        if self.ranges_km is None:
            raise FieldError("observations.range", "the light-time correction needs the range of each sample")
        shift = np.round(self.ranges_km / 299792.458 * 1e6).astype(np.int64).astype("timedelta64[us]")
        return replace(self, times_utc=self.times_utc - shift)

    def to_table(self) -> Any:
        """The light curve as an astropy ``TimeSeries`` (``time`` in UTC; the value column
        ``mag`` in mag or ``flux``; its error; every per-sample column; ``meta``)."""
        from astropy import units as u  # heavy: astropy, only for to_table()
        from astropy.time import Time  # heavy: astropy, only for to_table()
        from astropy.timeseries import TimeSeries  # heavy: astropy, only for to_table()

        ts = TimeSeries(time=Time(self.times_utc, scale="utc"))
        unit = u.mag if self.kind == "magnitude" else None
        name = "mag" if self.kind == "magnitude" else "flux"
        ts[name] = self.values if unit is None else self.values * unit
        if self.errors is not None:
            ts[f"{name}_err"] = self.errors if unit is None else self.errors * unit
        for k in _ROW_FIELDS[3:]:
            v = getattr(self, k)
            if v is None:
                continue
            if k == "sites":
                ts["site_lat_deg"], ts["site_lon_deg"], ts["site_alt_m"] = v[:, 0], v[:, 1], v[:, 2]
            else:
                ts[k] = v
        ts.meta.update({k: v for k, v in self.meta.items() if isinstance(v, (str, int, float)) or v is None})
        ts.meta.update(kind=self.kind, magnitude_system=self.magnitude_system, source=self.source)
        return ts

    def __len__(self) -> int:
        return len(self.times_utc)

    def magnitudes(self) -> np.ndarray:
        """The values as magnitudes (a flux in W/m² through the Sun's magnitude in ``band``; V by default)."""
        if self.kind == "magnitude":
            return self.values
        if self.band is not None:
            from cssat.optics.passbands import magnitude  # heavy: cssat.optics imports torch

            return magnitude(self.values, *self.band).numpy()
        from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V  # heavy: cssat.optics.photometry imports torch

        with np.errstate(divide="ignore"):
            return SUN_MAGNITUDE_V - 2.5 * np.log10(self.values / SOLAR_IRRADIANCE_W_M2)

    def fluxes(self) -> np.ndarray:
        """The values as flux in W/m² (a V magnitude through the Sun's: ``I₀ 10^(−0.4 (V − V_☉))``)."""
        if self.kind == "flux":
            return self.values
        if self.band is not None:  # the Sun's magnitude in the light curve's own band (Eq. P1 of cssat.optics.passbands)
            from cssat.optics.passbands import flux_from_magnitude  # heavy: cssat.optics imports torch

            return flux_from_magnitude(self.values, *self.band).numpy()
        from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V  # heavy: cssat.optics.photometry imports torch

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


def stretches(times_s: Any, gap_factor: float = 10.0, min_gap_s: float = 1800.0) -> np.ndarray:
    """``(T,)`` int: the contiguous stretch (a track, a night) of each sorted sample: a new one
    starts after a step over ``gap_factor`` × the median step, over twice the 95th percentile
    step and over ``min_gap_s`` (an irregular cadence's pauses, a meridian flip, are not gaps)."""
    t = np.asarray(times_s, dtype=np.float64)
    dt = np.diff(t)
    if not len(dt):
        return np.zeros(len(t), dtype=np.int64)
    pos = dt[dt > 0]
    gap = max(gap_factor * np.median(pos), 2 * np.percentile(pos, 95), min_gap_s) if len(pos) else 0.0
    return np.r_[0, np.cumsum(dt > gap)].astype(np.int64)


def read_light_curve(path: Any, *, time_col: Any = None, value_col: str | None = None, error_col: str | None = None,
                     kind: str = "magnitude", time_format: str = "iso", time_scale: str = "utc",
                     filter_col: str | None = "filter", observer_col: str | None = "observer",
                     track_col: str | None = "track", format: str | None = None, object: Any = None,
                     duplicates: str = "refuse", band: Any = None, band_system: str = "Vega") -> ObservedLightCurve:
    """Read a measured light curve from a file (or an astropy ``Table``/``QTable``/``TimeSeries``).

    ``format``: a registered format (:func:`cssat.data.registry.registered_formats`; cssat's own are
    :data:`~cssat.data.formats.FORMATS`; default: the one that identifies the file — an ALCDEF
    ``STARTMETADATA``, an MMT ``# satellite:`` header, SCORE's columns, ``.ecsv``/``.fits`` —
    else cssat's CSV; a new format is one module that calls
    :func:`~cssat.data.registry.register_format`). For a CSV (comma or whitespace separated; the header the first line or,
    when that is data, the last ``#`` line): ``time_col`` (default the first of ``time_utc``,
    ``time``, ``mjd``, ``jd``; a pair of columns — date and time — is joined), in
    ``time_format`` (``iso``, ``jd``, ``mjd``, ``unix``; a column named ``jd`` or ``mjd`` is
    read as such when it is left ``iso``) and ``time_scale`` (``utc``, ``tt``, ``tdb``, ``tai``:
    converted to UTC by astropy; for a table's plain time column too, a ``Time`` column keeps
    its own scale); ``value_col`` (default cssat's ``magnitude``/``flux_W_m2`` for ``kind``,
    else ``mag``/``flux``; MMT's ``Mag`` or ``StdMag``), ``error_col`` (its 1σ; default
    ``<value>_err``, ``mag_err``, ``magerr``, ``err``), ``filter_col``/``observer_col``/
    ``track_col`` where present. MMT, SCORE and ALCDEF set their own columns, times and kind:
    options that agree with them are accepted, others refused naming the allowed values.
    ``object``: the NORAD id or name to keep from a file of several (SCORE; MMT exports of
    several objects concatenated). ``band``/``band_system``: the magnitudes' band for
    flux↔magnitude (None: V with the Sun at −26.74; a band name, a measured filter file, or
    ``"file"``: the file's own filter column; :func:`cssat.optics.passbands.resolve_band`); a
    table's flux density in Jy is made a magnitude through that band's zero point (AB 3631 Jy;
    Vega: less Vega's AB magnitude in the band) — ``kind`` becomes ``"magnitude"``,
    ``meta["converted_from"]`` says how. ``duplicates``: equal time stamps within a camera
    channel (the whole file when it has no ``channels``) are refused (``"refuse"``) or averaged
    (``"merge"``: the mean value, the errors combined); channels may share a stamp (both kept);
    an exact repeat of a row (stamp, channel, value, error) is dropped
    (``meta["duplicates_dropped"]``). MMT, SCORE and ALCDEF rows are sorted by time; other
    files must increase.

    Errors (:class:`~cssat._checks.FieldError`, exit 2 on the CLI) name the column and the data
    row: a missing column (with the file's columns), an unparsable time, a NaN or infinite value,
    a magnitude outside ±30 (a placeholder such as 99.999), a flux < 0, an uncertainty ≤ 0,
    a unit, column name or values that contradict ``kind`` (fluxes in a magnitude column,
    magnitudes in a flux one), times that do not increase, an empty file, a file too large for
    the memory available.
    """
    kind = choice_param(kind, "kind", KINDS)
    time_format = choice_param(time_format, "time_format", TIME_FORMATS)
    time_scale = choice_param(time_scale, "time_scale", F.TIME_SCALES)
    duplicates = choice_param(duplicates, "duplicates", DUPLICATES)
    if band is not None:
        from cssat.optics.passbands import resolve_band  # heavy: cssat.optics imports torch

        if band != "file":
            resolve_band(band, band_system, field="observations.band")  # refused before the file is read
        else:
            choice_param(band_system, "observations.band_system", ("AB", "Vega"))
    if format is not None:
        format = get_format(str(format).lower()).name
    if hasattr(path, "colnames"):  # an astropy table in memory
        d = read_astropy(path, "the table", time_col=time_col, value_col=value_col, error_col=error_col, kind=kind,
                         time_format=time_format, time_scale=time_scale)
        name, fmt = "the table", "astropy"
    else:
        if not isinstance(path, (str, Path)):
            raise FieldTypeError("observations", f"expected a file path or an astropy table, got {type(path).__name__}")
        p = Path(path)
        if p.is_dir():
            raise FieldError("observations", f"{p} is a directory: a catalogue of its files runs with cssat -m "
                                             f"experiment=characterise observations={p}")
        if not p.is_file():
            raise FieldError("observations", f"no such file: {p}")

        check_size(p)
        name = p.name
        fmt = format or identify_format(p)  # every registered format asked (cssat.data.registry)
        fixed_format(fmt, kind=kind, time_col=time_col, error_col=error_col, time_format=time_format,
                      time_scale=time_scale, value_col=value_col)
        d = get_format(fmt).read(p, time_col=time_col, value_col=value_col, error_col=error_col, kind=kind,
                                 time_format=time_format, time_scale=time_scale, filter_col=filter_col,
                                 observer_col=observer_col, track_col=track_col, object=object)
    if d.get("meta", {}).get("flux_unit") == "Jy":  # a spectral flux density: a magnitude through the band's zero point
        d = jansky_to_magnitudes(d, band, band_system)
    lc = ObservedLightCurve(**{k: v for k, v in d.items() if k != "meta"}, meta=d.get("meta", {}),
                            source=str(path) if fmt != "astropy" else "")
    entry = get_format(fmt)
    if object is not None and not entry.selects_object:  # the file names its object: it must be the one asked for
        want, have = str(object).strip().upper(), {str(lc.meta.get(k) or "").strip().upper() for k in ("object_id", "name")}
        if not (have - {""}):
            raise FieldError("observations.object", f"{name} names no object to compare with {object!r}")
        if want not in have:
            raise FieldError("observations.object", f"{name} is of {lc.meta.get('object_id')} {lc.meta.get('name') or ''}"
                                                    f", not {object!r}")
    tcol = "+".join(time_col) if isinstance(time_col, (list, tuple)) else (time_col or entry.time_col)
    vcol = value_col or lc.meta.get("value_col") or DEFAULT_VALUE[kind]
    ecol = error_col or lc.meta.get("error_col") or DEFAULT_ERROR[kind]
    if band is not None:
        lc.band = resolve_band(band, band_system, lc.filters, field="observations.band")
    return finish(lc, fmt, duplicates, vcol, tcol, ecol)
