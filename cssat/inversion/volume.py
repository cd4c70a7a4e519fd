"""Volume IoU of two meshes by Monte Carlo points (the shape's score against the
TRUE mesh, not its convex hull)."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.scene.mesh import Mesh, as_mesh

__all__ = ["volume_iou", "inside", "volume_centroid"]


def _bodies(mesh: Any) -> list:
    """The mesh's closed bodies with a volume (trimesh, vertices merged)."""
    import trimesh  # heavy: trimesh, only to score a shape

    m = as_mesh(mesh)
    tm = trimesh.Trimesh(m.vertices, m.faces, process=True)  # merge the faces' duplicated vertices
    # a two-sided plate closes on itself with no volume
    return [b for b in tm.split(only_watertight=True) if abs(b.volume) > 1e-9 * max(b.area, 1e-300) ** 1.5]


def volume_centroid(mesh: Any) -> np.ndarray:
    """``(3,)`` the centroid of the mesh's closed bodies' volume (m); an error when it has none."""
    bodies = _bodies(mesh)
    if not bodies:
        raise FieldError("mesh", "no closed (watertight) body: no volume to compare")
    vol = np.array([abs(b.volume) for b in bodies])
    return np.sum([b.center_mass * v for b, v in zip(bodies, vol)], axis=0) / vol.sum()


def inside(mesh: Any, points: np.ndarray) -> np.ndarray:
    """``(P,)`` bool: each point inside one of the mesh's closed bodies. The mesh is split into
    connected components (vertices merged); the watertight ones with a volume are tested by ray
    parity (trimesh ``contains``). ASSUMPTION: open parts (zero-thickness panels, dishes) have no
    volume and are ignored."""
    out = np.zeros(len(points), dtype=bool)
    for body in _bodies(mesh):
        lo, hi = body.bounds
        box = np.all((points >= lo) & (points <= hi), axis=1)
        if box.any():
            out[box] |= body.contains(points[box])
    return out


def volume_iou(a: Any, b: Any, *, n_points: int = 200_000, seed: int = 0, align: bool = True) -> float:
    """``|A ∩ B| / |A ∪ B|`` of the closed bodies of meshes ``a`` and ``b`` in the same frame
    (no rotation, no rescaling; with ``align``, ``b`` translated so that its closed volume's
    centroid is ``a``'s: a light curve does not observe a translation), estimated from ``n_points`` uniform points in the union of
    their bounding boxes (standard error ≈ ``sqrt(IoU (1 − IoU) / n_inside_union)``)."""
    if isinstance(n_points, bool) or not isinstance(n_points, int) or n_points < 100:
        raise FieldError("n_points", f"expected an integer >= 100, got {n_points!r}")
    A, B = as_mesh(a), as_mesh(b)
    if align:
        B = Mesh(B.vertices + (volume_centroid(A) - volume_centroid(B)), B.faces, B.cd, B.cs)
    lo = np.minimum(A.vertices.min(0), B.vertices.min(0))
    hi = np.maximum(A.vertices.max(0), B.vertices.max(0))
    pts = np.random.default_rng(seed).uniform(lo, hi, size=(n_points, 3))
    ia, ib = inside(A, pts), inside(B, pts)
    union = int((ia | ib).sum())
    if union == 0:
        raise FieldError("mesh", "neither mesh has a closed (watertight) body: no volume to compare")
    return float((ia & ib).sum() / union)
