"""Linear operators of compressed sensing as ``nn.Module``s: the base class, a dense matrix, a
Gaussian Φ and compositions such as ΦΨ (the transforms Ψ are in :mod:`cssat.sparse.transforms`).

Conventions (``../shared/DESIGN.md``):

* batch-first: an operator maps ``(B, n_in)`` to ``(B, n_out)``; vectors are rows, so
  ``forward(x) = x @ Mᵀ`` for the operator's matrix ``M (n_out, n_in)``;
* ``forward`` applies the operator, ``adjoint`` its transpose, ``matrix()`` materialises ``M``;
* no stored device: fixed matrices are buffers (moved with ``.to()``), and every method follows the
  *input's* device and dtype.
"""

from __future__ import annotations

import functools
import math
from typing import Sequence

import torch
from torch import Tensor, nn

from cssat._checks import FieldError, FieldTypeError
from cssat.sparse._io import as_float_tensor

__all__ = ["LinearOperator", "MatrixOperator", "GaussianSensing", "ComposedOperator", "as_operator"]


def _accepts_any_input(method):
    """Let ``forward``/``adjoint`` take what users hold: a numpy array (numpy comes back) or an
    integer/bool tensor (promoted to torch's default float dtype, instead of silent integer math)."""

    @functools.wraps(method)
    def wrapper(self, x, *args, **kwargs):
        out = method(self, as_float_tensor(x), *args, **kwargs)
        return out if isinstance(x, Tensor) else out.detach().cpu().numpy()

    wrapper._cssat_input = True
    return wrapper


