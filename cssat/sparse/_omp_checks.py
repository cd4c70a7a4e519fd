"""The input checks of :func:`cssat.sparse.batch_omp`: shapes, dtypes and finiteness, the scale
normalisation by powers of two, and the consistency of a precomputed Gram or ``Dᵀy``."""

from __future__ import annotations

import math

import torch
from torch import Tensor

from cssat._checks import FieldError, FieldTypeError
from cssat.sparse._io import as_float_tensor


def check_inputs(D, Y, n_nonzero_coefs, tol):
    """Validate ``D``, ``Y``, ``K`` and ``tol`` of :func:`batch_omp`; returns ``(D, Y2, squeeze, K, tol)``
    with ``Y2 (B, m)`` in ``D``'s dtype and device and ``K`` the per-signal step cap."""
    if D.ndim != 2:
        raise FieldError("D", f"expected a 2-D dictionary (m, n_atoms), got shape {tuple(D.shape)}")
    for name, a in (("D", D), ("Y", Y)):
        if a.is_complex():
            raise FieldTypeError(name, f"batch_omp works on real data, got {a.dtype}; pass the real and imaginary "
                                       "parts as separate real signals")
    if not D.is_floating_point():  # integers: the default float dtype, not integer arithmetic
        D = D.to(torch.get_default_dtype())
    if D.dtype not in (torch.float32, torch.float64):
        raise FieldTypeError("D", f"batch_omp computes in float32 or float64, got {D.dtype}; cast it, e.g. D.float()")
    if not bool(torch.isfinite(D).all()):
        raise FieldError("D", "the dictionary contains NaN or Inf")
    m, n_atoms = D.shape
    squeeze = Y.ndim == 1
    Y2 = Y.reshape(1, -1) if squeeze else Y
    if Y2.ndim != 2 or Y2.shape[1] != m:
        raise FieldError("Y", f"expected shape (B, {m}) or ({m},) to match D (m={m}), got {tuple(Y.shape)}")
    Y2 = Y2.to(dtype=D.dtype, device=D.device)
    if not bool(torch.isfinite(Y2).all()):
        raise FieldError("Y", "signals contain NaN or Inf")
    if tol is not None:
        tol = float(tol)
        if not math.isfinite(tol) or tol < 0:
            raise FieldError("tol", f"squared residual bound must be finite and >= 0, got {tol}")
    if n_nonzero_coefs is not None:
        if isinstance(n_nonzero_coefs, bool) or int(n_nonzero_coefs) != n_nonzero_coefs:
            raise FieldError("n_nonzero_coefs", f"expected an integer, got {n_nonzero_coefs!r}")
        n_nonzero_coefs = int(n_nonzero_coefs)
        if not 1 <= n_nonzero_coefs <= n_atoms:
            raise FieldError(
                "n_nonzero_coefs", f"must be in [1, n_atoms={n_atoms}], got {n_nonzero_coefs}"
            )
    elif tol is None:
        n_nonzero_coefs = max(1, n_atoms // 10)
    K = min(n_nonzero_coefs if n_nonzero_coefs is not None else n_atoms, m, n_atoms)
    return D, Y2, squeeze, K, tol


def pow2(x: float) -> float:
    """The power of two nearest below ``x > 0`` (scaling by it is exact in floating point)."""
    return math.ldexp(1.0, math.frexp(x)[1] - 1)


#: inputs whose largest entry is outside [2⁻²⁰, 2²⁰] are scaled by a power of two (exact) before
#: the Gram and the correlations are formed, so they neither overflow nor underflow (float32 with
#: entries of 1e19 overflowed DᵀD; 1e-30 underflowed it); inputs in range are not touched
SAFE_EXP = 20


def rescale(D, Y2, gram, Dty, tol):
    """``(D/s, Y/t, G/s², Dᵀy/(s t), tol/t², (s, t))`` with powers of two ``s``, ``t`` bringing the
    largest entries of ``D`` and ``Y`` near 1 when they are far from it; ``(…, (1, 1))`` otherwise."""
    dmax = float(D.abs().max()) if D.numel() else 0.0
    ymax = float(Y2.abs().max()) if Y2.numel() else 0.0
    s = pow2(dmax) if dmax > 0 and abs(math.frexp(dmax)[1]) > SAFE_EXP else 1.0
    t = pow2(ymax) if ymax > 0 and abs(math.frexp(ymax)[1]) > SAFE_EXP else 1.0
    if s == 1.0 and t == 1.0:
        return D, Y2, gram, Dty, tol, (s, t)
    D, Y2 = D / s, Y2 / t
    if gram is not None:
        gram = as_float_tensor(gram).to(dtype=D.dtype, device=D.device) / s / s
    if Dty is not None:
        Dty = as_float_tensor(Dty).to(dtype=D.dtype, device=D.device) / s / t
    return D, Y2, gram, Dty, (None if tol is None else tol / t / t), (s, t)


def given(a, name: str, shape: tuple[int, int], D: Tensor) -> Tensor:
    """A precomputed ``gram``/``Dty`` in ``D``'s dtype and device, of ``shape``, finite and real."""
    a = as_float_tensor(a)
    if a.is_complex():
        raise FieldTypeError(name, f"expected real values, got {a.dtype}")
    if a.numel() != shape[0] * shape[1] or (a.ndim == 2 and tuple(a.shape) != shape):
        raise FieldError(name, f"expected shape {shape}, got {tuple(a.shape)}")
    a = a.reshape(shape).to(dtype=D.dtype, device=D.device)
    if not bool(torch.isfinite(a).all()):
        raise FieldError(name, "contains NaN or Inf")
    return a


def check_consistent(D: Tensor, Y2: Tensor, G: Tensor | None, A0: Tensor | None) -> None:
    """A precomputed Gram must be ``DᵀD`` (its diagonal and its largest column checked) and
    ``Dty`` must be ``DᵀY`` (its first row checked), to a tolerance of the dtype: ``O(m n)``."""
    tol = 1e-3 if D.dtype == torch.float32 else 1e-8
    if G is not None:
        norms = (D * D).sum(0)
        j = int(torch.argmax(norms))
        ref = torch.cat([norms, D.T @ D[:, j]])
        got = torch.cat([torch.diagonal(G), G[:, j]])
        if float((got - ref).abs().max()) > tol * float(norms.max()) + 1e-30:
            raise FieldError("gram", "is not DᵀD of this dictionary (its diagonal or a column differs); "
                                     "leave gram=None to compute it")
    if A0 is not None and Y2.shape[0]:
        ref = D.T @ Y2[0]
        scale = float(torch.linalg.vector_norm(Y2[0])) * float(torch.linalg.vector_norm(D, dim=0).max())
        if float((A0[0] - ref).abs().max()) > tol * scale + 1e-30:
            raise FieldError("Dty", "is not DᵀY of these signals (its first row differs); leave Dty=None")
