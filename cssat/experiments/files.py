"""Result files written atomically (:func:`cssat._tmpfiles.atomic_write`): JSON, ``.npz`` and CSV."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from cssat._tmpfiles import atomic_csv, atomic_write

if TYPE_CHECKING:
    from cssat._types import Array

__all__ = ["as_json", "write_json", "write_npz", "write_csv"]


def _finite(v):
    """JSON has no Infinity or NaN: they are written as null (e.g. the PSNR of an exact
    reconstruction of a constant image)."""
    if isinstance(v, (np.floating, np.integer)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: _finite(u) for k, u in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(u) for u in v]
    return v


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return str(v)


def as_json(data: Mapping[str, Any]) -> dict[str, Any]:
    """``data`` as JSON reads it back from :func:`write_json`: numpy scalars as numbers,
    non-finite floats as null, other objects as strings."""
    return json.loads(json.dumps(_finite(dict(data)), default=_jsonable, allow_nan=False))


def write_json(path: str | os.PathLike, data: Mapping[str, Any]) -> None:
    """Write ``data`` as JSON atomically (temporary file + rename); non-finite floats as null."""

    def w(tmp):
        with open(tmp, "w") as f:
            json.dump(_finite(dict(data)), f, indent=2, sort_keys=True, default=_jsonable, allow_nan=False)
            f.write("\n")

    atomic_write(Path(path), w)


def write_npz(path: str | os.PathLike, **arrays: Array) -> None:
    """Save arrays (numpy or torch) to a compressed ``.npz``, atomically."""
    conv = {k: (v.detach().cpu().numpy() if hasattr(v, "detach") else np.asarray(v)) for k, v in arrays.items()}

    def w(tmp):
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **conv)

    atomic_write(Path(path), w)


def write_csv(path: str | os.PathLike, rows: list[dict[str, Any]], fieldnames: list[str] | None = None) -> None:
    """Write ``rows`` (dicts) as a CSV with a header, atomically; columns ``fieldnames`` (default:
    every key in the order first seen), missing values empty (:func:`cssat._tmpfiles.atomic_csv`)."""
    atomic_csv(path, rows, fieldnames)
