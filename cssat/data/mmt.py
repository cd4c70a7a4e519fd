"""The Mini-MegaTORTORA (MMT-9, Karpov et al. 2015) reader: per-track downloads and
whole-object exports, and files that concatenate them.

An export is one or more **blocks**: ``# key: value`` header lines (``satellite: <NORAD> <NAME>
/ <country>``, ``track``, ``variability: 0|1|2 <label>``, ``variability_period``, ``npoints``),
a column line ``# Date Time StdMag Mag Filter Penumbra Distance Phase Channel [Track]`` and
whitespace-separated rows (UTC date and time as two fields; a time on a whole second has no
fraction). A header line after data rows starts a new block that inherits the keys it does not
repeat; a new column line does too. Each block's rows get its own ``# track:`` (unless the rows
carry a ``Track`` column) and its own column line — two column lines that name different
columns are refused naming the line. Blocks of two objects (concatenated exports) are refused
naming both, unless ``object=`` picks one: then only that object's blocks are read.
``variability_period`` of ``0``, ``0.0``, ``None`` or empty is MMT's "no period" (Not variable,
Aperiodic): no ``published_period_s``; ``variability`` is kept.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.formats import MMT_VARIABILITY, _bad_iso, _checked, _floats, period_or_none
from cssat.data.registry import read_text, register_format

__all__ = ["read_mmt", "identify_mmt", "MMT_VALUE_COLUMNS", "MMT_FIXED_OPTIONS"]

#: the value columns of an MMT export: apparent ``Mag`` (default) or ``StdMag`` (1000 km, 90°)
MMT_VALUE_COLUMNS = ("Mag", "StdMag")
#: the reading options an MMT export accepts (``None``: unset); any other value contradicts it
MMT_FIXED_OPTIONS = {"kind": ("magnitude",), "time_col": (None, "time_utc", "Date Time", ("Date", "Time"), "Date+Time"),
                     "value_col": (None, *MMT_VALUE_COLUMNS), "error_col": (None,), "time_format": ("iso",),
                     "time_scale": ("utc",)}


def _object_of(meta: dict[str, str]) -> tuple[str, str, str | None] | None:
    """``(NORAD id, name, country)`` of a block's ``satellite`` line, else None."""
    m = re.match(r"(\d+)\s+(.*?)(?:\s+/\s+(.*))?$", meta.get("satellite", "").strip())
    return (m.group(1), m.group(2).strip(), (m.group(3) or "").strip() or None) if m else None


def _blocks(text: str, name: str) -> list[dict[str, Any]]:
    """The file's blocks: ``meta`` (its header keys, inherited), ``cols``, ``rows`` (split
    fields), ``lines`` (each row's line number) and ``first_line``."""
    blocks: list[dict[str, Any]] = []
    meta: dict[str, str] = {}
    cols: list[str] | None = None
    other = ""
    cur: dict[str, Any] | None = None
    after_data = False
    for n, ln in enumerate(text.splitlines(), 1):
        s = ln.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s.lstrip("#").strip()
            m = re.match(r"([A-Za-z_]+)\s*:\s*(.*)$", body)
            toks = body.split()
            if not (m or toks[:2] == ["Date", "Time"]):
                other = other or body
                continue
            if after_data:  # a header after data rows: the next block, with the keys it does not repeat
                meta, cur, after_data = dict(meta), None, False
            if m:
                meta[m.group(1).lower()] = m.group(2).strip()
            else:
                if cols is not None and blocks and set(toks) != set(cols):
                    raise FieldError(f"observations[line {n}]", f"{name}: a second column line '{' '.join(toks)}' names other "
                                     f"columns than the first '{' '.join(cols)}' (two exports in one file?): split the "
                                     "file there and read the parts")
                cols = toks
            continue
        if cols is None:
            raise FieldError("observations", f"{name}: an MMT file names its columns in a '# Date Time ...' comment line "
                                             f"before its rows; found {other or 'none'}")
        if cur is None:
            cur = {"meta": meta, "cols": cols, "rows": [], "lines": [], "first_line": n}
            blocks.append(cur)
        cur["rows"].append(s.split())
        cur["lines"].append(n)
        after_data = True
    if cols is None:
        raise FieldError("observations", f"{name}: an MMT file names its columns in a '# Date Time ...' comment line; "
                                         f"found {other or 'none'}")
    if not blocks:
        raise FieldError("observations", f"{name}: an MMT header and no data rows")
    return blocks


def _pick_object(blocks: list[dict[str, Any]], name: str, obj: Any) -> list[dict[str, Any]]:
    """The blocks of one object: all of them when the file holds one; ``obj``'s (a NORAD id or
    name) when it holds several; else a FieldError naming the objects."""
    objects: dict[str, tuple[str, str, str | None, int]] = {}
    for b in blocks:
        o = _object_of(b["meta"])
        if o is not None:
            objects.setdefault(o[0], (*o, b["first_line"]))
    if len(objects) <= 1 or obj is None:
        if len(objects) > 1:
            raise FieldError("observations.object", f"{name} holds {len(objects)} objects (concatenated exports): "
                             + ", ".join(f"{k} {v[1]} (from line {v[3]})" for k, v in objects.items())
                             + "; read one with object=<NORAD id or name>")
        return blocks
    want = str(obj).strip().upper()
    keep = [b for b in blocks if (o := _object_of(b["meta"])) is not None and want in (o[0], o[1].upper())]
    if not keep:
        raise FieldError("observations.object", f"{want!r} is not in {name}; its objects: "
                         + ", ".join(f"{k} {v[1]}" for k, v in objects.items()))
    return keep


