"""The sparsifying transforms of the sparse layer: the orthonormal DCT Ψ (separable, any number of
axes), the overcomplete DCT of sparse K-SVD and the Kronecker operator of separable dictionaries.
Same conventions as :mod:`cssat.sparse.operators` (batch-first rows, follow the input's device
and dtype)."""

from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import Tensor

from cssat._checks import FieldError
from cssat.sparse.operators import LinearOperator, _check_last

__all__ = ["DCT", "KroneckerOperator", "dct_matrix", "odct_matrix"]


def dct_matrix(n: int, dtype: torch.dtype = torch.float64, device: torch.device | str | None = None) -> Tensor:
    """Orthonormal DCT-II matrix ``C (n, n)``: ``C[k, i] = s_k cos(π (2i + 1) k / (2n))``.

    ``s_0 = √(1/n)``, ``s_k = √(2/n)``; ``C @ x`` equals ``scipy.fft.dct(x, norm="ortho")`` and
    ``C Cᵀ = I``. Built in float64 and then cast, so float32 matrices are correctly rounded.
    """
    if n < 1:
        raise FieldError("n", f"DCT length must be >= 1, got {n}")
    k = torch.arange(n, dtype=torch.float64, device=device)[:, None]
    i = torch.arange(n, dtype=torch.float64, device=device)[None, :]
    c = torch.cos(math.pi * (2 * i + 1) * k / (2 * n)) * math.sqrt(2.0 / n)
    c[0] /= math.sqrt(2.0)
    return c.to(dtype)


