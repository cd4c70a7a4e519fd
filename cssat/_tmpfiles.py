"""Temporary files that a kill does not leave behind.

A result is written to a hidden temporary file beside it and renamed into place (atomic on
POSIX). A process killed with SIGKILL runs no cleanup of its own, so the temporary file of a write
in progress would stay. To remove it anyway, the first temporary file of a process starts a small
*guardian*: a child Python process, in a session of its own, that holds the read end of a pipe.
Before a temporary file is created its path is sent down the pipe, after it was renamed (or
removed) that is sent too. When the writing process ends — normally, by an exception, or killed
by any signal, even with its whole process group — the kernel closes the pipe; the guardian reads
end-of-file and removes whatever is still listed, then exits.

What this cannot cover: the guardian itself killed first (``kill -9`` of every process of the
user, a power cut, a machine that goes down). For those, the next run into the same directory
removes what it finds (:func:`cssat.experiments.results.clear_results`), and the reference cache
ignores and removes stale temporary files on its next write of that entry.
"""

from __future__ import annotations

import csv
import os
import secrets
import subprocess
import sys
import threading
from pathlib import Path

from cssat._record import note_output

# The guardian: read every record until the writer's end of the pipe closes, then remove the
# files registered ("+") and not released ("-"). Records are NUL-terminated file-system paths.
_GUARDIAN = r"""
import os, sys
live = set()
for rec in sys.stdin.buffer.read().split(b"\0"):
    if rec[:1] == b"+":
        live.add(rec[1:])
    elif rec[:1] == b"-":
        live.discard(rec[1:])
for p in live:
    try:
        os.unlink(p)
    except OSError:
        pass
"""

_lock = threading.Lock()
_guard: subprocess.Popen | None = None
_guard_pid: int | None = None  # the process that started it (a forked child starts its own)


def _send(flag: bytes, path: Path) -> None:
    global _guard, _guard_pid
    with _lock:
        if _guard is None or _guard_pid != os.getpid():
            try:
                _guard = subprocess.Popen(
                    [sys.executable, "-I", "-S", "-c", _GUARDIAN],
                    stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                    start_new_session=True,  # survives a kill of the writer's process group
                )
                _guard_pid = os.getpid()
            except OSError:  # no guardian: the next run's cleanup still removes leftovers
                _guard, _guard_pid = None, os.getpid()
                return
        if _guard is None:
            return
        try:
            _guard.stdin.write(flag + os.fsencode(os.path.abspath(path)) + b"\0")
            _guard.stdin.flush()
        except (OSError, ValueError):
            _guard = None


def temporary_path(path: Path) -> Path:
    """Create an empty hidden temporary file ``.NAME.<random>.tmp`` beside ``path`` (mode from
    the user's umask) and return its path; it is removed by the guardian if this process dies
    before :func:`release` is called for it."""
    path = Path(path)
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp"
        _send(b"+", tmp)  # listed before it exists: no moment where a kill leaves it unlisted
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:  # never ours: do not let the guardian remove it
            _send(b"-", tmp)
    raise FileExistsError(f"no free temporary name beside {path}")


def release(tmp: Path) -> None:
    """``tmp`` was renamed into place or removed: the guardian must leave that path alone."""
    _send(b"-", tmp)


def atomic_write(path: str | os.PathLike, write, result: bool = True) -> None:
    """Write ``path`` through ``write(tmp)`` on a temporary file beside it, then rename it into
    place: a reader sees the old file or the new one, never a part. The temporary file gets the
    mode the user's umask gives a new file, and is removed even when this process is killed.
    ``result``: the file is a result of the run being recorded (:mod:`cssat._record`; a cache
    entry or a sweep's bookkeeping passes ``False``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_path(path)
    try:
        write(str(tmp))
        os.replace(tmp, path)
        if result:
            note_output(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        release(tmp)


def atomic_csv(path: str | os.PathLike, rows: list, fieldnames: list | None = None) -> None:
    """Write ``rows`` (dicts) as a CSV with a header through :func:`atomic_write`; columns
    ``fieldnames`` (default: every key in the order first seen), missing values empty."""
    cols = fieldnames or list(dict.fromkeys(k for r in rows for k in r))

    def write(tmp):
        with open(tmp, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=cols, restval="")
            wr.writeheader()
            wr.writerows(rows)

    atomic_write(path, write)
