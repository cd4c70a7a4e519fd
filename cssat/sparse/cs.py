"""The compressed-sensing dictionary ``ΦΨ`` for a DCT Ψ (paper Eq. 1–6)."""

from __future__ import annotations

from typing import Sequence

import torch
from torch import Tensor

from cssat._checks import FieldError
from cssat.sparse.operators import ComposedOperator, LinearOperator, MatrixOperator
from cssat.sparse.transforms import DCT

__all__ = ["sensing_dictionary", "DictionarySensing"]


class DictionarySensing(LinearOperator):
    """A sensing operator held by its CS dictionary: ``Φ = (ΦΨ) Ψᵀ`` for a DCT Ψ on ``shape``.

    ``dictionary (m, N)`` is ``ΦΨ`` (e.g. ``Âᵀ`` of the sparse reference-satellite estimate,
    Eq. 26–30). ``forward(x) = (ΦΨ)(Ψᵀx)``, ``adjoint(y) = Ψ((ΦΨ)ᵀy)``; :func:`sensing_dictionary`
    returns ``dictionary`` itself, with no transform, and :meth:`matrix` forms ``Φ`` by a fast
    inverse DCT of its rows.
    """

    def __init__(self, dictionary: Tensor, shape: Sequence[int]):
        super().__init__()
        if dictionary.ndim != 2:
            raise FieldError("dictionary", f"expected a 2-D tensor (m, N), got shape {tuple(dictionary.shape)}")
        self.psi = DCT(tuple(shape))
        if dictionary.shape[1] != self.psi.n_in:
            raise FieldError("dictionary", f"expected {self.psi.n_in} columns for images of shape {tuple(shape)}, "
                             f"got {dictionary.shape[1]}")
        self.dictionary = dictionary
        self.dims = tuple(shape)
        self.n_out, self.n_in = dictionary.shape

    def forward(self, x: Tensor) -> Tensor:
        return self.psi.adjoint(x) @ self.dictionary.to(x).T

    def adjoint(self, y: Tensor) -> Tensor:
        return self.psi(y @ self.dictionary.to(y))

    def matrix(self, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> Tensor:
        """``Φ (m, N)``: row ``i`` is ``Ψ d_i`` for row ``d_i`` of ``ΦΨ``."""
        d = self.dictionary.to(dtype=dtype or self.dictionary.dtype, device=device or self.dictionary.device)
        out = torch.empty_like(d)
        for s in range(0, d.shape[0], 1024):
            out[s : s + 1024] = self.psi(d[s : s + 1024])
        return out

    def extra_repr(self) -> str:
        return f"m={self.n_out}, shape={self.dims}, dtype={self.dictionary.dtype}"


def sensing_dictionary(phi: Tensor | LinearOperator, shape: Sequence[int]) -> Tensor:
    """The CS dictionary ``ΦΨ (m, N)`` for a DCT Ψ on images of ``shape`` (``N = prod(shape)``).

    Row ``i`` is the DCT of row ``i`` of Φ (``(ΦΨ)ᵢ = (Ψᵀφᵢ)ᵀ``), computed by the separable
    transform in ``m · N · Σ nᵈ`` operations — never an ``N × N`` product
    (:meth:`ComposedOperator.matrix`). The result is a transposed view of a contiguous ``(N, m)``
    tensor, so each atom (column) is contiguous in memory, which is what the no-Gram OMP path
    reads. A :class:`DictionarySensing` gives its dictionary as it is.
    """
    psi = DCT(tuple(shape))
    if isinstance(phi, DictionarySensing) and phi.dims == psi.dims:
        return phi.dictionary
    op = phi if isinstance(phi, LinearOperator) else MatrixOperator(phi) if isinstance(phi, Tensor) and phi.ndim == 2 else None
    if op is None or op.n_in != psi.n_in:
        got = tuple(phi.shape) if hasattr(phi, "shape") else type(phi).__name__
        raise FieldError("phi", f"expected shape (m, {psi.n_in}) for images of shape {tuple(shape)}, got {got}")
    return ComposedOperator(op, psi).matrix(atoms_contiguous=True)
