"""The rendered reference sets of the operator estimates (``reference=full_rank|sparse|min_norm``),
cached on disk."""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import shutil
import stat
import time
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from filelock import FileLock
from numpy.lib import format as npf

from cssat._progress import progress_bar
from cssat._tmpfiles import atomic_write

if TYPE_CHECKING:
    import torch

    from cssat.scene import Mesh


log = logging.getLogger("cssat")

CACHE_VERSION = 3  # bump when the rendering of reference images (or the entry format) changes


def _key(mesh, size: int, n: int, seed: int, noise: float, shadows: bool):
    """The entry's key and spec: everything the rendered set depends on — the mesh's geometry and
    BRDF constants, its solar-array drives (each joint's facets, axis, pivot, normal, angle,
    tracking and limits), the glint model the renderer uses (:data:`cssat.optics.photometry.DEFAULT_GLINT`),
    size, count, seed, noise, shadows and :data:`CACHE_VERSION`."""
    from cssat.optics.photometry import check_glint  # heavy: cssat.optics imports torch

    h = hashlib.sha256()
    for a in (mesh.vertices, mesh.faces, mesh.cd, mesh.cs):
        h.update(np.ascontiguousarray(np.asarray(a)).tobytes())
    for j in getattr(mesh, "joints", ()) or ():  # an articulated mesh: its drives change every image
        for a in (j.facets, j.axis, j.pivot, j.normal, j.limits_deg, [j.angle0_deg]):
            h.update(np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes())
        h.update(str(j.tracking).encode())
    spec = {"v": CACHE_VERSION, "mesh": h.hexdigest(), "size": size, "n": n, "seed": seed,
            "noise": noise, "shadows": bool(shadows), "normalize": True, "fov_m": None, "glint": check_glint(None)}
    key = hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:20]
    return key, spec


def _array_hash(a: np.ndarray) -> str:
    return hashlib.blake2b(np.ascontiguousarray(a).data, digest_size=16).hexdigest()


def _remove(p: Path) -> None:
    """Remove whatever is at ``p`` (a file, a FIFO, a directory); errors are ignored."""
    try:
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
    except OSError:
        pass


def _regular(p: Path) -> bool | None:
    """``True`` for a regular file, ``None`` when nothing is there, ``False`` for anything else
    (a directory, a FIFO, a device, a socket): never opened, so never a hang."""
    try:
        return stat.S_ISREG(os.stat(p).st_mode)
    except FileNotFoundError:
        return None


def _check_npy(path: Path, shape: tuple[int, ...]) -> str | None:
    """Why the ``.npy`` at ``path`` is not a C-ordered float32 array of ``shape`` whose data fill
    the file exactly, read from its header only (nothing allocated), or ``None``."""
    with open(path, "rb") as f:
        version = npf.read_magic(f)
        if version == (1, 0):
            hdr = npf.read_array_header_1_0(f, max_header_size=10000)
        elif version == (2, 0):
            hdr = npf.read_array_header_2_0(f, max_header_size=10000)
        else:
            return f"unknown .npy version {version}"
        offset = f.tell()
    got_shape, fortran, dtype = hdr
    if tuple(got_shape) != tuple(shape) or dtype != np.dtype("<f4") or fortran:
        return f"its header declares {dtype} {tuple(got_shape)}, expected float32 {tuple(shape)}"
    if os.path.getsize(path) != offset + 4 * math.prod(shape):
        return "its size does not match its header (truncated or extended)"
    return None


