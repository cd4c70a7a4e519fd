"""What Simulations 2 and 3 share: the rendered reference set (cached on disk) and a progress bar."""

from __future__ import annotations

import hashlib
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from cssat.experiments.common import _atomic, require_float, require_int

log = logging.getLogger("cssat")

CACHE_VERSION = 1  # bump when the rendering of reference images changes


class Progress:
    """A one-line progress bar on stderr, silent when stderr is not a terminal."""

    def __init__(self, total: int, label: str):
        self.total, self.label, self.t0 = max(int(total), 1), label, time.perf_counter()
        self.on = sys.stderr.isatty()
        self.done = 0

    def update(self, n: int = 1) -> None:
        self.done += n
        if self.on:
            frac = self.done / self.total
            el = time.perf_counter() - self.t0
            eta = el / frac - el if frac > 0 else 0.0
            bar = "#" * int(30 * frac)
            sys.stderr.write(f"\r{self.label} [{bar:<30}] {self.done}/{self.total} {el:.0f}s eta {eta:.0f}s")
            sys.stderr.flush()

    def close(self) -> float:
        el = time.perf_counter() - self.t0
        if self.on:
            sys.stderr.write("\n")
        log.info("%s: %.1f s", self.label, el)
        return el


def reference_settings(cfg: Any, seed: int) -> int:
    """The reference set's seed (``reference.seed``, null: ``seed + 1000``), with ``reference.noise``
    and ``reference.model`` checked before any work."""
    from cssat.experiments.build import build_model

    ref = cfg.reference
    require_float(ref.get("noise", 0.0), "reference.noise", lo=0.0)
    build_model(ref.model, "reference.model")
    s = ref.get("seed")
    return seed + 1000 if s is None else require_int(s, "reference.seed", 0)


def _model_and_key(ref: Any, size: int, n: int, seed: int, noise: float, shadows: bool):
    from cssat.experiments.build import build_model

    mesh = build_model(ref.model, "reference.model")
    h = hashlib.sha256()
    for a in (mesh.vertices, mesh.faces, mesh.cd, mesh.cs):
        h.update(np.ascontiguousarray(np.asarray(a)).tobytes())
    spec = {"v": CACHE_VERSION, "mesh": h.hexdigest(), "size": size, "n": n, "seed": seed,
            "noise": noise, "shadows": bool(shadows), "normalize": True, "fov_m": None}
    key = hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:20]
    return mesh, key, spec


def reference_set(cfg: Any, size: int, n: int, seed: int):
    """``(n, size, size)`` float32 reference images (Astra-like model by default, random Sun and
    view directions, white noise ``reference.noise`` × each image's maximum), rendered in chunks
    with a progress bar, or read from the on-disk cache.

    The cache file (``cache_dir/refs-<key>.npy``) is keyed by everything that defines the set —
    the mesh's vertices, faces and BRDF constants, size, count, seed, noise, shadows and a version
    — so a sweep renders each set once. ``cache_dir: null`` disables the cache.
    """
    import torch

    from cssat.data import ReferenceImages

    ref = cfg.reference
    noise = require_float(ref.get("noise", 0.0), "reference.noise", lo=0.0)
    shadows = bool(ref.get("shadows", True))
    mesh, key, spec = _model_and_key(ref, size, n, seed, noise, shadows)
    cache_dir = cfg.get("cache_dir")
    path = Path(str(cache_dir)) / f"refs-{key}.npy" if cache_dir else None
    if path is not None and path.exists():
        arr = np.load(path, mmap_mode="r")
        if arr.shape == (n, size, size) and arr.dtype == np.float32:
            t = time.perf_counter()
            out = torch.from_numpy(np.array(arr))
            log.info("reference set: %d images %d² from the cache %s (%.1f s)", n, size, path, time.perf_counter() - t)
            return out, True
    ds = ReferenceImages(mesh, size, n, seed=seed, noise=noise, shadows=shadows, dtype=torch.float32)
    out = torch.empty(n, size, size, dtype=torch.float32)
    chunk = max(1, min(1024, (64 << 20) // (size * size * 8)))
    bar = Progress(n, f"rendering {n} reference images {size}²")
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        out[s:e] = ds.batch(s, e)
        bar.update(e - s)
    bar.close()
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)

        def w(tmp):
            with open(tmp, "wb") as f:
                np.save(f, out.numpy())

        _atomic(path, w)
        _atomic(path.with_suffix(".json"), lambda tmp: Path(tmp).write_text(json.dumps(spec, indent=1)))
    return out, False

