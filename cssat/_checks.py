"""Parameter checks shared by the library's objects (solvers, denoisers, atmospheres, noise models):
errors are ValueErrors that name the parameter."""

from __future__ import annotations

import math
import numbers
from typing import Any, Sequence


def int_param(value: Any, field: str, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an int in ``[lo, hi]``, else a ``ValueError`` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{field}: expected an integer, got {value!r}")
    value = int(value)
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ValueError(f"{field}: must be in [{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}], got {value}")
    return value


def float_param(value: Any, field: str, lo: float | None = None, hi: float | None = None, *, open_lo: bool = False) -> float:
    """``value`` as a finite float in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{field}: expected a number, got {value!r}")
    value = float(value)
    bad_lo = lo is not None and (value <= lo if open_lo else value < lo)
    if not math.isfinite(value) or bad_lo or (hi is not None and value > hi):
        left = "(" if open_lo else "["
        raise ValueError(f"{field}: must be a finite number in {left}{lo if lo is not None else '-inf'}, "
                         f"{hi if hi is not None else 'inf'}], got {value}")
    return value


def choice_param(value: Any, field: str, allowed: Sequence[str]) -> str:
    if value not in allowed:
        raise ValueError(f"{field}: expected one of {list(allowed)}, got {value!r}")
    return str(value)


def progress_param(value: Any, field: str = "progress") -> bool | None:
    """A progress flag: ``True``, ``False`` or ``None`` (a bar on a terminal only)."""
    if value is not None and not isinstance(value, bool):
        raise ValueError(f"{field}: expected true, false or null (a bar on a terminal only), got {value!r}")
    return value


def opt(value: Any, check, *args, **kw):
    """``None`` stays ``None``; anything else goes through ``check``."""
    return None if value is None else check(value, *args, **kw)