def _variability(meta: dict[str, str]) -> str | None:
    v = meta.get("variability", "").strip()
    if not v:
        return None
    code = v.split()[0]
    return MMT_VARIABILITY.get(int(code), v) if code.isdigit() else v


def read_mmt(text: str, name: str, value_col: str | None = None, obj: Any = None) -> dict[str, Any]:
    """The columns of an MMT-9 export (the module's docstring): ``times_utc (T,)``, ``values
    (T,)`` magnitudes (``Mag`` or ``StdMag``), per-sample ``filters``, ``ranges_km``
    (``Distance``), ``phase_deg``, ``channels``, ``tracks``, ``penumbra`` where the file has
    them, and ``meta``: ``object_id``, ``name``, ``country``, ``variability``,
    ``published_period_s`` (absent for MMT's "no period"; absent too when blocks disagree:
    ``published_periods_s`` by track), ``blocks`` (each block's track, variability, period and
    first line), ``header`` (the first block's keys)."""
    blocks = _pick_object(_blocks(text, name), name, obj)
    vcol = value_col or "Mag"
    cols0 = blocks[0]["cols"]
    if cols0[:2] != ["Date", "Time"]:
        raise FieldError("observations", f"{name}: the column line must start with 'Date Time'; found {' '.join(cols0)}")
    if vcol not in cols0:
        raise FieldError("observations.value_col", f"{name} has no column {vcol!r}; its columns: {', '.join(cols0)}")
    col: dict[str, list[str]] = {c: [] for c in cols0}
    tracks: list[str] = []
    row = 0
    info_blocks = []
    for k, b in enumerate(blocks):
        cols = b["cols"]
        for r, n in zip(b["rows"], b["lines"]):
            row += 1
            if len(r) != len(cols):
                raise FieldError(f"observations[row {row}]", f"{len(r)} fields (line {n}), the column line names "
                                                             f"{len(cols)}: {' '.join(cols)}")
            for j, c in enumerate(cols):
                col[c].append(r[j])
        trk = (b["meta"].get("track") or "").split()
        tracks += [trk[0] if trk else f"block {k + 1}"] * len(b["rows"])
        period = period_or_none(b["meta"].get("variability_period", b["meta"].get("period")),
                                "observations.variability_period")
        info_blocks.append({"track": trk[0] if trk else None, "variability": _variability(b["meta"]),
                            "published_period_s": period, "first_line": b["first_line"], "rows": len(b["rows"])})
    stamps = [f"{d}T{t}" for d, t in zip(col["Date"], col["Time"])]
    try:
        times = np.array(stamps, dtype="datetime64[us]")
    except ValueError:
        times = None
    if times is None or np.isnat(times).any():
        i = next((k for k, v in enumerate(stamps) if _bad_iso(v)), 0)
        raise FieldError(f"observations.Time[row {i + 1}]", f"not a UTC date and time: {stamps[i]!r}")
    out: dict[str, Any] = {"times_utc": times, "values": _floats(col[vcol], "observations", vcol), "errors": None,
                           "kind": "magnitude",
                           "magnitude_system": "normalised: 1000 km, phase 90°" if vcol == "StdMag" else "apparent"}
    if "Filter" in col:
        out["filters"] = np.array(col["Filter"])
    for key, c, lo, hi, open_lo in (("ranges_km", "Distance", 0.0, 1e7, True), ("phase_deg", "Phase", 0.0, 180.0, False)):
        if c in col:
            out[key] = _checked(_floats(col[c], "observations", c), f"observations.{c}", lo, hi, open_lo=open_lo)
    if "Channel" in col:
        out["channels"] = np.array(col["Channel"])
    if "Track" in col:
        out["tracks"] = np.array(col["Track"])
    elif any(b["track"] for b in info_blocks) or len(blocks) > 1:
        out["tracks"] = np.array(tracks)
    if "Penumbra" in col:
        out["penumbra"] = np.array([v not in ("0", "0.0") for v in col["Penumbra"]])
    info: dict[str, Any] = {"format": "mmt", "value_col": vcol}
    o = _object_of(blocks[0]["meta"])
    if o is not None:
        info.update(object_id=o[0], name=o[1], country=o[2])
    labels = {b["variability"] for b in info_blocks}
    if len(labels) == 1 and None not in labels:
        info["variability"] = labels.pop()
    periods = {b["published_period_s"] for b in info_blocks}
    if len(periods) == 1 and None not in periods:
        info["published_period_s"] = periods.pop()
    elif periods - {None}:
        info["published_periods_s"] = {b["track"] or f"block {k + 1}": b["published_period_s"]
                                       for k, b in enumerate(info_blocks) if b["published_period_s"] is not None}
    if len(blocks) > 1:
        info["blocks"] = info_blocks
    info["header"] = blocks[0]["meta"]
    out["meta"] = info
    return out


def identify_mmt(path: Any, first_lines: list[str]) -> bool:
    """An MMT export has a ``# satellite:``, ``# track:`` or ``# variability:`` header line or a
    ``# Date Time …`` column line in its first lines."""
    head = "".join(first_lines)
    return bool(re.search(r"^#\s*(satellite|track|variability)\s*:", head, re.M)
                or re.search(r"^#\s*Date\s+Time\s", head, re.M))


def _read(path: Any, *, value_col: str | None = None, object: Any = None, **options: Any) -> dict[str, Any]:
    return read_mmt(read_text(path), Path(path).name, value_col, object)


register_format("mmt", identify_mmt, _read, priority=30, fixed_options=MMT_FIXED_OPTIONS, sort=True, overwrite=True)
