"""The Asteroid Lightcurve Data Exchange Format reader (ALCDEF, Warner et al. 2011):
``STARTMETADATA … ENDMETADATA`` blocks (one per session: a track) and
``DATA=JD|MAG|MAGERR`` lines (UTC Julian dates; the block's ``MAGBAND``, ``DELIMITER``, object and
observers). Registered as the format ``alcdef`` (:mod:`cssat.data.registry`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.data.formats import to_utc
from cssat.data.registry import read_text, register_format

__all__ = ["read_alcdef", "identify_alcdef", "ALCDEF_FIXED_OPTIONS"]

#: the reading options an ALCDEF file accepts (``None``: unset); any other value contradicts it
ALCDEF_FIXED_OPTIONS = {"kind": ("magnitude",), "time_col": (None, "time_utc", "JD"), "value_col": (None, "MAG"),
                        "error_col": (None, "MAGERR"), "time_format": ("iso", "jd"), "time_scale": ("utc",)}


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


def identify_alcdef(path: Any, first_lines: list[str]) -> bool:
    """An ALCDEF file starts with ``STARTMETADATA`` (blank lines before it allowed)."""
    return "".join(first_lines).lstrip("\ufeff").lstrip().upper().startswith("STARTMETADATA")


def _read(path: Any, **options: Any) -> dict[str, Any]:
    return read_alcdef(read_text(path), Path(path).name)


register_format("alcdef", identify_alcdef, _read, priority=40,
                fixed_options=ALCDEF_FIXED_OPTIONS, sort=True, overwrite=True)
