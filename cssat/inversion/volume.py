"""Volume IoU of two meshes by Monte Carlo points (the shape's score against the
TRUE mesh, not its convex hull)."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, bool_param, int_param
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
    return _centroid(_bodies(mesh))


def _centroid(bodies: list) -> np.ndarray:
    """:func:`volume_centroid` of the closed bodies ``bodies`` (:func:`_bodies`)."""
    if not bodies:
        raise FieldError("mesh", "no closed (watertight) body: no volume to compare")
    vol = np.array([abs(b.volume) for b in bodies])
    return np.sum([b.center_mass * v for b, v in zip(bodies, vol)], axis=0) / vol.sum()


def inside(mesh: Any, points: np.ndarray) -> np.ndarray:
    """``(P,)`` bool: each point inside one of the mesh's closed bodies. The mesh is split into
    connected components (vertices merged); the watertight ones with a volume are tested by ray
    parity (trimesh ``contains``). ASSUMPTION: open parts (zero-thickness panels, dishes) have no
    volume and are ignored."""
    return _inside(_bodies(mesh), points)


def _inside(bodies: list, points: np.ndarray) -> np.ndarray:
    """:func:`inside` of the closed bodies ``bodies`` (:func:`_bodies`)."""
    out = np.zeros(len(points), dtype=bool)
    for body in bodies:
        lo, hi = body.bounds
        box = np.all((points >= lo) & (points <= hi), axis=1)
        if box.any():
            out[box] |= body.contains(points[box])
    return out


def volume_iou(a: Any, b: Any, *, n_points: int = 200_000, seed: int = 0, align: bool = True,
               min_union: int | None = None, return_stderr: bool = False) -> float | tuple[float, float]:
    """``|A ∩ B| / |A ∪ B|`` of the closed bodies of meshes ``a`` and ``b`` in the same frame
    (no rotation, no rescaling; with ``align``, ``b`` translated so that its closed volume's
    centroid is ``a``'s: a light curve does not observe a translation), estimated from
    ``n_points`` uniform points in the bounding box of the two meshes' CLOSED bodies (open panels
    and dishes have no volume and do not widen the box: a runaway panel cannot thin the points
    out). Standard error ``sqrt(IoU (1 − IoU) / n_union)`` with ``n_union`` the points inside
    ``A ∪ B``; fewer than ``min_union`` of them (default ``min(1000, n_points // 10)``) is an error
    naming ``n_points`` (an estimate from a handful of points would read as exact).
    ``return_stderr``: ``(IoU, standard error)``."""
    if isinstance(n_points, bool) or not isinstance(n_points, int) or n_points < 100:
        raise FieldError("n_points", f"expected an integer >= 100, got {n_points!r}")
    bool_param(align, "align")
    bool_param(return_stderr, "return_stderr")
    min_union = int_param(min(1000, n_points // 10) if min_union is None else min_union, "min_union", 1, n_points)
    A, B = as_mesh(a), as_mesh(b)
    bodies_a = _bodies(A)  # split once: the centroid, the box and the points
    if align:
        B = Mesh(B.vertices + (_centroid(bodies_a) - volume_centroid(B)), B.faces, B.cd, B.cs)
    bodies_b = _bodies(B)
    bounds = [body.bounds for body in bodies_a + bodies_b]
    if not bounds:
        raise FieldError("mesh", "neither mesh has a closed (watertight) body: no volume to compare")
    lo, hi = np.min([q[0] for q in bounds], axis=0), np.max([q[1] for q in bounds], axis=0)
    pts = np.random.default_rng(seed).uniform(lo, hi, size=(n_points, 3))
    ia, ib = _inside(bodies_a, pts), _inside(bodies_b, pts)
    union = int((ia | ib).sum())
    if union < min_union:
        raise FieldError("n_points", f"only {union} of {n_points} points fell inside either closed body "
                         f"(fewer than min_union={min_union}): raise n_points for a usable IoU")
    iou = float((ia & ib).sum() / union)
    return (iou, float(np.sqrt(iou * (1 - iou) / union))) if return_stderr else iou
