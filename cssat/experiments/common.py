"""Helpers shared by the experiments: config checks, atomic output files, dtype/device."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

if TYPE_CHECKING:
    import torch

    from cssat._types import Array


__all__ = [
    "ConfigError",
    "require_int",
    "require_float",
    "torch_dtype",
    "torch_device",
    "write_json",
    "write_npz",
    "write_csv",
]


class ConfigError(ValueError):
    """A config value is out of its allowed range; the message names the field."""


def require_int(value: Any, field: str, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an int in ``[lo, hi]``, else a :class:`ConfigError` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(f"{field}: expected an integer, got {value!r}")
    value = int(value)
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        rng = f"[{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}]"
        raise ConfigError(f"{field}: must be in {rng}, got {value}")
    return value


def require_float(value: Any, field: str, lo: float | None = None, hi: float | None = None) -> float:
    """``value`` as a finite float in ``[lo, hi]``, else a :class:`ConfigError` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ConfigError(f"{field}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or (lo is not None and value < lo) or (hi is not None and value > hi):
        rng = f"[{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}]"
        raise ConfigError(f"{field}: must be a finite number in {rng}, got {value}")
    return value


def torch_dtype(name: str, field: str = "dtype") -> torch.dtype:
    """``"float32"``/``"float64"`` -> torch dtype (config field ``field``)."""
    import torch

    table = {"float32": torch.float32, "float64": torch.float64}
    if name not in table:
        raise ConfigError(f"{field}: expected one of {sorted(table)}, got {name!r}")
    return table[name]


def torch_device(name: str) -> torch.device:
    """``"cpu"``/``"cuda"``/``"cuda:N"`` -> torch device (field ``device``), checked for availability."""
    import torch

    if not isinstance(name, str) or not (name == "cpu" or name.startswith("cuda")):
        raise ConfigError(f"device: expected 'cpu' or 'cuda[:N]', got {name!r}")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(f"device: {name!r} requested but CUDA is not available on this machine")
    return torch.device(name)


def run_settings(cfg: Any, max_size: int = 4096) -> tuple[torch.dtype, torch.device, int, int, int, int | None]:
    """``(dtype, device, seed, n, N, m)`` of an image experiment, validated: the fields ``dtype``,
    ``device``, ``seed``, ``target.size`` (``n``, at most ``max_size``) and ``cs.m`` (``1 ≤ m ≤ N = n²``)."""
    dtype = torch_dtype(cfg.get("dtype", "float32"))
    device = torch_device(cfg.get("device", "cpu"))
    seed = require_int(cfg.get("seed", 0), "seed", 0, 2**63 - 1)
    n = require_int(cfg.target.size, "target.size", 2, max_size)
    N = n * n
    m = measurements(cfg.cs, N) if "cs" in cfg else None
    return dtype, device, seed, n, N, m


def figure_format(cfg: Any) -> str:
    """The config's ``figure_format``: ``png`` (default), ``pdf`` or ``svg``."""
    from cssat.plots import FIGURE_FORMATS

    fmt = cfg.get("figure_format", "png")
    if fmt not in FIGURE_FORMATS:
        raise ConfigError(f"figure_format: expected one of {list(FIGURE_FORMATS)}, got {fmt!r}")
    return str(fmt)


def figure_file(cfg: Any, out_dir: str | os.PathLike, stem: str) -> Path:
    """``out_dir/figures/<stem>.<figure_format>``."""
    return Path(out_dir) / "figures" / f"{stem}.{figure_format(cfg)}"


def progress_setting(cfg: Any) -> bool | None:
    """The top-level ``progress`` flag (tqdm bars): ``true``, ``false`` or ``null`` (a terminal only)."""
    from cssat._checks import progress_param

    try:
        return progress_param(cfg.get("progress"))
    except ValueError as err:
        raise ConfigError(str(err)) from None


def measurements(cs: Any, N: int) -> int:
    """``m`` from the ``cs`` config: ``cs.m`` when set (``1 ≤ m ≤ N``), else
    ``round(cs.ratio · N)`` (``0 < ratio ≤ 1``), so that ``target.size`` can change alone."""
    if cs.get("m") is not None:
        return require_int(cs.m, "cs.m", 1, N)
    if cs.get("ratio") is None:
        raise ConfigError("cs.m: give the number of samples cs.m or the ratio cs.ratio = m/N")
    ratio = require_float(cs.ratio, "cs.ratio", lo=0.0, hi=1.0)
    if ratio == 0:
        raise ConfigError("cs.ratio: must be in (0, 1], got 0")
    return max(1, round(ratio * N))


def _atomic(path: Path, write) -> None:
    """Write ``path`` through ``write(tmp)`` on a temporary file beside it, then rename it into
    place: a reader sees the old file or the new one, never a part. The temporary file gets the
    mode the user's umask gives a new file, and is removed even when this process is killed
    (see :mod:`cssat._tmpfiles`)."""
    from cssat._tmpfiles import release, temporary_path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_path(path)
    try:
        write(str(tmp))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        release(tmp)


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


def write_json(path: str | os.PathLike, data: Mapping[str, Any]) -> None:
    """Write ``data`` as JSON atomically (temporary file + rename); non-finite floats as null."""

    def w(tmp):
        with open(tmp, "w") as f:
            json.dump(_finite(dict(data)), f, indent=2, sort_keys=True, default=_jsonable, allow_nan=False)
            f.write("\n")

    _atomic(Path(path), w)


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return str(v)


def write_npz(path: str | os.PathLike, **arrays: Array) -> None:
    """Save arrays (numpy or torch) to a compressed ``.npz``, atomically."""
    conv = {k: (v.detach().cpu().numpy() if hasattr(v, "detach") else np.asarray(v)) for k, v in arrays.items()}

    def w(tmp):
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **conv)

    _atomic(Path(path), w)


def write_csv(path: str | os.PathLike, rows: list[dict[str, Any]], fieldnames: list[str] | None = None) -> None:
    """Write ``rows`` (dicts) as a CSV with a header, atomically; columns ``fieldnames`` (default:
    the first row's keys), missing values empty."""
    import csv

    cols = fieldnames or list(rows[0])

    def w(tmp):
        with open(tmp, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=cols, restval="")
            wr.writeheader()
            wr.writerows(rows)

    _atomic(Path(path), w)
