"""Compressed-sensing reconstruction ``x = Ψγ`` from ``y = Φx`` with a DCT Ψ (paper Eq. 1–6)."""

from __future__ import annotations

from typing import Sequence

import torch
from torch import Tensor

from cssat.sparse.omp import OMPInfo, batch_omp
from cssat.sparse.operators import DCT, LinearOperator

__all__ = ["sensing_dictionary", "omp_reconstruct"]


def sensing_dictionary(phi: Tensor | LinearOperator, shape: Sequence[int]) -> Tensor:
    """The CS dictionary ``ΦΨ (m, N)`` for a DCT Ψ on images of ``shape`` (``N = prod(shape)``).

    Row ``i`` is the DCT of row ``i`` of Φ (``(ΦΨ)ᵢ = (Ψᵀφᵢ)ᵀ``), computed by the separable
    transform in ``m · N · Σ nᵈ`` operations — never an ``N × N`` product. The result is returned as
    a transposed view of a contiguous ``(N, m)`` tensor, so each atom (column) is contiguous in
    memory, which is what the no-Gram OMP path reads.
    """
    psi = DCT(tuple(shape))
    mat = phi.matrix() if isinstance(phi, LinearOperator) else phi
    if mat.ndim != 2 or mat.shape[1] != psi.n_in:
        raise ValueError(f"phi: expected shape (m, {psi.n_in}) for images of shape {tuple(shape)}, got {tuple(mat.shape)}")
    m = mat.shape[0]
    at = torch.empty(psi.n_in, m, dtype=mat.dtype, device=mat.device)
    block = 1024
    for s in range(0, m, block):
        at[:, s : s + block] = psi.adjoint(mat[s : s + block]).T
    return at.T


def omp_reconstruct(
    phi: Tensor | LinearOperator,
    y: Tensor,
    shape: Sequence[int],
    *,
    n_nonzero_coefs: int | None = None,
    tol: float | None = None,
    dictionary: Tensor | None = None,
) -> tuple[Tensor, Tensor, OMPInfo]:
    """Reconstruct images from measurements ``y = Φx`` by batch-OMP over ``ΦΨ`` (Eq. 5 or 6).

    ``y (m,)`` or ``(B, m)``; returns ``(x̂, γ, info)`` with ``x̂ = Ψγ`` of shape ``(*shape)`` or
    ``(B, *shape)``, ``γ`` the DCT coefficients, ``info`` the :class:`OMPInfo`. ``tol`` bounds the
    squared residual ``‖y − ΦΨγ‖₂²``. Pass ``dictionary`` (from :func:`sensing_dictionary`) to reuse it.
    """
    D = dictionary if dictionary is not None else sensing_dictionary(phi, shape)
    gamma, info = batch_omp(D, y.to(D.dtype), n_nonzero_coefs=n_nonzero_coefs, tol=tol, return_info=True)
    x = DCT(tuple(shape))(gamma)
    return x.reshape(*y.shape[:-1], *shape), gamma, info
