"""A run's results as one set: a directory lock, a manifest of content hashes, and the resume check.

``metrics.json`` is written last and lists every result file of the run with its BLAKE2 hash
(``files``) and the hashes of the input files the run read (``inputs``: ``target.image``,
``model.path``, ``reference.model.path`` when they are files). Before a run starts, the old
``metrics.json`` is removed first, so a run killed at any moment leaves a directory without a
complete set — never new arrays beside old metrics that say ``ok``. A reader (``resume``, the sweep
summary) trusts a directory only when every listed file is there with its hash.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

from cssat._checks import FieldError

__all__ = ["run_lock", "file_hash", "result_files", "input_files", "check_complete", "clear_results"]

log = logging.getLogger("cssat")

LOCK = ".cssat.lock"
#: files of a run directory that are not results: Hydra's own, the log, the lock, metrics.json
_NOT_RESULTS = {"metrics.json", "app.log", LOCK, ".cssat-sweep"}
#: config keys naming input files whose content defines the results
INPUT_KEYS = ("target.image", "model.path", "reference.model.path")


def file_hash(path: str | os.PathLike, chunk: int = 1 << 22) -> str:
    """BLAKE2b (16 bytes) of a file's content, hex."""
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def result_files(out_dir: Path) -> dict[str, str]:
    """``{relative path: hash}`` of every result file in ``out_dir`` (not ``.hydra/``, the log,
    the lock, ``metrics.json`` or temporary files)."""
    out: dict[str, str] = {}
    for p in sorted(Path(out_dir).rglob("*")):
        rel = p.relative_to(out_dir)
        if not p.is_file() or rel.parts[0] == ".hydra" or str(rel) in _NOT_RESULTS or p.name.endswith(".tmp"):
            continue
        out[rel.as_posix()] = file_hash(p)
    return out


def input_files(cfg: Any) -> dict[str, str]:
    """``{config key: hash}`` of the input files named by :data:`INPUT_KEYS` that exist."""
    from omegaconf import OmegaConf

    out = {}
    for key in INPUT_KEYS:
        try:
            value = OmegaConf.select(cfg, key) if OmegaConf.is_config(cfg) else None
        except Exception:  # a key of another experiment
            value = None
        if isinstance(value, str) and value and os.path.isfile(value):
            out[key] = file_hash(value)
    return out


def check_complete(out_dir: Path, saved: dict, sha: str, cfg: Any) -> str | None:
    """``None`` when ``saved`` (the old ``metrics.json``) describes a complete, current result
    set of config hash ``sha``; else the reason to run again."""
    if saved.get("status") != "ok":
        return f"the last run ended {saved.get('status', 'without a status')}"
    if saved.get("config_sha") != sha:
        return "the config changed"
    files = saved.get("files")
    if not isinstance(files, dict) or not files:
        return "the results have no manifest (an older cssat wrote them)"
    for rel, h in files.items():
        p = Path(out_dir) / rel
        if not p.is_file():
            return f"{rel} is missing"
        if file_hash(p) != h:
            return f"{rel} changed since the run (its content hash differs)"
    if input_files(cfg) != saved.get("inputs", {}):
        return "an input file changed (target.image / model.path)"
    return None


def clear_results(out_dir: Path) -> None:
    """Before a run: remove the old ``metrics.json`` first (a kill from now on leaves no ``ok``
    status), then temporary files a killed run left."""
    out_dir = Path(out_dir)
    (out_dir / "metrics.json").unlink(missing_ok=True)
    for p in out_dir.rglob(".*.tmp"):
        p.unlink(missing_ok=True)


@contextmanager
def run_lock(out_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out_dir`` (``flock`` on ``out_dir/.cssat.lock``) for a run; a
    second run into the same directory is refused at once with a FieldError naming it."""
    import fcntl

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fd = os.open(out_dir / LOCK, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            other = os.pread(fd, 64, 0).decode(errors="replace").strip() or "another process"
            raise FieldError("hydra.run.dir", f"{out_dir} is in use by another cssat run (pid {other}); "
                              "wait for it or choose another directory") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        os.close(fd)


def load_saved(out_dir: Path) -> dict | None:
    """The old ``metrics.json`` of ``out_dir``, or ``None`` when absent or unreadable."""
    try:
        return json.loads((Path(out_dir) / "metrics.json").read_text())
    except (OSError, ValueError):
        return None