def _read_entry(path: Path, key: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """The cached array at ``path`` when its sidecar ``.json`` names ``key`` and the array has
    ``shape``, float32 and the recorded content hash; ``None`` when there is no complete entry.
    A damaged entry — unreadable, truncated, of the wrong shape, dtype or hash, metadata that is
    not a JSON object, a header declaring another shape (checked before anything is allocated), a
    directory, FIFO or device in place of a file (never opened) — is logged with its path and
    removed, so that it is rendered again."""
    meta_path = path.with_suffix(".json")
    kinds = (_regular(meta_path), _regular(path))
    if kinds[0] is None:
        return None  # absent, or being written by another run (its .json comes last)
    arr, why = None, None
    if False in kinds or kinds[1] is None:
        why = "an entry is missing or is not a regular file (a directory, FIFO or device)"
    else:
        try:
            meta = json.loads(meta_path.read_text())
            if not isinstance(meta, dict):
                why = f"its metadata is a JSON {type(meta).__name__}, not an object"
            elif meta.get("key") != key:
                why = f"its key {meta.get('key')!r} is not {key!r}"
            else:
                why = _check_npy(path, shape)
            if why is None:
                arr = np.load(path, allow_pickle=False)
                if meta.get("hash") != _array_hash(arr):
                    why = "its content hash differs from the one recorded (the file was changed or damaged)"
        except (OSError, ValueError, EOFError, UnicodeDecodeError) as err:
            why = f"it cannot be read ({type(err).__name__}: {err})"
    if why is None:
        return arr
    log.warning("reference cache: %s is damaged (%s): removed, rendering it again", path, why)
    for p in (path, meta_path):
        _remove(p)
    return None


@contextmanager
def _key_lock(path: Path):
    """An exclusive lock per cache entry (``filelock``): concurrent sweeps render each set once
    (the second waits for the first, then reads its entry). Yields ``True`` when held; ``False``
    when the cache cannot be written (a read-only cache: it is only read). Anything but a regular
    file in the lock's place is removed first."""
    lock_path = path.with_suffix(".lock")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError:
        yield False
        return
    if _regular(lock_path) is False:
        log.warning("reference cache: %s is not a regular file: removed", lock_path)
        _remove(lock_path)
    lock = FileLock(str(lock_path))
    try:
        lock.acquire()
    except OSError:  # read-only cache directory
        yield False
        return
    try:
        yield True
    finally:
        lock.release()


def reference_set(cache_dir: str | None, size: int, n: int, seed: int, mesh: Mesh, noise: float, shadows: bool,
                  progress: bool | None = None) -> tuple[torch.Tensor, bool]:
    """``(n, size, size)`` float32 reference images of ``mesh`` (``reference.model``; the
    Astra-like model by default), random Sun and view directions and white noise of ``noise`` ×
    each image's maximum, rendered in chunks with a progress bar, or read from the on-disk cache
    ``cache_dir``; returns ``(images, read from the cache)``.

    A cache entry (``cache_dir/refs-<key>.npy`` and its ``.json``) is keyed by everything that
    defines the set (:func:`_key`: the mesh's vertices, faces, BRDF constants and array drives,
    the glint model, size, count, seed, noise, shadows and a version) — so a sweep renders each set once; the ``.json`` (written last) holds
    the key and the array's content hash, checked on every read: a damaged entry is logged,
    removed and rendered again. Runs that need one entry at once take turns on a lock file.
    ``cache_dir: null`` disables the cache.
    """
    key, spec = _key(mesh, size, n, seed, noise, shadows)
    if not cache_dir:
        return _render(mesh, size, n, seed, noise, shadows, progress), False
    path = Path(str(cache_dir)) / f"refs-{key}.npy"
    with _key_lock(path) as writable:
        t = time.perf_counter()
        arr = _read_entry(path, key, (n, size, size))
        if arr is not None:
            import torch  # heavy: torch (~1 s); the module imports without it

            log.info("reference set: %d images %d² from the cache %s (%.1f s)", n, size, path, time.perf_counter() - t)
            return torch.from_numpy(arr), True
        out = _render(mesh, size, n, seed, noise, shadows, progress)
        if writable:
            _write_entry(path, out.numpy(), key, spec)
        else:
            log.warning("reference cache: %s cannot be written (read-only?): the set is not cached", path.parent)
    return out, False


def _write_entry(path: Path, arr: np.ndarray, key: str, spec: dict) -> None:
    """Write a cache entry (the array, then its ``.json``); a disk that refuses it (full,
    read-only) costs the entry, not the run: logged, and what was written removed."""
    try:
        for entry in (path, path.with_suffix(".json")):  # under the entry's lock, any is stale
            for stale in entry.parent.glob(f".{entry.name}.*.tmp"):
                stale.unlink(missing_ok=True)

        def w(tmp):
            with open(tmp, "wb") as f:
                np.save(f, arr)

        atomic_write(path, w, result=False)
        meta = {"key": key, "hash": _array_hash(arr), "shape": list(arr.shape), "dtype": "float32", "spec": spec}
        atomic_write(path.with_suffix(".json"), lambda tmp: Path(tmp).write_text(json.dumps(meta, indent=1)), result=False)
    except OSError as err:
        log.warning("reference cache: could not write %s (%s): the run goes on without caching it", path,
                    err.strerror or err)
        path.unlink(missing_ok=True)


def _render(mesh, size: int, n: int, seed: int, noise: float, shadows: bool, progress: bool | None):
    import torch  # heavy: torch (~1 s); the module imports without it

    from cssat.data import ReferenceImages  # heavy: cssat.data imports torch

    ds = ReferenceImages(mesh, size, n, seed=seed, noise=noise, shadows=shadows, dtype=torch.float32)
    out = torch.empty(n, size, size, dtype=torch.float32)
    chunk = max(1, min(1024, (64 << 20) // (size * size * 8)))
    t = time.perf_counter()
    with progress_bar(n, f"rendering {n} reference images {size}²", progress, unit="image") as bar:
        for s in range(0, n, chunk):
            e = min(n, s + chunk)
            out[s:e] = ds.batch(s, e)
            bar.update(e - s)
    log.info("rendered %d reference images %d² in %.1f s", n, size, time.perf_counter() - t)
    return out
