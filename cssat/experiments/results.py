"""A run's results as one set: a directory lock, a manifest of content hashes, and the resume check.

``metrics.json`` is written last and lists the result files *this run wrote* with their BLAKE2
hashes (``files``; recorded as they are written, :mod:`cssat._record`) and the hashes of the
input files it read, taken from the bytes it read (``inputs``: ``{path: hash}``, a target image,
a mesh). A directory holding another experiment's or config's set has that set moved aside
first (:func:`move_aside`). Before a run starts, the old
``metrics.json`` is removed first, so a run killed at any moment leaves a directory without a
complete set — never new arrays beside old metrics that say ``ok``. A reader (``resume``, the sweep
summary) trusts a directory only when every listed file is there with its hash.

``metrics.json`` covers itself: its key ``metrics_digest`` is the hash of the rest of it (canonical
JSON: sorted keys, no spaces), so an edited value — a ``psnr`` typed over, a file's hash replaced
in ``files`` — no longer matches, and the set is not complete (``resume`` runs again, the sweep
summary says ``corrupt``). It guards against edits and damage, not forgery: whoever recomputes the
digest can sign anything.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterable, Iterator

from filelock import FileLock, Timeout

from cssat._checks import FieldError
from cssat._record import digest
from cssat.experiments.files import as_json, write_json

__all__ = ["run_lock", "file_hash", "result_files", "check_complete", "clear_results", "move_aside", "load_saved",
           "write_metrics", "seal_problem", "SEAL"]

log = logging.getLogger("cssat")

LOCK = ".cssat.lock"
#: files of a run directory that are not results: Hydra's own, the log, the lock, metrics.json
_NOT_RESULTS = {"metrics.json", "app.log", LOCK, LOCK + ".pid", ".cssat-sweep"}


#: the key of ``metrics.json`` that holds the digest of the rest of it
SEAL = "metrics_digest"


def _canonical(data: dict) -> bytes:
    """``data`` without its seal as canonical JSON (sorted keys, no spaces, ASCII)."""
    return json.dumps({k: v for k, v in data.items() if k != SEAL}, sort_keys=True, separators=(",", ":"),
                      allow_nan=False).encode()


def write_metrics(out_dir: Path, metrics: dict[str, Any]) -> dict[str, Any]:
    """Write ``out_dir/metrics.json`` atomically with its seal (``metrics_digest``: the hash of
    the rest, see the module's docstring) and return what was written: ``metrics`` as JSON reads
    it back (numpy scalars as numbers, non-finite floats as null, other objects as strings)."""
    data = as_json(metrics)
    data[SEAL] = digest(_canonical(data))
    write_json(Path(out_dir) / "metrics.json", data)
    return data


def seal_problem(saved: dict) -> str | None:
    """Why ``saved`` (a ``metrics.json`` as read) is not as its run wrote it, or ``None``."""
    seal = saved.get(SEAL)
    if not isinstance(seal, str):
        return "metrics.json has no digest of itself (written by an older cssat or by hand)"
    try:
        ok = seal == digest(_canonical(saved))
    except (TypeError, ValueError):  # NaN or an object JSON does not write: not what cssat wrote
        ok = False
    return None if ok else "metrics.json changed since the run (its digest differs)"


def file_hash(path: str | os.PathLike, chunk: int = 1 << 22) -> str:
    """BLAKE2b (16 bytes) of a file's content, hex."""
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def result_files(out_dir: Path, names: Iterable[str]) -> dict[str, str]:
    """``{relative path: hash}`` of the result files ``names`` (relative to ``out_dir``) that this
    run wrote — its own files and nothing else (``metrics.json`` and temporary files excluded)."""
    out: dict[str, str] = {}
    for rel in sorted(set(names)):
        p = Path(out_dir) / rel
        if rel in _NOT_RESULTS or p.name.endswith(".tmp") or not p.is_file():
            continue
        out[rel] = file_hash(p)
    return out


def check_complete(out_dir: Path, saved: dict, sha: str, cfg: Any = None) -> str | None:
    """``None`` when ``saved`` (the old ``metrics.json``) describes a complete, current result
    set of config hash ``sha``; else the reason to run again. The input files the run read
    (``saved["inputs"]``: ``{path: hash of the bytes read}``) must still hash the same."""
    if saved.get("status") != "ok":
        return f"the last run ended {saved.get('status', 'without a status')}"
    why = seal_problem(saved)
    if why is not None:
        return why
    if saved.get("config_sha") != sha:
        return "the config changed"
    files = saved.get("files")
    if not isinstance(files, dict):
        return "the results have no manifest (an older cssat wrote them)"
    why = files_problem(out_dir, files)
    if why is not None:
        return why
    inputs = saved.get("inputs", {})
    if not isinstance(inputs, dict):
        return "the manifest's inputs are not a mapping"
    for path, h in inputs.items():
        if not os.path.isfile(path):
            return f"the input file {path} is gone"
        if file_hash(path) != h:
            return f"the input file {path} changed since it was read"
    return None


def files_problem(out_dir: Path, files: dict) -> str | None:
    """The first listed result file (``{relative path: hash}``) that is missing or no longer has
    its hash, as a reason; ``None`` when every one is there as written."""
    for rel, h in files.items():
        p = Path(out_dir) / str(rel)
        if not p.is_file():
            return f"{rel} is missing"
        if file_hash(p) != h:
            return f"{rel} changed since the run (its content hash differs)"
    return None


def move_aside(out_dir: Path, saved: dict | None, experiment: str | None, sha: str) -> Path | None:
    """When ``out_dir`` holds the result set of another experiment or config (``saved``, its
    ``metrics.json``), move that set's files and its ``metrics.json`` into
    ``out_dir/previous/<experiment>-<config_sha>/`` and return that folder; else ``None``. So a
    directory never shows another run's files beside this run's (a PNG of a ``figure_format=png``
    run beside an SVG run, a light curve beside Simulation 1)."""
    if not isinstance(saved, dict) or (saved.get("experiment") == experiment and saved.get("config_sha") == sha):
        return None
    files = saved.get("files") if isinstance(saved.get("files"), dict) else {}
    old = [rel for rel in files if isinstance(rel, str) and (Path(out_dir) / rel).is_file()]
    if not old:
        return None
    name = f"{saved.get('experiment') or 'run'}-{saved.get('config_sha') or 'unknown'}"
    dest = Path(out_dir) / "previous" / "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name))
    for rel in ["metrics.json", *old]:  # its status first: a kill midway leaves no "ok" beside missing files
        src = Path(out_dir) / rel
        if src.is_file() and ".." not in Path(rel).parts and not Path(rel).is_absolute():
            target = dest / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, target)
    log.warning("%s held the results of %s (another experiment or config): moved to %s", out_dir, name, dest)
    return dest


