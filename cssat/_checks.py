"""The one validator vocabulary of cssat: checks that raise a :class:`FieldError`, which carries the
name of the offending field as data.

Every layer uses these (solvers, denoisers, atmospheres, noise models, the experiments' config).
A :class:`FieldError` is a ``ValueError`` (library callers can catch that); its ``field`` is the
parameter's name, and a caller that knows where the parameter sits in a config prefixes it with
:meth:`FieldError.within` — ``max_iter`` of the solver becomes ``solver.max_iter`` — instead of
parsing a message. The app exits 2 on any ``FieldError`` (bad input), with its one-line message.
"""

from __future__ import annotations

import math
import numbers
from typing import TYPE_CHECKING, Any, Sequence

if TYPE_CHECKING:
    import torch

__all__ = ["FieldError", "FieldTypeError", "int_param", "float_param", "choice_param", "bool_param", "progress_param", "opt",
           "dtype_param", "device_param"]


class FieldError(ValueError):
    """A bad value of the field ``field`` (a dotted config path, or a parameter's name);
    ``str(err)`` is ``"<field>: <detail>"``."""

    def __init__(self, field: str, detail: str):
        super().__init__(f"{field}: {detail}")
        self.field = str(field)
        self.detail = str(detail)

    def within(self, prefix: str) -> FieldError:
        """The same error with ``prefix.`` before its field (``prefix`` itself when the field is
        already ``prefix`` or under it); the cause is kept."""
        prefix = str(prefix)
        field = self.field if self.field == prefix or self.field.startswith(prefix + ".") else f"{prefix}.{self.field}"
        err = type(self)(field, self.detail)
        err.__cause__ = self.__cause__ or self
        return err

    def __reduce__(self):  # picklable across joblib/submitit workers
        return (type(self), (self.field, self.detail))


class FieldTypeError(FieldError, TypeError):
    """A :class:`FieldError` for a value of the wrong type (also a ``TypeError``)."""


def _range(lo: Any, hi: Any, left: str = "[") -> str:
    return f"{left}{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}]"


def int_param(value: Any, field: str, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an int in ``[lo, hi]``, else a :class:`FieldError` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise FieldError(field, f"expected an integer, got {value!r}")
    value = int(value)
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise FieldError(field, f"must be in {_range(lo, hi)}, got {value}")
    return value


def float_param(value: Any, field: str, lo: float | None = None, hi: float | None = None, *, open_lo: bool = False) -> float:
    """``value`` as a finite float in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise FieldError(field, f"expected a number, got {value!r}")
    value = float(value)
    bad_lo = lo is not None and (value <= lo if open_lo else value < lo)
    if not math.isfinite(value) or bad_lo or (hi is not None and value > hi):
        raise FieldError(field, f"must be a finite number in {_range(lo, hi, '(' if open_lo else '[')}, got {value}")
    return value


def choice_param(value: Any, field: str, allowed: Sequence[Any]) -> Any:
    """``value`` when it is one of ``allowed``, else a :class:`FieldError` listing them."""
    if isinstance(value, bool) and not any(a is value for a in allowed) or value not in allowed:
        raise FieldError(field, f"expected one of {list(allowed)}, got {value!r}")
    return value


def bool_param(value: Any, field: str) -> bool:
    """``value`` when it is ``True`` or ``False``."""
    if not isinstance(value, bool):
        raise FieldError(field, f"expected true or false, got {value!r}")
    return value


def progress_param(value: Any, field: str = "progress") -> bool | None:
    """A progress flag: ``True``, ``False`` or ``None`` (a bar on a terminal only)."""
    if value is not None and not isinstance(value, bool):
        raise FieldError(field, f"expected true, false or null (a bar on a terminal only), got {value!r}")
    return value


def opt(value: Any, check, *args, **kw):
    """``None`` stays ``None``; anything else goes through ``check``."""
    return None if value is None else check(value, *args, **kw)


def dtype_param(name: Any, field: str = "dtype") -> torch.dtype:
    """``"float32"``/``"float64"`` -> torch dtype."""
    import torch  # heavy: torch (~1 s); the module imports without it

    table = {"float32": torch.float32, "float64": torch.float64}
    if name not in table:
        raise FieldError(field, f"expected one of {sorted(table)}, got {name!r}")
    return table[name]


def device_param(name: Any, field: str = "device") -> torch.device:
    """``"cpu"``/``"cuda"``/``"cuda:N"`` -> torch device, checked for availability."""
    import torch  # heavy: torch (~1 s); the module imports without it

    if not isinstance(name, str) or not (name == "cpu" or name.startswith("cuda")):
        raise FieldError(field, f"expected 'cpu' or 'cuda[:N]', got {name!r}")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise FieldError(field, f"{name!r} requested but CUDA is not available on this machine")
    return torch.device(name)
