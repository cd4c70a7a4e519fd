"""What every reader's columns go through: the reading options a fixed
format accepts, a flux density in Jy made a magnitude, and :func:`finish` — values, dates and
kind checked, rows sorted, duplicate stamps refused or merged within each camera channel."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.alcdef import ALCDEF_FIXED_OPTIONS
from cssat.data.formats import check_dates, check_kind, check_magnitudes
from cssat.data.mmt import MMT_FIXED_OPTIONS
from cssat.data.registry import get_format
from cssat.data.score import SCORE_FIXED_OPTIONS

__all__ = ["FIXED_OPTIONS", "fixed_format", "jansky_to_magnitudes", "finish"]


#: the reading options cssat's fixed formats accept (``None``: unset; each format's own, registered
#: with it: :class:`cssat.data.registry.Format`'s ``fixed_options``)
FIXED_OPTIONS: dict[str, dict[str, tuple]] = {"mmt": MMT_FIXED_OPTIONS, "score": SCORE_FIXED_OPTIONS,
                                              "alcdef": ALCDEF_FIXED_OPTIONS}


def fixed_format(fmt: str, **given: Any) -> None:
    """Refuse a reading option that contradicts a fixed format (MMT, SCORE, ALCDEF say
    themselves what their columns, times and kind are); one that agrees — the format's own
    column name, ``kind='magnitude'`` — is accepted. The error names the option and the values
    the format allows (the format's registered ``fixed_options``)."""
    allowed = get_format(fmt).fixed_options
    if allowed is None:
        return
    for key, value in given.items():
        if key not in allowed:  # an option the format leaves to the caller
            continue
        v = tuple(str(x) for x in value) if not isinstance(value, (str, type(None))) and hasattr(value, "__iter__") \
            else value  # a list (or Hydra's ListConfig) of two columns compares as a tuple
        if v not in allowed[key]:
            ok = ", ".join(repr(list(a) if isinstance(a, tuple) else a) for a in allowed[key] if a is not None)
            raise FieldError(f"observations.{key}", f"a {fmt.upper()} file sets its own: {key}={value!r} contradicts it "
                             f"(allowed: {ok or 'none'}; or leave it unset)")


def jansky_to_magnitudes(d: dict[str, Any], band: Any, band_system: str) -> dict[str, Any]:
    """A spectral flux density ``f_ν`` in Jy as magnitudes: ``m_AB = −2.5 log10(f_ν / 3631 Jy)``
    (Oke & Gunn 1983), in Vega ``m_AB − m_AB(Vega)`` with the band's Vega zero point
    (:mod:`cssat.optics.passbands`; ``band=None``: V, Vega, cssat's default); the error
    ``2.5/ln 10 · σ/f_ν``. A flux ≤ 0 has no magnitude: a FieldError naming its row."""
    from cssat.optics.passbands import AB_ZERO_W_M2_HZ, passband, resolve_band  # heavy: cssat.optics imports torch

    meta = dict(d["meta"])
    col = meta.get("value_col") or "flux"
    f = np.asarray(d["values"], dtype=np.float64)
    bad = np.flatnonzero(~(f > 0))
    if bad.size:
        i = int(bad[0])
        raise FieldError(f"observations.{col}[row {i + 1}]", f"a flux density of {float(f[i])!r} Jy has no magnitude "
                         "(cssat converts a flux in Jy to a magnitude through the band's zero point)")
    pb, system = resolve_band(band, band_system, d.get("filters"), field="observations.band") if band is not None \
        else (passband("V"), "Vega")
    zero_jy = AB_ZERO_W_M2_HZ / 1e-26
    m = -2.5 * np.log10(f / zero_jy) - (pb.vega_ab if system == "Vega" else 0.0)
    e = d.get("errors")
    meta["converted_from"] = (f"{col} in Jy (f_nu): m = -2.5 log10(F / {zero_jy:g} Jy)"
                              + (f" - {pb.vega_ab:.4f} (Vega's AB magnitude in {pb.name})" if system == "Vega" else ""))
    meta["value_col"] = col
    return {**d, "values": m, "errors": None if e is None else 2.5 / math.log(10) * np.asarray(e) / f,
            "kind": "magnitude", "magnitude_system": f"{system} ({pb.name}), from a flux density in Jy", "meta": meta}


def finish(lc: Any, fmt: str, duplicates: str, vcol: str, tcol: str, ecol: str) -> Any:
    """Check values and dates, sort (MMT, SCORE, ALCDEF), drop exact repeats of a row, refuse
    or merge duplicate stamps within a channel (camera channels of one track may share a stamp:
    they are kept, in file order); every error names the file's own row."""
    if not len(lc):
        raise FieldError("observations", "no data rows")
    check_dates(lc.times_utc, f"observations.{tcol}")
    if not np.isfinite(lc.values).all():
        i = int(np.flatnonzero(~np.isfinite(lc.values))[0])
        raise FieldError(f"observations.{vcol}[row {i + 1}]", f"{float(lc.values[i])!r} is not a finite value (drop the row)")
    if "converted_from" not in lc.meta:
        check_kind(lc.values, vcol, lc.kind)
    if lc.kind == "magnitude":
        check_magnitudes(lc.values, vcol)
    if lc.errors is not None and not (np.isfinite(lc.errors) & (lc.errors > 0)).all():
        i = int(np.flatnonzero(~(np.isfinite(lc.errors) & (lc.errors > 0)))[0])
        raise FieldError(f"observations.{ecol}[row {i + 1}]", f"an uncertainty must be finite and > 0, got "
                                                             f"{float(lc.errors[i])!r}")
    rows = np.arange(len(lc))  # each sample's data row in the file
    if get_format(fmt).sort:
        rows = np.argsort(lc.times_utc, kind="stable")
        lc = lc.rows(rows)
    step = np.diff(lc.times_utc).astype(np.int64)
    back = np.flatnonzero(step < 0)
    if back.size:
        i = int(back[0]) + 1
        raise FieldError(f"observations.{tcol}[row {rows[i] + 1}]", f"times must increase: {lc.times_utc[i]} does not "
                                                                   f"come after {lc.times_utc[i - 1]} (sort the file)")
    if not (step == 0).any():
        return lc
    # equal stamps: compared within each camera channel (all samples one channel when the file has none)
    chan = np.zeros(len(lc), np.int64) if lc.channels is None else np.unique(np.asarray(lc.channels).astype(str),
                                                                             return_inverse=True)[1].reshape(-1)
    t = lc.times_utc.astype(np.int64)
    order = np.lexsort((np.arange(len(lc)), t, chan))  # by channel, then time, then file order
    same = (np.diff(t[order]) == 0) & (np.diff(chan[order]) == 0)  # order[k + 1] repeats order[k]'s stamp
    if not same.any():
        return lc
    err = lc.errors if lc.errors is not None else np.zeros(len(lc))
    exact = same & (np.diff(lc.values[order]) == 0) & (np.diff(err[order]) == 0)
    if exact.any():  # an exact repeat of a row (same stamp, channel, value, error): the same measurement twice
        keep = np.ones(len(lc), bool)
        keep[order[1:][exact]] = False
        meta = {**lc.meta, "duplicates_dropped": int(exact.sum()) + int(lc.meta.get("duplicates_dropped", 0))}
        lc, rows = replace(lc.rows(keep), meta=meta), rows[keep]
        return _duplicates(lc, rows, duplicates, tcol, chan[keep])
    return _duplicates(lc, rows, duplicates, tcol, chan)


def _duplicates(lc: Any, rows: np.ndarray, duplicates: str, tcol: str,
                       chan: np.ndarray) -> Any:
    """Refuse (``duplicates='refuse'``) or average (``'merge'``: the mean, or the inverse-variance
    mean and its error) the samples of one channel that share a stamp."""
    t = lc.times_utc.astype(np.int64)
    order = np.lexsort((np.arange(len(lc)), t, chan))
    same = (np.diff(t[order]) == 0) & (np.diff(chan[order]) == 0)
    if not same.any():
        return lc
    if duplicates == "refuse":
        k = int(np.flatnonzero(same)[0])
        i, j = order[k + 1], order[k]
        where = "" if lc.channels is None else f" in channel {lc.channels[i]}"
        raise FieldError(f"observations.{tcol}[row {rows[i] + 1}]", f"a duplicate time stamp {lc.times_utc[i]}{where} (of "
                                                                   f"row {rows[j] + 1}; drop it, or read with "
                                                                   "duplicates='merge' to average them)")
    group = np.empty(len(lc), np.int64)
    group[order] = np.r_[0, np.cumsum(~same)]
    _, first = np.unique(group, return_index=True)
    first = np.sort(first)  # each group's first sample, in time order
    if lc.errors is not None:
        wgt = 1.0 / lc.errors ** 2
        vals = np.bincount(group, lc.values * wgt) / np.bincount(group, wgt)
        errs = 1.0 / np.sqrt(np.bincount(group, wgt))
        return replace(lc.rows(first), values=vals[group[first]], errors=errs[group[first]])
    vals = np.bincount(group, lc.values) / np.bincount(group)
    return replace(lc.rows(first), values=vals[group[first]], errors=None)
