"""Difference operators ``D`` for total variation, ``TV(x) = Σ_g ‖(Dx)_g‖₂``.

One kind of object serves every TV solver: the image gradient (forward differences along both
axes, Neumann boundary, grouped per pixel: the isotropic TV) and any graph's differences (one row
``e_i − e_j`` per edge — an image grid's, or each point's nearest neighbours on a sphere — each
its own group: the anisotropic TV). A :class:`Differences` maps ``x (B, N)`` to ``Dx (B, G, *E)``
whose axis 1 is the group (the components shrunk together), and back by :meth:`~Differences.adjoint`.
Both the primal–dual and the ADMM solvers, and the non-negative solvers, import it from here.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError

__all__ = ["image_shape", "Differences", "ImageGradient", "GraphDifferences", "tv_gradient", "tv_divergence", "grid_differences",
           "knn_differences"]


def tv_gradient(x: Tensor) -> Tensor:
    """Forward differences of images ``x (B, H, W)`` with Neumann boundary: ``(B, 2, H, W)``."""
    g = torch.zeros(x.shape[0], 2, *x.shape[1:], dtype=x.dtype, device=x.device)
    g[:, 0, :-1, :] = x[:, 1:, :] - x[:, :-1, :]
    g[:, 1, :, :-1] = x[:, :, 1:] - x[:, :, :-1]
    return g


def tv_divergence(p: Tensor) -> Tensor:
    """``div = −∇ᵀ``: the negative adjoint of :func:`tv_gradient`, ``(B, 2, H, W) → (B, H, W)``."""
    d = torch.zeros(p.shape[0], *p.shape[2:], dtype=p.dtype, device=p.device)
    d[:, :-1, :] += p[:, 0, :-1, :]
    d[:, 1:, :] -= p[:, 0, :-1, :]
    d[:, :, :-1] += p[:, 1, :, :-1]
    d[:, :, 1:] -= p[:, 1, :, :-1]
    return d


def image_shape(shape: Sequence[int], n_pixels: int) -> tuple[int, int]:
    """``shape`` as an image's ``(H, W)`` of ``n_pixels`` pixels, or a :class:`FieldError` naming ``shape``."""
    if len(tuple(shape)) != 2:
        raise FieldError("shape", f"total variation works on images (H, W); the unknown has shape {tuple(shape)}")
    H, W = (int(s) for s in shape)
    if H * W != n_pixels:
        raise FieldError("shape", f"{tuple(shape)} does not match the operator's {n_pixels} pixels")
    return H, W


class Differences:
    """A difference operator ``D``: ``forward (B, N) → (B, G, *E)`` (axis 1 the group shrunk
    together), ``divergence = −Dᵀ`` back to ``(B, N)``; ``key`` identifies it (factor caches)."""

    n: int
    key: tuple

    def forward(self, x: Tensor) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def divergence(self, p: Tensor) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def laplacian(self, dtype: torch.dtype, device: Any = None) -> Tensor:
        """``DᵀD (N, N)`` dense (the ADMM's exact solve forms ``AᵀA + ρ(DᵀD + I)``)."""
        eye = torch.eye(self.n, dtype=dtype, device=device)
        return -self.divergence(self.forward(eye))

    def norm(self, x: Tensor) -> Tensor:
        """``TV(x) = Σ_g ‖(Dx)_g‖₂`` per signal, ``(B,)``."""
        g = self.forward(x)
        return torch.sqrt((g * g).sum(1)).flatten(1).sum(1)


class ImageGradient(Differences):
    """:func:`tv_gradient` on images of ``shape (H, W)`` flattened row-major: ``(B, H·W) → (B, 2, H, W)``,
    the two components of a pixel one group (the isotropic TV)."""

    def __init__(self, shape: Sequence[int]):
        self.shape = tuple(int(s) for s in shape)
        self.n = self.shape[0] * self.shape[1]
        self.key = ("image", self.shape)

    def forward(self, x: Tensor) -> Tensor:
        return tv_gradient(x.reshape(x.shape[0], *self.shape))

    def divergence(self, p: Tensor) -> Tensor:
        return tv_divergence(p).reshape(p.shape[0], -1)