class LinearOperator(nn.Module):
    """A linear map ``M (n_out, n_in)`` acting on batches of row vectors.

    Subclasses implement :meth:`forward` (``(B, n_in) -> (B, n_out)``) and :meth:`adjoint`
    (``(B, n_out) -> (B, n_in)``); both accept numpy arrays (and return numpy) and promote integer
    tensors to the default float dtype, in every subclass. :meth:`matrix` materialises ``M`` by applying the adjoint to
    identity blocks, so it never needs more than one ``(block, n_in)`` temporary beside the result.
    ``A @ B`` composes two operators (``B`` first).

    deepinv's names are there too: :meth:`A` (``forward``), :meth:`A_adjoint` (``adjoint``) and
    :meth:`A_dagger`, the minimum-norm least-squares solution ``M⁺y``. An operator with an
    ``in_shape`` (e.g. ``GaussianSensing(m, (1, H, W))``) takes inputs ``(B, *in_shape)`` and its
    adjoint returns that shape; any operator takes images ``(B, C, H, W)`` or ``(B, H, W)``
    whose trailing sizes multiply to ``n_in`` (see :meth:`flatten_input`).
    """

    n_in: int
    n_out: int
    in_shape: tuple[int, ...] | None = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for name in ("forward", "adjoint", "A_dagger"):
            method = cls.__dict__.get(name)
            if method is not None and not getattr(method, "_cssat_input", False):
                setattr(cls, name, _accepts_any_input(method))

    @property
    def shape(self) -> tuple[int, int]:
        """``(n_out, n_in)``, the shape of the matrix."""
        return (self.n_out, self.n_in)

    def flatten_input(self, x: Tensor) -> Tensor:
        """``x`` as rows ``(..., n_in)``. Accepted: rows ``(..., n_in)`` (every leading axis is a
        batch axis); ``(..., *in_shape)``; images ``(B, C, H, W)``, ``(B, H, W)`` or one ``(H, W)``
        whose trailing sizes multiply to ``n_in`` — as many trailing axes as possible are joined,
        keeping the first as the batch axis (one unbatched image becomes one row ``(n_in,)``)."""
        n = self.n_in
        if x.shape[-1] == n:
            return x
        s = self.in_shape
        if s is not None and tuple(x.shape[x.ndim - len(s):]) == s:
            return x.reshape(*x.shape[: x.ndim - len(s)], n)
        for k in range(x.ndim - 1, 0, -1):
            if math.prod(x.shape[x.ndim - k:]) == n:
                return x.reshape(*x.shape[: x.ndim - k], n)
        if math.prod(x.shape) == n:
            return x.reshape(n)
        raise FieldError("x", f"expected rows (B, {n}), images (B, C, H, W) or (B, H, W) with C·H·W = {n}"
                         f"{'' if s is None else f', or (B, *{s})'}; got shape {tuple(x.shape)}")

    def _shape_output(self, x: Tensor) -> Tensor:
        """Rows ``(..., n_in)`` as ``(..., *in_shape)`` when the operator has an ``in_shape``."""
        return x if self.in_shape is None else x.reshape(*x.shape[:-1], *self.in_shape)

    def adjoint(self, y: Tensor) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def A(self, x: Tensor) -> Tensor:
        """deepinv's name for :meth:`forward`."""
        return self(x)

    def A_adjoint(self, y: Tensor) -> Tensor:
        """deepinv's name for :meth:`adjoint`."""
        return self.adjoint(y)

    def A_dagger(self, y: Tensor, max_iter: int = 1000, rtol: float = 1e-7) -> Tensor:
        """The minimum-norm least-squares solution ``x = M⁺y`` of ``min ‖Mx − y‖``, for rows
        ``y (B, n_out)``; returns ``(B, n_in)`` (or ``(B, *in_shape)``).

        Matrix-free CGLS (conjugate gradients on the normal equations, started from 0, so the
        iterates stay in the row space of ``M`` and converge to the minimum-norm solution); it
        stops when ``‖Mᵀr‖`` falls below ``rtol`` times its start, or after ``max_iter``
        iterations. :class:`MatrixOperator` solves exactly instead, :class:`DCT` is orthogonal.
        """
        _check_last(y, self.n_out, "y")
        batch = y.shape[:-1]
        b = y.reshape(-1, self.n_out)
        x = b.new_zeros(b.shape[0], self.n_in)
        r = b.clone()
        s = self.flatten_input(self.adjoint(r))
        p = s.clone()
        gamma = (s * s).sum(-1)
        stop = rtol**2 * gamma
        for _ in range(int(max_iter)):
            active = gamma > stop
            if not bool(active.any()):
                break
            q = self(p)
            alpha = torch.where(active, gamma / (q * q).sum(-1).clamp_min(torch.finfo(q.dtype).tiny), 0)
            x += alpha[:, None] * p
            r -= alpha[:, None] * q
            s = self.flatten_input(self.adjoint(r))
            gamma_new = (s * s).sum(-1)
            p = s + torch.where(active, gamma_new / gamma.clamp_min(torch.finfo(q.dtype).tiny), 0)[:, None] * p
            gamma = gamma_new
        return self._shape_output(x.reshape(*batch, self.n_in))

    def matrix(
        self, dtype: torch.dtype | None = None, device: torch.device | str | None = None
    ) -> Tensor:
        """The dense matrix ``M (n_out, n_in)``.

        Row ``i`` of ``M`` is ``adjoint(e_i)``; rows are produced in blocks of at most 1024.
        """
        dtype = dtype or torch.get_default_dtype()
        out = torch.empty(self.n_out, self.n_in, dtype=dtype, device=device)
        block = 1024
        for start in range(0, self.n_out, block):
            stop = min(start + block, self.n_out)
            eye = torch.zeros(stop - start, self.n_out, dtype=dtype, device=device)
            eye[:, start:stop] = torch.eye(stop - start, dtype=dtype, device=device)
            out[start:stop] = self.flatten_input(self.adjoint(eye))
        return out

    def __matmul__(self, other: "LinearOperator") -> "ComposedOperator":
        if not isinstance(other, LinearOperator):
            return NotImplemented
        return ComposedOperator(self, other)


def as_operator(A: "LinearOperator | Tensor", field: str = "A") -> "LinearOperator":
    """``A`` as a :class:`LinearOperator`: itself, or a :class:`MatrixOperator` of a 2-D tensor."""
    if isinstance(A, LinearOperator):
        return A
    if isinstance(A, Tensor) and A.ndim == 2:
        return MatrixOperator(A)
    raise FieldTypeError(field, f"expected a LinearOperator or a 2-D matrix, got {type(A).__name__}")


def _as_shape(n: int | Sequence[int], field: str = "n") -> tuple[int, tuple[int, ...] | None]:
    """``(n_in, in_shape)`` of a size or a signal shape such as ``(C, H, W)``."""
    if isinstance(n, (tuple, list, torch.Size)):
        shape = tuple(n)
        if not shape or any(isinstance(d, bool) or not isinstance(d, int) or d < 1 for d in shape):
            raise FieldError(field, f"a signal shape needs positive integer sizes, got {shape!r}")
        return math.prod(shape), shape
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise FieldError(field, f"number of columns must be a positive integer or a shape such as (C, H, W), got {n!r}")
    return n, None


