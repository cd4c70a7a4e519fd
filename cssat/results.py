"""The base of cssat's result objects (:mod:`cssat.inversion.results`,
:mod:`cssat.occultation.results`): a read-only mapping of an estimator's keys with attributes.

A result is a :class:`~collections.abc.Mapping` over the estimator's own dict — ``r["period_s"]``,
``dict(r)``, ``r.keys()``, ``"fap" in r``, ``r.get(k, default)`` read as they did on the dict —
with typed properties for the documented keys (``r.period_s``) and attribute access to any other
key. Not a frozen dataclass of fixed fields, because the keys are open: each period method records
its own (the default 36 keys, a plain periodogram a dozen, a registered method whatever it has),
and an absent key must stay absent — ``r.get("photometric_period_s", r["best_period_s"])`` reads
as it did on the dict, where a dataclass's default ``None`` would be a present value and change
what the experiments record. ``dict(r)`` is the estimator's dict key for key (the experiments'
metrics unchanged); :meth:`Result.to_json` writes it as JSON (arrays as lists),
:meth:`Result.from_json` reads it back (the class's array keys as arrays).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, ClassVar, Iterator

import numpy as np

from cssat._checks import FieldError, FieldTypeError

__all__ = ["Result", "jsonable"]


def jsonable(value: Any) -> Any:
    """``value`` with numpy arrays as lists, numpy scalars as Python numbers, tuples as lists,
    mappings (results included) as dicts with string keys; other objects (a BRDF, a state) as
    their ``repr`` — JSON of them is a record, not a way back."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


class Result(Mapping):
    """A read-only mapping of an estimator's keys with attribute access (the module's
    docstring). ``Result(d)`` or ``Result(**kw)``; ``Result(r)`` of a result copies its keys.
    Subclasses name the keys they require (:attr:`required`, a FieldError naming the missing
    ones) and the keys :meth:`from_json` makes arrays again (:attr:`array_keys`, dotted for a
    nested mapping)."""

    __slots__ = ("_data",)
    required: ClassVar[tuple[str, ...]] = ()
    array_keys: ClassVar[tuple[str, ...]] = ()

    def __init__(self, data: Mapping[str, Any] | None = None, /, **kw: Any):
        if data is not None and not isinstance(data, Mapping):
            raise FieldTypeError(self._name(), f"expected a mapping of the result's keys, got {type(data).__name__}")
        d = {**(dict(data._data) if isinstance(data, Result) else dict(data or {})), **kw}
        missing = [k for k in self.required if k not in d]
        if missing:
            raise FieldError(self._name(), f"missing {', '.join(missing)}; a {type(self).__name__} needs "
                                           f"{', '.join(self.required)}")
        object.__setattr__(self, "_data", d)

    @classmethod
    def _name(cls) -> str:
        return cls.__name__

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Any:
        """``data`` as this class: a result of it returned as it is (idempotent), a dict wrapped."""
        return data if type(data) is cls else cls(data)

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __contains__(self, key: object) -> bool:
        return key in self._data

    def __getattr__(self, name: str) -> Any:  # only for names that are not attributes: the other keys
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._data[name]
        except KeyError:
            raise AttributeError(f"{type(self).__name__} has no {name!r}; its keys: {', '.join(self._data)}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"a {type(self).__name__} is read-only: make a new one, "
                             f"{type(self).__name__}({{**r, {name!r}: ...}})")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"a {type(self).__name__} is read-only")

    def __reduce__(self) -> tuple:  # pickled across joblib workers as its dict
        return (type(self), (self._data,))

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | {k for k in self._data if isinstance(k, str) and k.isidentifier()})

    def __repr__(self) -> str:
        keys = ", ".join(list(self._data)[:8]) + (", …" if len(self._data) > 8 else "")
        return f"{type(self).__name__}({keys})"

    def to_dict(self) -> dict[str, Any]:
        """A (shallow) copy of the keys as a plain dict: ``dict(r)``."""
        return dict(self._data)

    def to_json(self, **kw: Any) -> str:
        """The keys as JSON (:func:`jsonable`; ``kw`` to :func:`json.dumps`; NaN as ``NaN``)."""
        return json.dumps(jsonable(self._data), **kw)

    @classmethod
    def from_json(cls, text: str) -> Any:
        """A result from :meth:`to_json`'s text, :attr:`array_keys` as float arrays."""
        d = json.loads(text)
        for key in cls.array_keys:
            *outer, last = key.split(".")
            node = d
            for k in outer:
                node = node.get(k) if isinstance(node, dict) else None
            if isinstance(node, dict) and node.get(last) is not None:
                node[last] = np.asarray(node[last], dtype=np.float64)
        return cls(d)
