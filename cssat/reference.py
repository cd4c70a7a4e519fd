"""Sensing-matrix estimation from reference satellites (paper Eq. 22–30, the guide-star idea).

Reference images ``X_ref (n_pixel, N)`` (images as columns) observed through the same atmosphere
as the target give light curves ``Y_ref = Φ X_ref (m, N)`` (Eq. 22). Three estimates of ``Φ``:

* :func:`estimate_sensing_full_rank` — ``N = n_pixel`` linearly independent references:
  ``Φ̂ = Y_ref X_ref⁻¹`` (Eq. 24), by an LU solve, never an explicit inverse;
* :func:`estimate_sensing_sparse` — ``N < n_pixel``: model ``Φᵀ = Ψ A`` with ``T₀``-sparse columns
  (Eq. 26), code every row of ``Y_ref`` over ``D = X_refᵀ Ψ`` by batch-OMP (Eq. 27–29) and set
  ``Φ̂ = Âᵀ Ψᵀ`` (Eq. 30);
* :func:`estimate_sensing_min_norm` — the baseline without a sparsity model: the minimum-norm
  ``Φ̂ = Y_ref X_ref⁺`` (exact on the span of the references, zero off it).

Shapes follow Eq. 22: ``Φ̂ (m, n_pixel)``. All functions follow the inputs' dtype and device.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import torch
from torch import Tensor
from cssat._checks import FieldError, FieldTypeError
from cssat.sparse import DCT, batch_omp
from cssat.sparse._io import numpy_io

__all__ = [
    "estimate_sensing_full_rank",
    "estimate_sensing_sparse",
    "estimate_sensing_min_norm",
    "relative_error",
    "SparseEstimate",
]


def _check(X_ref: Tensor, Y_ref: Tensor) -> tuple[int, int, int]:
    if X_ref.ndim != 2:
        raise FieldError("X_ref", f"expected (n_pixel, N) with reference images as columns, got shape {tuple(X_ref.shape)}")
    if Y_ref.ndim != 2 or Y_ref.shape[1] != X_ref.shape[1]:
        raise FieldError(
            "Y_ref", f"expected (m, N={X_ref.shape[1]}) light curves of the N references, got shape {tuple(Y_ref.shape)}"
        )
    for name, t in (("X_ref", X_ref), ("Y_ref", Y_ref)):
        if not t.is_floating_point():
            raise FieldTypeError(name, f"expected a float32 or float64 tensor, got {t.dtype}")
        if not bool(torch.isfinite(t).all()):
            raise FieldError(name, "contains NaN or Inf")
    return int(X_ref.shape[0]), int(X_ref.shape[1]), int(Y_ref.shape[0])


def _rcond_1norm(lu: Tensor, anorm: float) -> float | None:
    """LAPACK's 1-norm reciprocal condition estimate from an LU factor (CPU only; else None)."""
    if lu.device.type != "cpu":
        return None
    from scipy.linalg import lapack  # heavy: scipy.linalg, only for _rcond_1norm()

    fn = lapack.sgecon if lu.dtype == torch.float32 else lapack.dgecon
    rcond, info = fn(lu.numpy(), anorm, norm="1")
    return float(rcond) if info == 0 else None