class GraphDifferences(Differences):
    """The rows of a matrix ``D (E, N)`` (scipy sparse or dense), each its own group (the
    anisotropic TV over a graph's edges): ``(B, N) → (B, 1, E)``, applied from its non-zeros
    (no dense ``E × N`` copy)."""

    def __init__(self, D: Any):
        import scipy.sparse as sp  # heavy: scipy.sparse, only for GraphDifferences()

        D = sp.coo_matrix(D)
        self.n, self.n_edges = D.shape[1], D.shape[0]
        self.rows, self.cols, self.vals = (np.asarray(a) for a in (D.row, D.col, D.data))
        self.key = ("graph", D.shape, D.nnz, hash(self.rows.tobytes()), hash(self.cols.tobytes()), hash(self.vals.tobytes()))
        self._on: dict = {}

    def _index(self, like: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        k = (like.dtype, str(like.device))
        if k not in self._on:
            self._on[k] = (torch.as_tensor(self.rows, dtype=torch.long, device=like.device),
                           torch.as_tensor(self.cols, dtype=torch.long, device=like.device),
                           torch.as_tensor(self.vals, dtype=like.dtype, device=like.device))
        return self._on[k]

    def forward(self, x: Tensor) -> Tensor:
        r, c, v = self._index(x)
        out = torch.zeros(x.shape[0], self.n_edges, dtype=x.dtype, device=x.device)
        return out.index_add_(1, r, x[:, c] * v)[:, None]

    def divergence(self, p: Tensor) -> Tensor:
        r, c, v = self._index(p)
        out = torch.zeros(p.shape[0], self.n, dtype=p.dtype, device=p.device)
        return -out.index_add_(1, c, p[:, 0, r] * v)


def knn_differences(points: Any, k: int = 6) -> Any:
    """``D (E, K)`` sparse: one row ``e_i − e_j`` per edge joining each of the ``points (K, d)`` to
    its ``k`` nearest (Euclidean; on the unit sphere the same order as by angle; each edge once)."""
    import scipy.sparse as sp  # heavy: scipy.sparse, only for knn_differences()
    from scipy.spatial import cKDTree  # heavy: scipy.spatial, only for knn_differences()

    P = np.asarray(points, dtype=np.float64)
    k = min(int(k), len(P) - 1)
    if k < 1:
        return sp.csr_matrix((0, len(P)))
    _, nb = cKDTree(P).query(P, k=k + 1)
    i = np.repeat(np.arange(len(P)), k)
    j = nb[:, 1:].reshape(-1)
    edges = np.unique(np.sort(np.stack([i, j], 1), axis=1), axis=0)
    E = len(edges)
    rows = np.repeat(np.arange(E), 2)
    return sp.csr_matrix((np.tile([1.0, -1.0], E), (rows, edges.reshape(-1))), shape=(E, len(P)))


def grid_differences(shape: Sequence[int]) -> Any:
    """``D (E, prod(shape))`` sparse: the forward differences along each axis of a grid of
    ``shape`` (row-major, as ``x.reshape(-1)``), one row ``e_{i+1} − e_i`` per adjacent pair — the
    anisotropic TV's gradient of an image."""
    import scipy.sparse as sp  # heavy: scipy.sparse, only for grid_differences()

    shape = tuple(int(s) for s in shape)
    blocks = []
    for ax, n in enumerate(shape):
        d = sp.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))
        mats = [sp.identity(m) for m in shape]
        mats[ax] = d
        out = mats[0]
        for m in mats[1:]:
            out = sp.kron(out, m)
        blocks.append(out)
    return sp.vstack(blocks).tocsr()
