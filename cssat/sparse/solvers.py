"""Convex reconstruction beyond OMP: ℓ1 in a dictionary (FISTA) and total variation (primal–dual).

Both take the forward operator as an ``nn.Module``-style :class:`~cssat.sparse.LinearOperator`
(or a dense matrix) with ``forward``/``adjoint``, work on batches of signals (rows) and follow the
input's device and dtype. Regularisation weights are given *relative to the data*:
``λ = lam · ‖Aᵀy‖_∞`` — the ℓ1 problem's solution is zero for ``lam ≥ 1`` — so one default
works across m and across image scales.
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING, NamedTuple, Sequence

import torch
from torch import Tensor

from cssat.sparse.operators import LinearOperator, MatrixOperator
from cssat.sparse._io import numpy_io

if TYPE_CHECKING:
    from typing import Callable

    from cssat._types import Array, OperatorLike

__all__ = ["fista_l1", "tv_pdhg", "pnp_pgd", "operator_norm_sq", "SolverInfo", "tv_gradient", "tv_divergence"]

log = logging.getLogger("cssat")


class SolverInfo(NamedTuple):
    """``n_iter``: iterations run; ``objective``: the objective per iteration (summed over the
    batch); ``converged``: whether the relative-change rule stopped it; ``lam``: the absolute
    weights used, ``(B,)``; ``step``: the step size(s)."""

    n_iter: int
    objective: list
    converged: bool
    lam: Tensor
    step: float


def _as_operator(A) -> LinearOperator:
    if isinstance(A, LinearOperator):
        return A
    if isinstance(A, Tensor) and A.ndim == 2:
        return MatrixOperator(A)
    raise TypeError("A: expected a LinearOperator or a 2-D matrix")


def operator_norm_sq(A: OperatorLike, *, n_iter: int = 50, dtype: torch.dtype = torch.float64,
                     device: torch.device | str | None = None, seed: int = 0) -> float:
    """``‖A‖²`` (the largest eigenvalue of ``AᵀA``) by power iteration, with a 1 % safety margin
    (the Lipschitz constant of the data term's gradient)."""
    op = _as_operator(A)
    g = torch.Generator().manual_seed(seed)
    v = torch.randn(1, op.n_in, generator=g, dtype=dtype).to(device)
    v /= v.norm()
    est = 0.0
    for _ in range(int(n_iter)):
        w = op.adjoint(op(v))
        est = float(w.norm())
        if est == 0:
            return 0.0
        v = w / est
    return est * 1.01


def _check(y: Tensor, n_out: int, lam: float, max_iter: int, rtol: float) -> tuple[Tensor, bool]:
    squeeze = y.ndim == 1
    y2 = y[None] if squeeze else y
    if y2.ndim != 2 or y2.shape[1] != n_out:
        raise ValueError(f"y: expected shape (B, {n_out}) or ({n_out},), got {tuple(y.shape)}")
    if not bool(torch.isfinite(y2).all()):
        raise ValueError("y: contains NaN or Inf")
    if not (isinstance(lam, (int, float)) and math.isfinite(lam) and lam >= 0):
        raise ValueError(f"lam: the relative weight must be finite and >= 0, got {lam!r}")
    if isinstance(max_iter, bool) or int(max_iter) != max_iter or max_iter < 1:
        raise ValueError(f"max_iter: must be an integer >= 1, got {max_iter!r}")
    if not rtol >= 0:
        raise ValueError(f"rtol: must be >= 0, got {rtol!r}")
    return y2, squeeze


@numpy_io
def fista_l1(
    A: OperatorLike,
    y: Array,
    *,
    lam: float = 1e-3,
    max_iter: int = 500,
    rtol: float = 1e-6,
    lipschitz: float | None = None,
    return_info: bool = False,
    progress: bool | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """ℓ1-regularised least squares by FISTA (Beck & Teboulle 2009):
    ``min_γ ½‖Aγ − y‖² + λ‖γ‖₁`` for every row of ``y``.

    ``A`` is the CS dictionary ``ΦΨ (m, n)`` as an operator or matrix; ``y (B, m)`` or ``(m,)``.
    ``λ = lam · ‖Aᵀy‖_∞`` per signal. The step is ``1/L`` with ``L = ‖A‖²`` from a power
    iteration (or ``lipschitz``). Stops when ``‖γₖ − γₖ₋₁‖ ≤ rtol ‖γₖ‖`` for every signal or after
    ``max_iter`` iterations. Returns ``γ (B, n)`` (and a :class:`SolverInfo`). ``progress``: a
    tqdm bar of the iterations (``None``: on a terminal, after a second).
    """
    from cssat._progress import progress_bar

    op = _as_operator(A)
    y2, squeeze = _check(y, op.n_out, lam, max_iter, rtol)
    L = operator_norm_sq(op, dtype=y2.dtype, device=y2.device) if lipschitz is None else float(lipschitz)
    if not L > 0:
        raise ValueError("A: the operator is zero")
    aty = op.adjoint(y2)
    lam_abs = lam * aty.abs().amax(1, keepdim=True)
    thr = lam_abs / L
    x = torch.zeros_like(aty)
    z = x.clone()
    t = 1.0
    objective, converged, k = [], False, 0
    bar = progress_bar(int(max_iter), "FISTA (ℓ1)", progress, unit="iter")
    for k in range(1, int(max_iter) + 1):
        bar.update()
        grad = op.adjoint(op(z) - y2)
        v = z - grad / L
        x_new = torch.sign(v) * torch.clamp(v.abs() - thr, min=0)
        t_new = (1 + math.sqrt(1 + 4 * t * t)) / 2
        z = x_new + ((t - 1) / t_new) * (x_new - x)
        change = (x_new - x).norm(dim=1) / x_new.norm(dim=1).clamp_min(torch.finfo(x.dtype).tiny)
        x, t = x_new, t_new
        if k % 10 == 0 or k == 1:
            r = op(x) - y2
            objective.append(float((0.5 * (r * r).sum(1) + lam_abs[:, 0] * x.abs().sum(1)).sum()))
        if bool((change <= rtol).all()):
            converged = True
            break
    bar.close()
    log.debug("fista_l1: %d iterations, converged=%s", k, converged)
    out = x[0] if squeeze else x
    if return_info:
        return out, SolverInfo(k, objective, converged, lam_abs[:, 0], 1.0 / L)
    return out


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


@numpy_io
def tv_pdhg(
    phi: OperatorLike,
    y: Array,
    shape: Sequence[int],
    *,
    lam: float = 1e-4,
    nonneg: bool = True,
    max_iter: int = 1000,
    rtol: float = 1e-5,
    return_info: bool = False,
    progress: bool | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """Isotropic total variation by the primal–dual method of Chambolle & Pock (2011):
    ``min_x ½‖Φx − y‖² + λ TV(x)`` (``+ x ≥ 0`` when ``nonneg``), ``TV(x) = Σ ‖(∇x)ᵢ‖₂``.

    ``phi (m, N)`` as an operator or matrix; ``y (B, m)`` or ``(m,)``; images of ``shape (H, W)``.
    ``λ = lam · ‖Φᵀy‖_∞`` per signal. Step sizes ``σ = τ = 0.99 / ‖K‖`` with
    ``‖K‖² ≤ ‖Φ‖² + 8`` for ``K = [Φ; ∇]``. Stops when ``‖xₖ − xₖ₋₁‖ ≤ rtol ‖xₖ‖`` for every signal.
    Returns images ``(B, H, W)`` or ``(H, W)`` (and a :class:`SolverInfo`). ``progress`` as in
    :func:`fista_l1`.
    """
    from cssat._progress import progress_bar

    op = _as_operator(phi)
    H, W = (int(s) for s in shape)
    if H * W != op.n_in:
        raise ValueError(f"shape: {tuple(shape)} does not match the operator's {op.n_in} pixels")
    y2, squeeze = _check(y, op.n_out, lam, max_iter, rtol)
    B = y2.shape[0]
    Lphi = operator_norm_sq(op, dtype=y2.dtype, device=y2.device)
    step = 0.99 / math.sqrt(Lphi + 8.0)
    sigma = tau = step
    aty = op.adjoint(y2)
    lam_abs = (lam * aty.abs().amax(1)).reshape(B, 1, 1, 1)
    x = torch.zeros(B, H, W, dtype=y2.dtype, device=y2.device)
    xbar = x.clone()
    p = torch.zeros(B, 2, H, W, dtype=y2.dtype, device=y2.device)
    q = torch.zeros_like(y2)
    objective, converged, k = [], False, 0
    bar = progress_bar(int(max_iter), "TV (Chambolle-Pock)", progress, unit="iter")
    for k in range(1, int(max_iter) + 1):
        bar.update()
        p = p + sigma * tv_gradient(xbar)
        norm = torch.sqrt((p * p).sum(1, keepdim=True))
        p = p / torch.clamp(norm / lam_abs.clamp_min(torch.finfo(p.dtype).tiny), min=1.0)
        q = (q + sigma * (op(xbar.reshape(B, -1)) - y2)) / (1 + sigma)
        x_new = x - tau * (-tv_divergence(p) + op.adjoint(q).reshape(B, H, W))
        if nonneg:
            x_new = x_new.clamp_min(0)
        xbar = 2 * x_new - x
        change = (x_new - x).flatten(1).norm(dim=1) / x_new.flatten(1).norm(dim=1).clamp_min(torch.finfo(x.dtype).tiny)
        x = x_new
        if k % 10 == 0 or k == 1:
            r = op(x.reshape(B, -1)) - y2
            g = tv_gradient(x)
            tv = torch.sqrt((g * g).sum(1)).flatten(1).sum(1)
            objective.append(float((0.5 * (r * r).sum(1) + lam_abs.flatten() * tv).sum()))
        if bool((change <= rtol).all()):
            converged = True
            break
    bar.close()
    log.debug("tv_pdhg: %d iterations, converged=%s", k, converged)
    out = x[0] if squeeze else x
    if return_info:
        return out, SolverInfo(k, objective, converged, lam_abs.flatten(), step)
    return out


@numpy_io
def pnp_pgd(
    phi: OperatorLike,
    y: Array,
    shape: Sequence[int],
    denoiser: Callable[[Tensor, float], Array],
    *,
    sigmas: Sequence[float],
    x0: Tensor | None = None,
    return_info: bool = False,
    progress: bool | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """Plug-and-play proximal gradient (Venkatakrishnan et al. 2013; PnP-ISTA):
    ``xₖ₊₁ = D(xₖ − Φᵀ(Φxₖ − y)/L, σₖ)`` with a decreasing noise level ``σₖ`` (image units).

    ``denoiser(image (H, W), sigma) -> image`` is any denoiser — sparse K-SVD, TV, wavelets, BM3D
    — which replaces the proximal step of a regulariser. ``phi (m, N)``, ``y (B, m)`` or ``(m,)``
    (the gradient steps are batched, the denoiser runs image by image); ``x0`` the start
    (default ``0``). One iteration per ``σ`` in ``sigmas``. Returns ``(B, H, W)`` or ``(H, W)``
    (and a :class:`SolverInfo` whose objective is the summed data misfit ``½‖Φx − y‖²``).
    ``progress`` as in :func:`fista_l1`.
    """
    from cssat._progress import progress_bar

    op = _as_operator(phi)
    H, W = (int(s) for s in shape)
    if H * W != op.n_in:
        raise ValueError(f"shape: {tuple(shape)} does not match the operator's {op.n_in} pixels")
    squeeze = y.ndim == 1
    y2 = y[None] if squeeze else y
    if y2.ndim != 2 or y2.shape[1] != op.n_out:
        raise ValueError(f"y: expected shape (B, {op.n_out}) or ({op.n_out},), got {tuple(y.shape)}")
    sigmas = [float(s) for s in sigmas]
    if not sigmas or any(not (math.isfinite(s) and s >= 0) for s in sigmas):
        raise ValueError(f"sigmas: expected a non-empty list of noise levels >= 0, got {sigmas}")
    L = operator_norm_sq(op, dtype=y2.dtype, device=y2.device)
    B = y2.shape[0]
    x = torch.zeros(B, H * W, dtype=y2.dtype, device=y2.device) if x0 is None else x0.reshape(B, -1).to(y2)
    misfit = []
    for s in progress_bar(None, "PnP", progress, unit="iter", iterable=sigmas):
        v = (x - op.adjoint(op(x) - y2) / L).reshape(B, H, W)  # the gradient step, batched
        x = torch.stack([torch.as_tensor(denoiser(v[b], s), dtype=y2.dtype, device=y2.device).reshape(-1)
                         for b in range(B)])  # the denoiser, image by image
        r = op(x) - y2
        misfit.append(float(0.5 * (r * r).sum()))
    out = x.reshape(H, W) if squeeze else x.reshape(B, H, W)
    if return_info:
        return out, SolverInfo(len(sigmas), misfit, True, torch.tensor(sigmas), 1.0 / L)
    return out