def clear_results(out_dir: Path) -> None:
    """Before a run: remove the old ``metrics.json`` first (a kill from now on leaves no ``ok``
    status), then temporary files a killed run left."""
    out_dir = Path(out_dir)
    (out_dir / "metrics.json").unlink(missing_ok=True)
    for p in out_dir.rglob(".*.tmp"):
        p.unlink(missing_ok=True)


@contextmanager
def run_lock(out_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out_dir`` (``filelock`` on ``out_dir/.cssat.lock``: ``flock`` on
    POSIX, ``msvcrt`` on Windows) for a run; a second run into the same directory is refused at
    once with a FieldError naming it. The holder's pid is in ``.cssat.lock.pid``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(out_dir / LOCK), timeout=0)
    pid_file = out_dir / (LOCK + ".pid")
    try:
        lock.acquire()
    except Timeout:
        try:
            other = pid_file.read_text().strip() or "another process"
        except OSError:
            other = "another process"
        raise FieldError("hydra.run.dir", f"{out_dir} is in use by another cssat run (pid {other}); "
                          "wait for it or choose another directory") from None
    try:
        pid_file.write_text(str(os.getpid()))
        yield
    finally:
        lock.release()


def load_saved(out_dir: Path) -> dict | None:
    """The old ``metrics.json`` of ``out_dir``, or ``None`` when absent or unreadable."""
    try:
        return json.loads((Path(out_dir) / "metrics.json").read_text())
    except (OSError, ValueError):
        return None