@numpy_io
def estimate_sensing_full_rank(
    X_ref: Tensor, Y_ref: Tensor, *, rcond_min: float | None = None, return_rcond: bool = False
) -> Tensor | tuple[Tensor, float | None]:
    """``Φ̂ = Y_ref X_ref⁻¹`` (Eq. 24) for ``N = n_pixel`` linearly independent references.

    Solves ``Φ̂ X_ref = Y_ref`` by one LU factorisation of ``X_ref`` (``⅔ n³`` flops) and
    triangular solves from the right for blocks of rows of ``Y_ref`` (``2 n² m``). ``X_ref (n_pixel, n_pixel)``, ``Y_ref (m, n_pixel)`` →
    ``Φ̂ (m, n_pixel)``.

    Raises ``ValueError`` naming ``X_ref`` when there are fewer references than pixels, when the
    LU factorisation finds an exactly singular matrix, or when LAPACK's 1-norm reciprocal
    condition estimate ``rcond`` is below ``rcond_min`` (default: the dtype's ``eps``, LAPACK's
    own test for numerical singularity): then use :func:`estimate_sensing_sparse` (or
    :func:`estimate_sensing_min_norm`). The relative error of ``Φ̂`` is about ``eps / rcond``: renders
    of one satellite are nearly linearly dependent and only their noise makes ``X_ref`` invertible,
    so 128² references with 1 % noise have ``rcond ≈ 1e-8`` — float64 is needed for a near-exact
    ``Φ̂``. ``return_rcond=True`` also returns ``rcond`` (``None`` off the CPU).
    """
    n_pixel, N, m = _check(X_ref, Y_ref)
    if N < n_pixel:
        raise FieldError(
            "X_ref", f"N={N} reference images for n_pixel={n_pixel} pixels is rank deficient (Eq. 25); "
            "use estimate_sensing_sparse (Eq. 26-30) or estimate_sensing_min_norm"
        )
    Y = Y_ref.to(X_ref.dtype)
    if N > n_pixel:  # more references than pixels: least squares
        sol = torch.linalg.lstsq(X_ref.T, Y.T).solution.T.contiguous()
        return (sol, None) if return_rcond else sol
    anorm = float(X_ref.abs().sum(0).max())  # ‖X_ref‖₁ = max column sum
    LU, piv, info = torch.linalg.lu_factor_ex(X_ref)
    eps = torch.finfo(X_ref.dtype).eps
    limit = eps if rcond_min is None else float(rcond_min)
    if int(info) > 0:
        raise FieldError(
            "X_ref", f"singular (pivot {int(info)} of the LU factorisation is zero): the references are "
            "linearly dependent; use estimate_sensing_sparse (Eq. 26-30) or estimate_sensing_min_norm"
        )
    rcond = lapack_rcond = _rcond_1norm(LU, anorm)
    if rcond is None:  # not on a CPU: the ratio of the smallest to the largest pivot, a rough proxy
        d = torch.diagonal(LU).abs()
        rcond = float(d.min() / d.max().clamp_min(torch.finfo(d.dtype).tiny))
    if not rcond > limit:
        raise FieldError(
            "X_ref", f"numerically singular (reciprocal condition ≈ {rcond:.2e} <= {limit:.2e}): the references "
            "are (nearly) linearly dependent; use estimate_sensing_sparse (Eq. 26-30) or estimate_sensing_min_norm"
        )
    out = torch.empty(m, n_pixel, dtype=X_ref.dtype, device=X_ref.device)
    block = 4096  # rows of Φ̂ per solve Φ̂ X_ref = Y_ref (right-hand side form, no transposes)
    for s in range(0, m, block):
        out[s : s + block] = torch.linalg.lu_solve(LU, piv, Y[s : s + block], left=False)
    return (out, lapack_rcond) if return_rcond else out


@numpy_io
def estimate_sensing_min_norm(X_ref: Tensor, Y_ref: Tensor) -> Tensor:
    """The minimum-norm estimate ``Φ̂ = Y_ref X_ref⁺`` (no sparsity model): ``Φ̂ X_ref = Y_ref``
    and every row of ``Φ̂`` lies in the span of the references. For full column rank ``X_ref``
    (``N ≤ n_pixel``) it is ``Y_ref (X_refᵀX_ref)⁻¹ X_refᵀ``, by a Cholesky solve of the ``N × N``
    Gram matrix; a rank-deficient ``X_ref`` falls back to a pseudo-inverse."""
    n_pixel, N, m = _check(X_ref, Y_ref)
    Y = Y_ref.to(X_ref.dtype)
    G = X_ref.T @ X_ref
    L, info = torch.linalg.cholesky_ex(G)
    if int(info) == 0:
        Z = torch.cholesky_solve(Y.T.contiguous(), L)  # (N, m) = G⁻¹ Yᵀ
    else:
        Z = torch.linalg.pinv(G, hermitian=True) @ Y.T
    return (X_ref @ Z).T.contiguous()


class SparseEstimate(NamedTuple):
    """Extra output of :func:`estimate_sensing_sparse`: ``coefficients (m, n_pixel)`` is ``Âᵀ``
    — so ``Φ̂Ψ = Âᵀ`` is the CS dictionary directly; ``n_iter (m,)`` atoms per row;
    ``residual_sq (m,)`` final ``‖ȳᵢ − Dâᵢ‖²``."""

    coefficients: Tensor
    n_iter: Tensor
    residual_sq: Tensor


