"""Shadows resolved below a facet: the lit-and-seen fraction of each facet from rays cast at many
points on it (:func:`cssat.optics.photometry.shadow_mask`'s ``resolution_m``).

A centroid ray makes a facet wholly lit or wholly dark, so a shadow edge moves over a facet in one
step: a light curve of a coarse mesh (a bus face in 0.8 m cells) carries steps that the satellite
does not have, of the size of the photometric noise (BENCHMARKS.md, "Converged shadows"). Here a
facet of longest edge ``ℓ`` is split ``L = ⌈log₂(ℓ / resolution_m)⌉`` times at its edges'
midpoints (``4^L`` equal sub-triangles, each edge ≤ ``resolution_m``); a ray pair (to the Sun, to
the observer) leaves each sub-triangle's centroid, and the facet's visibility is the fraction of
its sub-triangles neither self- nor observer-shadowed — exactly the mean, over the children, of the
centroid visibility of the mesh subdivided to ``resolution_m`` (``trimesh.remesh.subdivide_to_size``),
without building that mesh. :func:`lit_and_seen` and :func:`any_hit` (the ray engine's occlusion query) cast the rays of
:func:`~cssat.optics.photometry.shadow_mask` at the centroids too.

ASSUMPTIONS: flat facets (the sub-triangles are in the facet's plane, at its normal's offset);
equal weights (midpoint subdivision gives sub-triangles of equal area); at most :data:`MAX_LEVEL`
splits (``4^6`` points) a facet.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import torch

from cssat._checks import float_param

__all__ = ["MAX_LEVEL", "any_hit", "barycentric_points", "facet_levels", "lit_and_seen", "sampled_visibility"]

#: the most midpoint splits of one facet (4**MAX_LEVEL = 4096 rays a facet and direction)
MAX_LEVEL = 6
#: rays cast in one batch (memory: ~50 bytes a ray)
_CHUNK_RAYS = 2_000_000


def barycentric_points(level: int) -> np.ndarray:
    """``(4**level, 3)`` barycentric coordinates of the centroids of a triangle's ``level``-fold
    midpoint subdivision (``n = 2**level`` segments an edge: ``n(n+1)/2`` upright and ``n(n−1)/2``
    inverted sub-triangles, all of area ``1/n²`` of the facet's)."""
    n = 2**level
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    up = (i + j) <= n - 1
    down = (i + j) <= n - 2
    u = np.concatenate([(i[up] + 1 / 3) / n, (i[down] + 2 / 3) / n])
    v = np.concatenate([(j[up] + 1 / 3) / n, (j[down] + 2 / 3) / n])
    return np.stack([1.0 - u - v, u, v], axis=1)


def facet_levels(triangles: np.ndarray, resolution_m: float) -> np.ndarray:
    """``(F,)`` the splits ``L`` each facet of ``triangles (F, 3, 3)`` (m) needs for every edge of
    its sub-triangles to be at most ``resolution_m`` (module docstring), capped at
    :data:`MAX_LEVEL`."""
    edges = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(axis=1)
    with np.errstate(divide="ignore"):
        lev = np.ceil(np.log2(np.maximum(edges, 1e-300) / resolution_m))
    return np.clip(lev, 0, MAX_LEVEL).astype(np.int64)


def check_resolution(resolution_m: Any) -> float | None:
    """``resolution_m`` checked: None (centroid rays) or a finite length > 0 (m)."""
    return None if resolution_m is None else float_param(resolution_m, "resolution_m", 0.0, open_lo=True)


def sampled_visibility(triangles: np.ndarray, normals: np.ndarray, ti: np.ndarray, fi: np.ndarray,
                       sun: np.ndarray, observer: np.ndarray, resolution_m: float, offset: float, inter: Any,
                       threaded: bool) -> np.ndarray:
    """``(n,)`` float64 in [0, 1]: the fraction of facet ``fi[k]`` lit and seen at step ``ti[k]``
    (module docstring). ``triangles (F, 3, 3)``, ``normals (F, 3)`` the mesh's; ``sun, observer
    (T, 3)`` unit vectors; ``offset`` (m) along the normal; ``inter`` the ray engine
    (:func:`any_hit`'s, with ``threaded``)."""
    levels = facet_levels(triangles, resolution_m)
    out = np.zeros(len(ti), dtype=np.float64)
    for lev in np.unique(levels[fi]):
        bary = barycentric_points(int(lev))
        k = len(bary)
        sel = np.flatnonzero(levels[fi] == lev)
        step = max(1, _CHUNK_RAYS // k)
        for s in range(0, len(sel), step):
            idx = sel[s:s + step]
            f, t = fi[idx], ti[idx]
            pts = np.einsum("pj,njc->npc", bary, triangles[f]) + offset * normals[f][:, None, :]
            seen = lit_and_seen(inter, pts.reshape(-1, 3), np.repeat(sun[t], k, axis=0),
                                np.repeat(observer[t], k, axis=0), threaded)
            out[idx] = seen.reshape(-1, k).mean(axis=1)
    return out


def lit_and_seen(inter: Any, origins: np.ndarray, sun: np.ndarray, observer: np.ndarray, threaded: bool) -> np.ndarray:
    """``(N,)`` bool: the ray from each of ``origins (N, 3)`` towards ``sun (N, 3)`` hits nothing,
    nor (cast only for those still lit) the one towards ``observer (N, 3)`` (:func:`any_hit`)."""
    blocked = np.zeros(len(origins), dtype=bool)
    for dirs in (sun, observer):
        todo = np.flatnonzero(~blocked)
        if len(todo):
            blocked[todo] |= any_hit(inter, origins[todo], dirs[todo], threaded)
    return ~blocked


def any_hit(inter: Any, origins: np.ndarray, dirs: np.ndarray, threaded: bool) -> np.ndarray:
    """Does each ray (unit ``dirs``) hit the mesh? With Embree, an occlusion query straight on
    trimesh's Embree scene (about 3× faster than ``intersects_any``, which finds the first hit),
    over ``torch.get_num_threads()`` threads for large batches (Embree releases the GIL and its
    queries on a committed scene are thread-safe)."""
    scene = getattr(inter, "_scene", None) if threaded else None
    if scene is not None and hasattr(scene, "run"):

        def query(o, d):
            occ = scene.run(np.ascontiguousarray(o, dtype=np.float32), np.ascontiguousarray(d, dtype=np.float32),
                            query="OCCLUDED")
            return np.asarray(occ) != -1
    else:

        def query(o, d):
            return np.asarray(inter.intersects_any(o, d), dtype=bool)

    threads = torch.get_num_threads()
    if not threaded or threads < 2 or len(origins) < 100_000:
        return query(origins, dirs)

    parts = np.array_split(np.arange(len(origins)), threads)
    with ThreadPoolExecutor(threads) as pool:
        hits = list(pool.map(lambda p: query(origins[p], dirs[p]), parts))
    return np.concatenate(hits)