class MatrixOperator(LinearOperator):
    """An explicit matrix ``M (n_out, n_in)`` stored as a buffer; ``in_shape`` (optional) is the
    shape of one input signal, e.g. ``(C, H, W)``, with ``prod(in_shape) = n_in``."""

    def __init__(self, matrix: Tensor, in_shape: Sequence[int] | None = None):
        super().__init__()
        if matrix.ndim != 2:
            raise FieldError("matrix", f"expected a 2-D tensor (n_out, n_in), got shape {tuple(matrix.shape)}")
        self.register_buffer("weight", matrix)
        self.n_out, self.n_in = matrix.shape
        if in_shape is not None:
            n, self.in_shape = _as_shape(tuple(in_shape), "in_shape")
            if n != self.n_in:
                raise FieldError("in_shape", f"{self.in_shape} has {n} entries, the matrix {self.n_in} columns")

    def _w(self, like: Tensor) -> Tensor:
        return self.weight.to(device=like.device, dtype=like.dtype)

    def forward(self, x: Tensor) -> Tensor:
        """``Mx`` for rows ``x (B, n_in)``, one ``(n_in,)`` vector or images (see
        :meth:`LinearOperator.flatten_input`); returns ``(B, n_out)``."""
        x = self.flatten_input(x)
        return x @ self._w(x).T

    def adjoint(self, y: Tensor) -> Tensor:
        """``Mᵀy`` for rows ``y (B, n_out)``; returns ``(B, n_in)`` (or ``(B, *in_shape)``)."""
        _check_last(y, self.n_out, "y")
        return self._shape_output(y @ self._w(y))

    def A_dagger(self, y: Tensor, max_iter: int = 1000, rtol: float = 1e-7) -> Tensor:
        """``M⁺y`` exactly, by an SVD-based least-squares solve (LAPACK ``gelsd`` on the CPU,
        ``pinv`` elsewhere): the minimum-norm solution for a wide or rank-deficient ``M``.
        ``max_iter``/``rtol`` are unused (the iterative method's). Costs ``O(m n min(m, n))``."""
        _check_last(y, self.n_out, "y")
        w = self._w(y)
        b = y.reshape(-1, self.n_out).T
        x = torch.linalg.lstsq(w, b, driver="gelsd").solution if w.device.type == "cpu" else torch.linalg.pinv(w) @ b
        return self._shape_output(x.T.reshape(*y.shape[:-1], self.n_in))

    def matrix(self, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> Tensor:
        return self.weight.to(dtype=dtype or self.weight.dtype, device=device or self.weight.device)

    def extra_repr(self) -> str:
        shape = "" if self.in_shape is None else f", in_shape={self.in_shape}"
        return f"n_out={self.n_out}, n_in={self.n_in}{shape}, dtype={self.weight.dtype}"


class GaussianSensing(MatrixOperator):
    """Gaussian sensing matrix ``Φ (m, n)`` with i.i.d. ``N(mean, std²)`` entries; by default
    ``N(0, 1/n)`` (paper Eq. 1, 12, 15).

    The paper's "zero-mean, 1/N-variance" matrix: ``n`` is the number of pixels. Row ``i`` is drawn
    from its own ``torch.Generator`` seeded by ``(seed, i)``, so

    * the same ``(m, n, seed)`` gives the same matrix on every machine and chunking;
    * the first ``m`` rows do not depend on ``m``: a sweep over ``m`` uses nested measurements.

    Each row is drawn in place into the preallocated ``(m, n)`` buffer (on a GPU, through one small
    CPU block), so a 13225 × 16384 float32 matrix needs its own 0.87 GB and no temporary copy.
    The draw depends on ``dtype``: float32 and float64 matrices of one seed are different samples.
    ``mean`` and ``std`` (default ``1/√n``) shift and scale the same draws.

    ``n`` may be a signal shape such as ``(C, H, W)`` (deepinv's ``img_shape``): the matrix is the
    same as for ``n = C·H·W``, inputs ``(B, C, H, W)`` are flattened and the adjoint returns that
    shape.
    """

    def __init__(
        self,
        m: int,
        n: int | Sequence[int],
        seed: int = 0,
        dtype: torch.dtype | None = None,
        device: torch.device | str | None = None,
        mean: float = 0.0,
        std: float | None = None,
    ):
        n, in_shape = _as_shape(n)
        if isinstance(m, bool) or not isinstance(m, int) or m < 1:
            raise FieldError("m", f"number of measurements must be a positive integer, got {m!r}")
        seed = int(seed)
        dtype = dtype or torch.get_default_dtype()
        if dtype not in (torch.float32, torch.float64):
            raise FieldError("dtype", f"expected torch.float32 or torch.float64, got {dtype}")
        std = 1.0 / math.sqrt(n) if std is None else float(std)
        mean = float(mean)
        if not (math.isfinite(std) and std >= 0):
            raise FieldError("std", f"must be a finite number >= 0, got {std}")
        if not math.isfinite(mean):
            raise FieldError("mean", f"must be finite, got {mean}")
        w = torch.empty(m, n, dtype=dtype, device=device)
        gen = torch.Generator(device="cpu")
        on_cpu = w.device.type == "cpu"
        block = max(1, min(m, (1 << 22) // n))
        buf = w if on_cpu else torch.empty(block, n, dtype=dtype)
        for start in range(0, m, block):
            stop = min(start + block, m)
            for i in range(start, stop):
                gen.manual_seed(_row_seed(seed, i))
                buf[i if on_cpu else i - start].normal_(mean, std, generator=gen)
            if not on_cpu:
                w[start:stop] = buf[: stop - start].to(w.device)
        super().__init__(w, in_shape)
        self.seed, self.mean, self.std = seed, mean, std

    def extra_repr(self) -> str:
        shape = "" if self.in_shape is None else f", in_shape={self.in_shape}"
        return (f"m={self.n_out}, n={self.n_in}{shape}, seed={self.seed}, mean={self.mean:g}, std={self.std:.4g}, "
                f"dtype={self.weight.dtype}")


def _row_seed(seed: int, row: int) -> int:
    # A fixed, well-mixed 63-bit seed per (seed, row) pair (splitmix64 finaliser).
    z = (seed * 0x9E3779B97F4A7C15 + row + 1) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return (z ^ (z >> 31)) & 0x7FFFFFFFFFFFFFFF


class ComposedOperator(LinearOperator):
    """The product ``A B`` of two operators (``B`` applied first), e.g. the CS dictionary ΦΨ.

    ``forward(γ) = A(B(γ))``, ``adjoint(y) = Bᵀ(Aᵀ(y))``. :meth:`matrix` materialises
    ``A B (n_out, n_in)`` as ``(Bᵀ applied to the rows of A)``: for ΦΨ with a DCT Ψ this is a fast
    separable DCT of each row of Φ, ``m · N · Σ n_d`` operations, not an ``N × N`` product.
    """

    def __init__(self, outer: LinearOperator, inner: LinearOperator):
        super().__init__()
        if outer.n_in != inner.n_out:
            raise FieldError(
                "inner", f"output size {inner.n_out} does not match the outer operator's input size {outer.n_in}"
            )
        self.outer, self.inner = outer, inner
        self.n_out, self.n_in = outer.n_out, inner.n_in

    def forward(self, x: Tensor) -> Tensor:
        return self.outer(self.inner(x))

    def extra_repr(self) -> str:
        return f"n_out={self.n_out}, n_in={self.n_in}"

    def adjoint(self, y: Tensor) -> Tensor:
        return self.inner.adjoint(self.outer.adjoint(y))

    def matrix(self, dtype: torch.dtype | None = None, device: torch.device | str | None = None, block_rows: int = 1024,
               atoms_contiguous: bool = False) -> Tensor:
        """Dense ``(n_out, n_in)``; rows of the outer matrix are pushed through ``innerᵀ`` in blocks.

        ``atoms_contiguous``: return a transposed view of a contiguous ``(n_in, n_out)`` tensor, so
        each column (a dictionary atom) is contiguous in memory.
        """
        a = self.outer.matrix(dtype=dtype, device=device)
        if atoms_contiguous:
            at = torch.empty(self.n_in, self.n_out, dtype=a.dtype, device=a.device)
            for start in range(0, self.n_out, block_rows):
                at[:, start : start + block_rows] = self.inner.adjoint(a[start : start + block_rows]).T
            return at.T
        out = torch.empty(self.n_out, self.n_in, dtype=a.dtype, device=a.device)
        for start in range(0, self.n_out, block_rows):
            out[start : start + block_rows] = self.inner.adjoint(a[start : start + block_rows])
        return out


def _check_last(x: Tensor, n: int, name: str) -> None:
    if x.shape[-1] != n:
        raise FieldError(name, f"last dimension must be {n}, got shape {tuple(x.shape)}")
