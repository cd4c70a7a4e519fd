"""The extended Gaussian image (EGI) and the light curve's sensing operator in it.

Without shadowing, a body of facets with normals ``n_k``, areas ``A_k`` and one BRDF ``f``
sends, per unit solar irradiance and at unit range,

    ``y(t) = Σ_k G(t, k) a_k``,  ``G(t, k) = f(n_k, s_t, o_t) max(0, s_t·n_k) max(0, o_t·n_k)``

with ``s_t``, ``o_t`` the Sun and observer directions in the body frame and ``a_k`` the area
(× albedo, for a Lambert ``f`` of albedo 1) facing ``n_k``: the EGI (Horn 1984; Kaasalainen &
Torppa 2001). ``G`` is known exactly from the geometry — compressed sensing with a real sensing
matrix. Assumptions: no self-shadowing or occlusion (exact for convex bodies), single
scattering, one BRDF shape for every facet (its albedo goes into ``a_k``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, int_param
from cssat.optics.brdf import Lambert
from cssat.scene import as_mesh
from cssat.sparse.differences import knn_differences
from cssat.sparse.operators import MatrixOperator

__all__ = ["EGIOperator", "egi", "egi_operator", "fibonacci_sphere", "geometry_matrix"]


def fibonacci_sphere(k: int, *, dtype: torch.dtype = torch.float64, device: Any = None) -> Tensor:
    """``k`` nearly uniform unit vectors ``(k, 3)`` on the sphere (the Fibonacci lattice: equal
    area per point, ``z = 1 − (2i + 1)/k``, golden-angle longitudes)."""
    k = int_param(k, "k", 1)
    i = torch.arange(k, dtype=torch.float64)
    z = 1 - (2 * i + 1) / k
    phi = math.pi * (3 - math.sqrt(5)) * i
    r = torch.sqrt(torch.clamp(1 - z * z, min=0))
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1).to(dtype=dtype, device=device)


class EGIOperator(MatrixOperator):
    """``G (T, K)`` as a :class:`~cssat.sparse.MatrixOperator` (``A``/``A_adjoint``, batched rows,
    the device and dtype of its inputs), with the ``normals (K, 3)`` it was built on."""

    def __init__(self, matrix: Tensor, normals: Tensor):
        super().__init__(matrix)
        self.register_buffer("normals", normals)

    def equalities(self) -> Any:
        """``C (3, K)``: the unknown's exact constraint ``C a = 0`` — a closed body's EGI sums to
        the zero vector, ``Σ a_k n_k = 0`` (Minkowski) — as a float64 array (the non-negative
        solvers' ``closure`` rows)."""
        return self.normals.detach().cpu().double().numpy().T

    def differences(self, k: int = 6) -> Any:
        """``D (E, K)`` sparse: the unknown's neighbours for TV — each normal to its ``k`` nearest."""
        return knn_differences(self.normals.detach().cpu().double().numpy(), k)


def egi_operator(sun_body: Any, obs_body: Any, normals: Any, brdf: Any = None) -> EGIOperator:
    """The light curve's sensing operator in the EGI: ``G(t, k) = f(n_k, s_t, o_t)
    max(0, s_t·n_k) max(0, o_t·n_k)`` for ``sun_body``, ``obs_body`` ``(T, 3)`` body-frame unit
    vectors from the object and ``normals (K, 3)``; ``brdf`` a :mod:`cssat.optics.brdf` object
    (default ``Lambert(1)``: ``G = (s·n)₊(o·n)₊/π``). Per unit irradiance and range: multiply
    by ``I₀ / r²`` for W/m². Follows the dtype and device of ``normals`` when it is a tensor."""
    ref = normals if isinstance(normals, Tensor) else None
    dtype = ref.dtype if ref is not None and ref.is_floating_point() else torch.float64
    device = ref.device if ref is not None else None
    S, O, N = (torch.as_tensor(x, dtype=dtype, device=device) for x in (sun_body, obs_body, normals))
    for name, x in (("sun_body", S), ("obs_body", O), ("normals", N)):
        if x.ndim != 2 or x.shape[1] != 3 or not bool(torch.isfinite(x).all()):
            raise FieldError(name, f"expected finite unit vectors (n, 3), got shape {tuple(x.shape)}")
    if S.shape != O.shape:
        raise FieldError("obs_body", f"{O.shape[0]} observer directions for {S.shape[0]} Sun directions")
    f = (brdf or Lambert(1.0)).evaluate(N[None], S[:, None], O[:, None])
    G = f * (S @ N.T).clamp_min(0) * (O @ N.T).clamp_min(0)
    return EGIOperator(G, N)


def lambert_scale(brdf: Any) -> float | None:
    """``albedo/π`` when ``brdf`` is ``None`` (Lambert, albedo 1) or exactly a
    :class:`~cssat.optics.brdf.Lambert`; ``None`` for any other BRDF."""
    return 1.0 / math.pi if brdf is None else brdf.albedo / math.pi if type(brdf) is Lambert else None


def geometry_matrix(sun_body: np.ndarray, obs_body: np.ndarray, normals: np.ndarray, brdf: Any = None) -> np.ndarray:
    """:func:`egi_operator`'s ``G`` as a float64 array for the search loops: ``(..., T, K)`` for
    body-frame ``sun_body``, ``obs_body`` ``(..., T, 3)`` and ``normals (K, 3)`` — for a Lambert
    surface by two clipped products in numpy (no tensor round trip), any other BRDF through
    :func:`egi_operator` batch by batch."""
    lam = lambert_scale(brdf)
    if lam is not None:
        return lam * np.clip(sun_body @ normals.T, 0, None) * np.clip(obs_body @ normals.T, 0, None)
    S = sun_body.reshape(-1, *sun_body.shape[-2:])
    O = obs_body.reshape(-1, *obs_body.shape[-2:])
    G = np.stack([egi_operator(s_, o_, normals, brdf).matrix().numpy() for s_, o_ in zip(S, O)])
    return G.reshape(*sun_body.shape[:-1], len(normals))


def egi(mesh: Any, *, decimals: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's own EGI: ``(normals (U, 3), areas (U,))`` — the facets' areas × their diffuse
    albedo ``cd`` summed over identical normals (rounded to ``decimals``), so that the mesh's
    Lambertian light curve without shadows is ``egi_operator(s, o, normals) @ areas``."""
    m = as_mesh(mesh)
    keep = m.areas > 0
    N = np.round(m.normals[keep], decimals) + 0.0
    w = (m.areas * m.cd)[keep]
    uniq, inv = np.unique(N, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    areas = np.bincount(inv, weights=w, minlength=len(uniq))
    # each group's normal: the area-weighted mean of its facets' own (equal to round-off)
    normals = np.stack([np.bincount(inv, weights=m.areas[keep] * m.normals[keep][:, i], minlength=len(uniq))
                        for i in range(3)], 1)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True), areas