class DCT(LinearOperator):
    """Separable orthonormal DCT-II dictionary Ψ on arrays of ``shape`` (1-D, 2-D or 3-D).

    ``Ψ (N, N)``, ``N = prod(shape)``, is the *synthesis* operator whose columns are the DCT atoms
    (paper Eq. 3, ``x = Ψγ``); ``Ψᵀ`` is the type-II DCT of ``scipy.fft.dctn(x, norm="ortho")``.
    Vectors are flattened in C (row-major) order, so ``Ψᵀ = C₁ ⊗ C₂ (⊗ C₃)``.

    Inputs may be flattened ``(B, N)`` or shaped ``(B, *shape)``; the output has the same layout.
    The transform is applied one axis at a time with the small ``(n_d, n_d)`` matrices, costing
    ``N · Σ n_d`` multiply-adds per vector; the ``N × N`` matrix is only formed by :meth:`matrix`.
    """

    def __init__(self, shape: int | Sequence[int]):
        super().__init__()
        shape = (int(shape),) if isinstance(shape, int) else tuple(int(s) for s in shape)
        if not 1 <= len(shape) <= 3 or any(s < 1 for s in shape):
            raise FieldError("shape", f"expected 1 to 3 positive sizes, got {shape}")
        self.dims = shape
        self.n_in = self.n_out = math.prod(shape)
        for d, n in enumerate(shape):
            self.register_buffer(f"c{d}", dct_matrix(n), persistent=False)

    def _mats(self, like: Tensor) -> list[Tensor]:
        return [getattr(self, f"c{d}").to(device=like.device, dtype=like.dtype) for d in range(len(self.dims))]

    def _separable(self, x: Tensor, transpose: bool) -> Tensor:
        nd = len(self.dims)
        if tuple(x.shape[-nd:]) == self.dims:
            flat = False
            batch = x.shape[:-nd]
        elif x.shape[-1] == self.n_in:
            flat = True
            batch = x.shape[:-1]
        else:
            raise FieldError(
                "x", f"trailing shape must be {self.dims} or ({self.n_in},), got {tuple(x.shape)}"
            )
        z = x.reshape(-1, *self.dims)
        for d, c in enumerate(self._mats(x)):
            # Contract axis d+1 of z with c (analysis: C @ v along the axis; synthesis: Cᵀ @ v).
            m = c if transpose else c.T
            z = torch.movedim(torch.movedim(z, d + 1, -1) @ m.T, -1, d + 1)
        return z.reshape(*batch, self.n_in) if flat else z.reshape(*batch, *self.dims)

    def forward(self, coeffs: Tensor) -> Tensor:
        """Synthesis ``x = Ψγ`` (inverse DCT): ``(B, N)`` or ``(B, *shape)`` in, same layout out."""
        return self._separable(coeffs, transpose=False)

    def adjoint(self, x: Tensor) -> Tensor:
        """Analysis ``γ = Ψᵀx`` (forward orthonormal DCT-II), same layouts as :meth:`forward`."""
        return self._separable(x, transpose=True)

    def A_dagger(self, y: Tensor, max_iter: int = 1000, rtol: float = 1e-7) -> Tensor:
        """``Ψ⁺ = Ψᵀ``: Ψ is orthonormal, so the least-squares solution is the analysis."""
        return self.adjoint(y)

    def extra_repr(self) -> str:
        return f"shape={self.dims}"

    def matrix(self, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> Tensor:
        """Dense ``Ψ (N, N)`` (columns are atoms): ``(C₁ ⊗ C₂ ⊗ …)ᵀ``. Costs ``N²`` memory."""
        dtype = dtype or torch.get_default_dtype()
        mats = [getattr(self, f"c{d}").to(dtype=dtype, device=device) for d in range(len(self.dims))]
        k = mats[0]
        for c in mats[1:]:
            k = torch.kron(k, c)
        return k.T.contiguous()


def odct_matrix(n: int, atoms: int, dtype: torch.dtype = torch.float64) -> Tensor:
    """1-D overcomplete DCT dictionary ``(n, atoms)`` (KSVDBox's ``odctdict``): column 0 is the
    constant ``1/√n``; column ``k`` is ``cos(π k i / atoms)``, ``i = 0..n−1``, with its mean removed
    and scaled to unit norm. The base dictionary of sparse-KSVD (Rubinstein et al. 2010)."""
    if n < 1 or atoms < 1:
        raise FieldError("atoms", f"an (n, atoms) dictionary needs both >= 1, got ({n}, {atoms})")
    i = torch.arange(n, dtype=torch.float64)[:, None]
    k = torch.arange(atoms, dtype=torch.float64)[None, :]
    d = torch.cos(math.pi * i * k / atoms)
    d[:, 1:] -= d[:, 1:].mean(0, keepdim=True)
    norms = torch.linalg.vector_norm(d, dim=0)
    d = torch.where(norms > 1e-12, d / norms.clamp_min(1e-300), d)
    d[:, 0] = 1.0 / math.sqrt(n)
    return d.to(dtype)


class KroneckerOperator(LinearOperator):
    """The Kronecker product ``M₁ ⊗ M₂ (⊗ M₃)`` of small matrices, applied one axis at a time.

    ``Mₐ (rₐ, cₐ)``; the operator maps ``(B, Π cₐ)`` to ``(B, Π rₐ)`` with vectors flattened in C
    order — a separable dictionary for patches (columns of ``Mₐ`` are 1-D atoms) costing
    ``Σ`` small products instead of one ``Π rₐ × Π cₐ`` matrix.
    """

    def __init__(self, mats: Sequence[Tensor]):
        super().__init__()
        mats = [torch.as_tensor(m) for m in mats]
        if not 1 <= len(mats) <= 3 or any(m.ndim != 2 for m in mats):
            raise FieldError("mats", "expected 1 to 3 two-dimensional matrices")
        for d, m in enumerate(mats):
            self.register_buffer(f"m{d}", m)
        self.rows = tuple(int(m.shape[0]) for m in mats)
        self.cols = tuple(int(m.shape[1]) for m in mats)
        self.n_out, self.n_in = math.prod(self.rows), math.prod(self.cols)

    def extra_repr(self) -> str:
        return f"rows={self.rows}, cols={self.cols}"

    def _mats(self, like: Tensor) -> list[Tensor]:
        return [getattr(self, f"m{d}").to(device=like.device, dtype=like.dtype) for d in range(len(self.rows))]

    def _separable(self, x: Tensor, transpose: bool) -> Tensor:
        dims_in = self.rows if transpose else self.cols
        _check_last(x, math.prod(dims_in), "x")
        batch = x.shape[:-1]
        z = x.reshape(-1, *dims_in)
        for d, m in enumerate(self._mats(x)):
            mm = m if transpose else m.T  # forward: contract with M (z @ Mᵀ); adjoint: with Mᵀ
            z = torch.movedim(torch.movedim(z, d + 1, -1) @ mm, -1, d + 1)
        return z.reshape(*batch, -1)

    def forward(self, x: Tensor) -> Tensor:
        """``(M₁ ⊗ M₂ ⊗ …) x`` for rows ``x (B, Π cₐ)``; returns ``(B, Π rₐ)``."""
        return self._separable(x, transpose=False)

    def adjoint(self, y: Tensor) -> Tensor:
        """``(M₁ ⊗ M₂ ⊗ …)ᵀ y`` for rows ``y (B, Π rₐ)``; returns ``(B, Π cₐ)``."""
        return self._separable(y, transpose=True)

    def matrix(self, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> Tensor:
        mats = [getattr(self, f"m{d}").to(dtype=dtype or torch.get_default_dtype(), device=device) for d in range(len(self.rows))]
        k = mats[0]
        for m in mats[1:]:
            k = torch.kron(k, m)
        return k
