"""The rendered reference sets of the operator estimates (``reference=full_rank|sparse|min_norm``),
cached on disk."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cssat._tmpfiles import atomic_write

if TYPE_CHECKING:
    import torch

    from cssat.scene import Mesh


log = logging.getLogger("cssat")

CACHE_VERSION = 2  # bump when the rendering of reference images (or the entry format) changes


def _key(mesh, size: int, n: int, seed: int, noise: float, shadows: bool):
    h = hashlib.sha256()
    for a in (mesh.vertices, mesh.faces, mesh.cd, mesh.cs):
        h.update(np.ascontiguousarray(np.asarray(a)).tobytes())
    spec = {"v": CACHE_VERSION, "mesh": h.hexdigest(), "size": size, "n": n, "seed": seed,
            "noise": noise, "shadows": bool(shadows), "normalize": True, "fov_m": None}
    key = hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:20]
    return key, spec


def _array_hash(a: np.ndarray) -> str:
    return hashlib.blake2b(np.ascontiguousarray(a).data, digest_size=16).hexdigest()


def _read_entry(path: Path, key: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """The cached array at ``path`` when its sidecar ``.json`` names ``key`` and the array has
    ``shape``, float32 and the recorded content hash; ``None`` when there is no complete entry.
    A damaged entry (unreadable, truncated, wrong shape or hash) is logged with its path and
    removed, so that it is rendered again."""
    meta_path = path.with_suffix(".json")
    if not meta_path.exists():
        return None  # absent, or being written by another run (its .json comes last)
    try:
        meta = json.loads(meta_path.read_text())
        arr = np.load(path, allow_pickle=False)
        why = None
        if meta.get("key") != key:
            why = f"its key {meta.get('key')!r} is not {key!r}"
        elif arr.shape != shape or arr.dtype != np.float32:
            why = f"it holds {arr.dtype} {arr.shape}, expected float32 {shape}"
        elif meta.get("hash") != _array_hash(arr):
            why = "its content hash differs from the one recorded (the file was changed or damaged)"
    except (OSError, ValueError, EOFError) as err:
        why, arr = f"it cannot be read ({type(err).__name__}: {err})", None
    if why is None:
        return arr
    log.warning("reference cache: %s is damaged (%s): removed, rendering it again", path, why)
    for p in (path, meta_path):
        p.unlink(missing_ok=True)
    return None


@contextmanager
def _key_lock(path: Path):
    """An exclusive lock per cache entry: concurrent sweeps render each set once (the second
    waits for the first, then reads its entry)."""
    import fcntl

    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path.with_suffix(".lock"), os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def reference_set(cache_dir: str | None, size: int, n: int, seed: int, mesh: Mesh, noise: float, shadows: bool,
                  progress: bool | None = None) -> tuple[torch.Tensor, bool]:
    """``(n, size, size)`` float32 reference images of ``mesh`` (``reference.model``; the
    Astra-like model by default), random Sun and view directions and white noise of ``noise`` ×
    each image's maximum, rendered in chunks with a progress bar, or read from the on-disk cache
    ``cache_dir``; returns ``(images, read from the cache)``.

    A cache entry (``cache_dir/refs-<key>.npy`` and its ``.json``) is keyed by everything that
    defines the set — the mesh's vertices, faces and BRDF constants, size, count, seed, noise,
    shadows and a version — so a sweep renders each set once; the ``.json`` (written last) holds
    the key and the array's content hash, checked on every read: a damaged entry is logged,
    removed and rendered again. Runs that need one entry at once take turns on a lock file.
    ``cache_dir: null`` disables the cache.
    """
    key, spec = _key(mesh, size, n, seed, noise, shadows)
    if not cache_dir:
        return _render(mesh, size, n, seed, noise, shadows, progress), False
    path = Path(str(cache_dir)) / f"refs-{key}.npy"
    with _key_lock(path):
        t = time.perf_counter()
        arr = _read_entry(path, key, (n, size, size))
        if arr is not None:
            import torch

            log.info("reference set: %d images %d² from the cache %s (%.1f s)", n, size, path, time.perf_counter() - t)
            return torch.from_numpy(arr), True
        for entry in (path, path.with_suffix(".json")):  # under the entry's lock, any is stale
            for stale in entry.parent.glob(f".{entry.name}.*.tmp"):
                stale.unlink(missing_ok=True)
        out = _render(mesh, size, n, seed, noise, shadows, progress)

        def w(tmp):
            with open(tmp, "wb") as f:
                np.save(f, out.numpy())

        atomic_write(path, w)
        meta = {"key": key, "hash": _array_hash(out.numpy()), "shape": [n, size, size], "dtype": "float32", "spec": spec}
        atomic_write(path.with_suffix(".json"), lambda tmp: Path(tmp).write_text(json.dumps(meta, indent=1)))
    return out, False


def _render(mesh, size: int, n: int, seed: int, noise: float, shadows: bool, progress: bool | None):
    import torch

    from cssat._progress import progress_bar

    from cssat.data import ReferenceImages

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