@numpy_io
def estimate_sensing_sparse(
    X_ref: Tensor,
    Y_ref: Tensor,
    *,
    n_nonzero_coefs: int | None = None,
    tol: float | None = None,
    shape: Sequence[int] | None = None,
    normalize: bool = True,
    return_info: bool = False,
    progress: bool | None = None,
) -> Tensor | tuple[Tensor, SparseEstimate]:
    """Rank-deficient estimate (Eq. 26–30): ``Φᵀ = Ψ A`` with sparse columns ``āᵢ``.

    ``D = X_refᵀ Ψ (N, n_pixel)`` (the DCT of every reference image), and row ``i`` of ``Y_ref``
    (column ``i`` of ``Y_refᵀ``) is coded as ``ȳᵢ ≈ D āᵢ`` by :func:`~cssat.sparse.batch_omp` —
    all ``m`` rows in one batched call, with ``T₀ = n_nonzero_coefs`` (Eq. 28) and/or the squared
    error bound ``tol = ε₀²`` (Eq. 29). Then ``Φ̂ = Âᵀ Ψᵀ`` (Eq. 30).

    ``D``'s columns have very unequal norms (the images are non-negative, so the DC column
    dominates); OMP selects atoms on the normalised columns and the coefficients are scaled back,
    so a frequency is chosen for how well it explains ``ȳᵢ``, not for its energy in the references
    (``normalize=False``: select on the raw columns, scikit-learn's convention).

    ``shape`` is the image shape (default: square ``√n_pixel``). Returns ``Φ̂ (m, n_pixel)`` and,
    with ``return_info``, a :class:`SparseEstimate`. ``progress``: the OMP's tqdm bar
    (:func:`~cssat.sparse.batch_omp`).
    """
    n_pixel, N, m = _check(X_ref, Y_ref)
    if shape is None:
        side = math.isqrt(n_pixel)
        if side * side != n_pixel:
            raise FieldError("shape", f"n_pixel={n_pixel} is not a square; give the image shape")
        shape = (side, side)
    shape = tuple(int(s) for s in shape)
    if math.prod(shape) != n_pixel:
        raise FieldError("shape", f"{shape} does not have n_pixel={n_pixel} pixels")
    if n_nonzero_coefs is None and tol is None:
        raise FieldError("n_nonzero_coefs", "give T0 (Eq. 28), eps0^2 (Eq. 29) or both")
    psi = DCT(shape)
    D = psi.adjoint(X_ref.T.contiguous())  # (N, n_pixel): row k is the DCT of reference k
    norms = torch.linalg.vector_norm(D, dim=0)
    ok = norms > 0
    if not normalize:
        norms = torch.ones_like(norms)
    scale = torch.where(ok, norms, torch.ones_like(norms))
    Dn = D.div_(scale)  # in place: D (N × n_pixel, 0.9 GB at 128²) is not needed again
    del D
    coef, oinfo = batch_omp(Dn, Y_ref.to(Dn.dtype), n_nonzero_coefs=n_nonzero_coefs, tol=tol, return_info=True,
                            progress=progress)
    del Dn
    coef.div_(scale)
    if not bool(ok.all()):  # atoms of zero norm (a pixel frequency no reference has) get no coefficient
        coef[:, ~ok] = 0
    phi_hat = psi(coef)  # rows: Φ̂ᵢ = Ψ āᵢ
    if return_info:
        return phi_hat, SparseEstimate(coef, oinfo.n_iter, oinfo.residual_sq)
    return phi_hat


@numpy_io
def relative_error(phi_hat: Tensor, phi: Tensor) -> float:
    """``‖Φ̂ − Φ‖_F / ‖Φ‖_F``, computed in row blocks (no full-size temporary)."""
    if phi_hat.shape != phi.shape:
        raise FieldError("phi_hat", f"shape {tuple(phi_hat.shape)} differs from phi {tuple(phi.shape)}")
    num = den = 0.0
    for s in range(0, phi.shape[0], 1024):
        a, b = phi_hat[s : s + 1024].double(), phi[s : s + 1024].double()
        num += float(((a - b) ** 2).sum())
        den += float((b**2).sum())
    if den == 0:
        raise FieldError("phi", "the reference Φ is zero: its relative error is undefined")
    return math.sqrt(num / den)
