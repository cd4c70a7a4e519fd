"""What a run wrote and read: the record behind its result manifest.

While :func:`recording` is active (one experiment run), every result file written through
:func:`cssat._tmpfiles.atomic_write` below the run's directory is noted as an *output*, and every
input file read through :func:`read_input` (a target image, a mesh) is noted with the hash of the
bytes that were read — hashed as read, so a file changed during the run cannot pass as the one
the results came from. Outside a recording both are no-ops: library calls in a notebook are not
affected.
"""

from __future__ import annotations

import hashlib
import os
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from cssat._checks import FieldError

__all__ = ["Record", "recording", "note_output", "read_input", "digest"]


@dataclass
class Record:
    """``outputs``: paths written (relative to ``root``, in order); ``inputs``: ``{path: hash}``."""

    root: Path
    outputs: dict[str, None] = field(default_factory=dict)
    inputs: dict[str, str] = field(default_factory=dict)


_current: ContextVar[Record | None] = ContextVar("cssat_record", default=None)


def digest(data: bytes) -> str:
    """BLAKE2b (16 bytes) of ``data``, hex — the hash of every manifest."""
    return hashlib.blake2b(data, digest_size=16).hexdigest()


@contextmanager
def recording(root: str | os.PathLike) -> Iterator[Record]:
    """Record the outputs below ``root`` and the inputs read within the block."""
    rec = Record(Path(root).resolve())
    token = _current.set(rec)
    try:
        yield rec
    finally:
        _current.reset(token)


def note_output(path: str | os.PathLike) -> None:
    """Note ``path`` as a result of the current recording (ignored outside it or outside its root)."""
    rec = _current.get()
    if rec is None:
        return
    try:
        rel = Path(path).resolve().relative_to(rec.root)
    except ValueError:  # not below the run's directory (a cache, a sweep's files)
        return
    rec.outputs[rel.as_posix()] = None


def read_input(path: str | os.PathLike, max_bytes: int | None = None, field: str = "path") -> bytes:
    """The bytes of the input file ``path``, noted with their hash in the current recording; a
    file larger than ``max_bytes`` is refused (a FieldError naming ``field``) before it is read."""
    if max_bytes is not None and os.path.isfile(path):
        size = os.path.getsize(path)
        if size > max_bytes:
            raise FieldError(field, f"{os.fspath(path)!r} is {size / 2**20:.0f} MiB, more than the "
                                    f"{max_bytes / 2**20:.0f} MiB an input of this kind may be")
    try:
        data = Path(path).read_bytes()
    except OSError as err:  # the user's input: a field error, not a machine fault
        raise FieldError(field, f"cannot read {os.fspath(path)!r}: {err.strerror or err}") from None
    rec = _current.get()
    if rec is not None:
        rec.inputs[os.path.abspath(os.fspath(path))] = digest(data)
    return data
