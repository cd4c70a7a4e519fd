"""Light-curve file formats by name, in the manner of astropy's I/O registry: each format
registers a function that tells its files (``identify``) and one that reads them (``read``), and
:func:`~cssat.data.read_light_curve` picks one by ``format=`` or by asking every ``identify``.

A new format is one module::

    from cssat.data import register_format

    def identify(path, first_lines):          # the path, the file's first lines (line ends kept)
        return bool(first_lines) and first_lines[0].startswith("# my survey")

    def read(path, **options):                # read_light_curve's reading options (use what applies)
        ...
        return {"times_utc": ..., "values": ..., "errors": None, "kind": "magnitude",
                "meta": {"format": "mysurvey"}}   # ObservedLightCurve's columns, as a dict

    register_format("mysurvey", identify, read, extensions=("msv",))

— imported once before reading (``import mysurvey`` in the script or the module that runs the
experiment: ``register_format`` runs at its import). ``read`` returns the columns of
:class:`~cssat.data.ObservedLightCurve` as a dict (``times_utc`` ``datetime64[us]`` UTC,
``values``, ``errors`` or None, ``kind``, the optional per-sample columns, ``meta``); every format's
columns then go through the same checks (:func:`cssat.data.finish.finish`). ``options``: ``time_col``,
``value_col``, ``error_col``, ``kind``, ``time_format``, ``time_scale``, ``filter_col``,
``observer_col``, ``track_col``, ``object``. :func:`read_text` reads a text file with the size
cap and the errors every format gives.

Identification: a format identifies a file when its ``extensions`` hold the file's suffix or its
``identify`` says so; of several, the highest ``priority`` wins (cssat's: FITS 60, ECSV 50, ALCDEF
40, MMT 30, SCORE 20; CSV −100, any text table, the fallback; a new format's default 0); a tie is
a FieldError naming ``format`` and the candidates, as is no match.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from cssat._checks import FieldError

__all__ = ["Format", "register_format", "unregister_format", "registered_formats", "get_format", "identify_format", "read_text",
           "read_bytes", "decode_text", "HEAD_CHARS", "BUILTIN_FORMATS"]

#: cssat's own formats, in the order they are listed (registered by their modules)
BUILTIN_FORMATS = ("csv", "mmt", "score", "alcdef", "ecsv", "fits", "astropy")
#: the modules of cssat.data that register them when imported (alcdef; ecsv, fits, astropy; mmt; score; csv)
BUILTIN_MODULES = ("alcdef", "astro", "mmt", "score", "text")
#: the characters of a file's start that ``identify`` sees (as lines)
HEAD_CHARS = 8192


@dataclass(frozen=True)
class Format:
    """A registered format: its ``name``, ``identify(path, first_lines) -> bool`` (None: by
    ``extensions`` alone), ``read(path, **options) -> dict``, the ``extensions`` (lower case,
    no dot) that identify it, its ``priority`` among formats that identify one file,
    ``fixed_options`` (the reading options it sets itself: option → the values that agree with
    it, ``None`` for unset; any other value is refused naming the option), ``sort`` (its rows
    are sorted by time; otherwise they must increase), ``selects_object`` (its ``read`` keeps
    the rows of ``object=`` itself; otherwise the file's named object is compared with it),
    ``time_col`` (the time column errors name when the caller names none) and ``binary`` (no
    text is decoded to identify it)."""

    name: str
    identify: Callable[[Any, list[str]], bool] | None
    read: Callable[..., dict[str, Any]]
    extensions: tuple[str, ...] = ()
    priority: int = 0
    fixed_options: dict[str, tuple] | None = None
    sort: bool = False
    selects_object: bool = False
    time_col: str = "time"
    binary: bool = False
    module: str = field(default="", compare=False)


_FORMATS: dict[str, Format] = {}


def register_format(name: str, identify: Callable[[Any, list[str]], bool] | None, read: Callable[..., dict[str, Any]], *,
                    extensions: tuple[str, ...] | list[str] = (), priority: int = 0,
                    fixed_options: dict[str, tuple] | None = None, sort: bool = False, selects_object: bool = False,
                    time_col: str = "time", binary: bool = False, overwrite: bool = False) -> Format:
    """Register the format ``name`` (the module's docstring; the options :class:`Format`'s). A
    name taken is a FieldError naming ``format`` unless ``overwrite``. Returns the entry."""
    if not isinstance(name, str) or not name or name != name.lower() or not name.replace("_", "").isalnum():
        raise FieldError("format", f"a format's name is lower-case letters, digits and _, got {name!r}")
    if name in _FORMATS and not overwrite:
        raise FieldError("format", f"the format {name!r} is registered already (overwrite=True replaces it); the "
                                   f"formats: {', '.join(_FORMATS)}")
    if identify is not None and not callable(identify) or not callable(read):
        raise FieldError("format", f"{name}: identify (or None) and read must be functions")
    exts = tuple(str(e).lower().lstrip(".") for e in ([extensions] if isinstance(extensions, str) else extensions))
    if identify is None and not exts:
        raise FieldError("format", f"{name}: a format without identify needs extensions")
    entry = Format(name, identify, read, exts, int(priority), dict(fixed_options) if fixed_options else None, bool(sort),
                   bool(selects_object), str(time_col), bool(binary), getattr(read, "__module__", ""))
    _FORMATS[name] = entry
    return entry


def unregister_format(name: str) -> None:
    """Remove the format ``name`` (a FieldError listing the formats when there is none)."""
    get_format(name)
    del _FORMATS[name]


def registered_formats() -> dict[str, Format]:
    """The registered formats by name: cssat's own (:data:`BUILTIN_FORMATS`), then the others
    in the order of their registration (a copy)."""
    _builtins()
    names = list(dict.fromkeys([*(b for b in BUILTIN_FORMATS if b in _FORMATS), *_FORMATS]))
    return {name: _FORMATS[name] for name in names}


def get_format(name: str, field: str = "format") -> Format:
    """The format ``name``; an unknown one is a FieldError naming ``field`` and the formats."""
    _builtins()
    entry = _FORMATS.get(name) if isinstance(name, str) else None
    if entry is None:
        raise FieldError(field, f"expected one of {list(registered_formats())}, got {name!r}")
    return entry


def _head(path: Path) -> list[str]:
    """The file's first :data:`HEAD_CHARS` characters as lines, line ends kept (UTF-8, a BOM
    dropped, undecodable bytes replaced: identification only)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(4 * HEAD_CHARS)
    except OSError:
        return []
    return data.decode("utf-8-sig", errors="replace")[:HEAD_CHARS].splitlines(keepends=True)


def identify_format(path: str | os.PathLike, first_lines: list[str] | None = None) -> str:
    """The name of the format of the file ``path`` (the module's docstring): a FieldError naming
    ``format`` and the formats when none identifies it or several of the highest priority do."""
    _builtins()
    p = Path(path)
    suffix = p.suffix.lower().lstrip(".")
    lines: list[str] | None = first_lines
    found = []
    for entry in _FORMATS.values():
        ok = bool(suffix) and suffix in entry.extensions
        if not ok and entry.identify is not None:
            if lines is None:
                lines = _head(p)
            ok = bool(entry.identify(p, lines))
        if ok:
            found.append(entry)
    if not found:
        raise FieldError("format", f"{p.name}: no format identifies it; give format=, one of {', '.join(registered_formats())}")
    top = max(e.priority for e in found)
    best = [e.name for e in found if e.priority == top]
    if len(best) > 1:
        raise FieldError("format", f"{p.name} is ambiguous: the formats {', '.join(best)} each identify it; give format=, "
                                   f"one of {', '.join(registered_formats())}")
    return best[0]


def read_bytes(path: str | os.PathLike) -> bytes:
    """The bytes of the file ``path``, read with the input cap (1 GiB) and recorded
    (:func:`cssat._record.read_input`; a FieldError naming ``observations``)."""
    from cssat._record import read_input  # local: the recording of inputs (stdlib only), only for reading

    return read_input(Path(path), 1 << 30, "observations")


def decode_text(data: bytes, name: str) -> str:
    """``data`` as UTF-8 text (a BOM dropped); not UTF-8 is a FieldError naming ``observations``."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise FieldError("observations", f"{name}: not a UTF-8 text table (nor FITS)") from None


def read_text(path: str | os.PathLike) -> str:
    """The text of the file ``path`` (:func:`read_bytes`, :func:`decode_text`)."""
    return decode_text(read_bytes(path), Path(path).name)


_LOADED = False


def _builtins() -> None:
    """cssat's own formats, registered by their modules (imported here on first use)."""
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    import importlib  # local: plugins by module name (the modules import this one to register)

    for module in BUILTIN_MODULES:
        importlib.import_module(f"cssat.data.{module}")
