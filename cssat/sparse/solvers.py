"""Iterative reconstruction beyond OMP: ℓ1 in a dictionary (FISTA), total variation (primal–dual),
plug-and-play and projected Landweber — each an :class:`~cssat.sparse.iterate.Iteration` (its
state and its step) run by the one loop :func:`~cssat.sparse.iterate.run_iterations`.

All take the forward operator as an ``nn.Module``-style :class:`~cssat.sparse.LinearOperator`
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

from cssat._checks import FieldError
from cssat.sparse._io import numpy_io
from cssat.sparse.differences import image_shape, tv_divergence, tv_gradient
from cssat.sparse.iterate import Iteration, relative_change, run_iterations
from cssat.sparse.operators import LinearOperator, as_operator
from cssat.sparse.tv_admm import relative_weight

if TYPE_CHECKING:
    from typing import Callable

    from cssat._types import Array, OperatorLike

__all__ = ["fista_l1", "tv_pdhg", "pnp_pgd", "landweber", "operator_norm_sq", "SolverInfo", "tv_gradient", "tv_divergence"]

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


def operator_norm_sq(A: OperatorLike, *, n_iter: int = 50, dtype: torch.dtype = torch.float64,
                     device: torch.device | str | None = None, seed: int = 0) -> float:
    """``‖A‖²`` (the largest eigenvalue of ``AᵀA``) by power iteration, with a 1 % safety margin
    (the Lipschitz constant of the data term's gradient)."""
    op = as_operator(A, "A")
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
        raise FieldError("y", f"expected shape (B, {n_out}) or ({n_out},), got {tuple(y.shape)}")
    if not bool(torch.isfinite(y2).all()):
        raise FieldError("y", "contains NaN or Inf")
    if not (isinstance(lam, (int, float)) and math.isfinite(lam) and lam >= 0):
        raise FieldError("lam", f"the relative weight must be finite and >= 0, got {lam!r}")
    if isinstance(max_iter, bool) or int(max_iter) != max_iter or max_iter < 1:
        raise FieldError("max_iter", f"must be an integer >= 1, got {max_iter!r}")
    if not rtol >= 0:
        raise FieldError("rtol", f"must be >= 0, got {rtol!r}")
    return y2, squeeze


def _rows(y: Tensor, n_out: int) -> tuple[Tensor, bool]:
    squeeze = y.ndim == 1
    y2 = y[None] if squeeze else y
    if y2.ndim != 2 or y2.shape[1] != n_out:
        raise FieldError("y", f"expected shape (B, {n_out}) or ({n_out},), got {tuple(y.shape)}")
    return y2, squeeze


class _FISTA(Iteration):
    """FISTA's state: the iterate ``x``, the extrapolated point ``z`` and the momentum ``t``."""

    label = "FISTA (ℓ1)"

    def __init__(self, op: LinearOperator, y: Tensor, lam_abs: Tensor, L: float, nonneg: bool = False):
        self.op, self.y, self.lam_abs, self.L, self.nonneg = op, y, lam_abs, L, nonneg
        self.thr = lam_abs / L
        self.x = torch.zeros(y.shape[0], op.n_in, dtype=y.dtype, device=y.device)
        self.z = self.x.clone()
        self.t = 1.0

    def step(self, k: int) -> Tensor:
        grad = self.op.adjoint(self.op(self.z) - self.y)
        v = self.z - grad / self.L
        if self.nonneg:  # the prox of λ Σ x + the indicator of x ≥ 0
            x_new = torch.clamp(v - self.thr, min=0)
        else:
            x_new = torch.sign(v) * torch.clamp(v.abs() - self.thr, min=0)
        t_new = (1 + math.sqrt(1 + 4 * self.t * self.t)) / 2
        self.z = x_new + ((self.t - 1) / t_new) * (x_new - self.x)
        change = relative_change(x_new, self.x)
        self.x, self.t = x_new, t_new
        return change

    def objective(self) -> float:
        r = self.op(self.x) - self.y
        return float((0.5 * (r * r).sum(1) + self.lam_abs[:, 0] * self.x.abs().sum(1)).sum())


@numpy_io
def fista_l1(
    A: OperatorLike,
    y: Array,
    *,
    lam: float = 1e-3,
    max_iter: int = 500,
    rtol: float = 1e-6,
    lipschitz: float | None = None,
    nonneg: bool = False,
    return_info: bool = False,
    progress: bool | None = None,
    callback: Callable | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """ℓ1-regularised least squares by FISTA (Beck & Teboulle 2009):
    ``min_γ ½‖Aγ − y‖² + λ‖γ‖₁`` for every row of ``y``.

    ``A`` is the CS dictionary ``ΦΨ (m, n)`` as an operator or matrix; ``y (B, m)`` or ``(m,)``.
    ``λ = lam · ‖Aᵀy‖_∞`` per signal. The step is ``1/L`` with ``L = ‖A‖²`` from a power
    iteration (or ``lipschitz``). Stops when ``‖γₖ − γₖ₋₁‖ ≤ rtol ‖γₖ‖`` for every signal or after
    ``max_iter`` iterations. ``nonneg``: over ``γ ≥ 0`` (the ℓ1 term is then ``λ Σ γ``).
    Returns ``γ (B, n)`` (and a :class:`SolverInfo`). ``progress``: a
    tqdm bar of the iterations (``None``: on a terminal, after a second); ``callback(k, state)``
    after each iteration (``True`` stops).
    """
    op = as_operator(A, "A")
    y2, squeeze = _check(y, op.n_out, lam, max_iter, rtol)
    L = operator_norm_sq(op, dtype=y2.dtype, device=y2.device) if lipschitz is None else float(lipschitz)
    if not L > 0:
        raise FieldError("A", "the operator is zero")
    lam_abs = lam * op.adjoint(y2).abs().amax(1, keepdim=True)
    alg = _FISTA(op, y2, lam_abs, L, bool(nonneg))
    info = run_iterations(alg, max_iter, rtol=rtol, progress=progress, callback=callback)
    out = alg.x[0] if squeeze else alg.x
    if return_info:
        return out, SolverInfo(info.n_iter, info.objective, info.converged, lam_abs[:, 0], 1.0 / L)
    return out


class _ChambollePock(Iteration):
    """The primal ``x``, its extrapolation ``x̄``, the duals ``p`` (of ∇) and ``q`` (of Φ)."""

    label = "TV (Chambolle-Pock)"

    def __init__(self, op: LinearOperator, y: Tensor, shape: tuple[int, int], lam_abs: Tensor, step: float, nonneg: bool):
        B, (H, W) = y.shape[0], shape
        self.op, self.y, self.shape, self.lam_abs, self.nonneg = op, y, (B, H, W), lam_abs, nonneg
        self.sigma = self.tau = step
        self.x = torch.zeros(B, H, W, dtype=y.dtype, device=y.device)
        self.xbar = self.x.clone()
        self.p = torch.zeros(B, 2, H, W, dtype=y.dtype, device=y.device)
        self.q = torch.zeros_like(y)

    def step(self, k: int) -> Tensor:
        B = self.shape[0]
        sigma, tau = self.sigma, self.tau
        p = self.p + sigma * tv_gradient(self.xbar)
        norm = torch.sqrt((p * p).sum(1, keepdim=True))
        self.p = p / torch.clamp(norm / self.lam_abs.clamp_min(torch.finfo(p.dtype).tiny), min=1.0)
        self.q = (self.q + sigma * (self.op(self.xbar.reshape(B, -1)) - self.y)) / (1 + sigma)
        x_new = self.x - tau * (-tv_divergence(self.p) + self.op.adjoint(self.q).reshape(self.shape))
        if self.nonneg:
            x_new = x_new.clamp_min(0)
        self.xbar = 2 * x_new - self.x
        change = relative_change(x_new, self.x)
        self.x = x_new
        return change

    def objective(self) -> float:
        B = self.shape[0]
        r = self.op(self.x.reshape(B, -1)) - self.y
        g = tv_gradient(self.x)
        tv = torch.sqrt((g * g).sum(1)).flatten(1).sum(1)
        return float((0.5 * (r * r).sum(1) + self.lam_abs.flatten() * tv).sum())


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
    callback: Callable | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """Isotropic total variation by the primal–dual method of Chambolle & Pock (2011):
    ``min_x ½‖Φx − y‖² + λ TV(x)`` (``+ x ≥ 0`` when ``nonneg``), ``TV(x) = Σ ‖(∇x)ᵢ‖₂``.

    ``phi (m, N)`` as an operator or matrix; ``y (B, m)`` or ``(m,)``; images of ``shape (H, W)``.
    ``λ = lam · ‖Φᵀy‖_∞`` per signal (on a centred system's fluctuation rows). Step sizes ``σ = τ = 0.99 / ‖K‖`` with
    ``‖K‖² ≤ ‖Φ‖² + 8`` for ``K = [Φ; ∇]``. Stops when ``‖xₖ − xₖ₋₁‖ ≤ rtol ‖xₖ‖`` for every signal.
    Returns images ``(B, H, W)`` or ``(H, W)`` (and a :class:`SolverInfo`). ``progress`` and
    ``callback`` as in :func:`fista_l1`.
    """
    op = as_operator(phi, "phi")
    H, W = image_shape(shape, op.n_in)
    y2, squeeze = _check(y, op.n_out, lam, max_iter, rtol)
    B = y2.shape[0]
    step = 0.99 / math.sqrt(operator_norm_sq(op, dtype=y2.dtype, device=y2.device) + 8.0)
    lam_abs = relative_weight(op, y2, lam).reshape(B, 1, 1, 1)  # a centred system: on its fluctuation rows
    alg = _ChambollePock(op, y2, (H, W), lam_abs, step, nonneg)
    info = run_iterations(alg, max_iter, rtol=rtol, progress=progress, callback=callback)
    out = alg.x[0] if squeeze else alg.x
    if return_info:
        return out, SolverInfo(info.n_iter, info.objective, info.converged, lam_abs.flatten(), step)
    return out


class _DataFit(Iteration):
    """An iteration whose objective is the data misfit ``½‖Ax − y‖²`` of its iterate ``x (B, N)``."""

    def objective(self) -> float:
        r = self.op(self.x) - self.y
        return float(0.5 * (r * r).sum())


class _PnP(_DataFit):
    """The iterate ``x (B, N)``; step ``k`` denoises at ``σ = sigmas[k − 1]``."""

    label = "PnP"

    def __init__(self, op, y, shape, denoiser, sigmas, L, x0):
        self.op, self.y, self.denoiser, self.sigmas, self.L = op, y, denoiser, sigmas, L
        self.shape = (y.shape[0], *shape)
        self.x = torch.zeros(y.shape[0], op.n_in, dtype=y.dtype, device=y.device) if x0 is None else x0.reshape(y.shape[0], -1).to(y)

    def step(self, k: int) -> None:
        v = (self.x - self.op.adjoint(self.op(self.x) - self.y) / self.L).reshape(self.shape)  # the gradient step, batched
        s = self.sigmas[k - 1]
        self.x = torch.stack([torch.as_tensor(self.denoiser(v[b], s), dtype=self.y.dtype, device=self.y.device).reshape(-1)
                              for b in range(self.shape[0])])  # the denoiser, image by image
        return None


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
    callback: Callable | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """Plug-and-play proximal gradient (Venkatakrishnan et al. 2013; PnP-ISTA):
    ``xₖ₊₁ = D(xₖ − Φᵀ(Φxₖ − y)/L, σₖ)`` with a decreasing noise level ``σₖ`` (image units).

    ``denoiser(image (H, W), sigma) -> image`` is any denoiser — sparse K-SVD, TV, wavelets, BM3D
    — which replaces the proximal step of a regulariser. ``phi (m, N)``, ``y (B, m)`` or ``(m,)``
    (the gradient steps are batched, the denoiser runs image by image); ``x0`` the start
    (default ``0``). One iteration per ``σ`` in ``sigmas``. Returns ``(B, H, W)`` or ``(H, W)``
    (and a :class:`SolverInfo` whose objective is the summed data misfit ``½‖Φx − y‖²``, one
    value per iteration). ``progress`` and ``callback`` as in :func:`fista_l1`.
    """
    op = as_operator(phi, "phi")
    H, W = image_shape(shape, op.n_in)
    y2, squeeze = _rows(y, op.n_out)
    sigmas = [float(s) for s in sigmas]
    if not sigmas or any(not (math.isfinite(s) and s >= 0) for s in sigmas):
        raise FieldError("sigmas", f"expected a non-empty list of noise levels >= 0, got {sigmas}")
    L = operator_norm_sq(op, dtype=y2.dtype, device=y2.device)
    alg = _PnP(op, y2, (H, W), denoiser, sigmas, L, x0)
    info = run_iterations(alg, len(sigmas), progress=progress, objective_every=1, callback=callback)
    out = alg.x.reshape(H, W) if squeeze else alg.x.reshape(-1, H, W)
    if return_info:
        return out, SolverInfo(info.n_iter, info.objective, True, torch.tensor(sigmas), 1.0 / L)
    return out


class _Landweber(_DataFit):
    """The iterate ``x (B, N)`` of projected Landweber."""

    label = "Landweber"

    def __init__(self, op, y, tau, lower, upper):
        self.op, self.y, self.tau, self.lower, self.upper = op, y, tau, lower, upper
        self.x = torch.zeros(y.shape[0], op.n_in, dtype=y.dtype, device=y.device)

    def step(self, k: int) -> Tensor:
        x_new = self.x - self.tau * self.op.adjoint(self.op(self.x) - self.y)
        if self.lower is not None or self.upper is not None:
            x_new = x_new.clamp(self.lower, self.upper)  # the projection on the box
        change = relative_change(x_new, self.x)
        self.x = x_new
        return change


@numpy_io
def landweber(
    A: OperatorLike,
    y: Array,
    *,
    relaxation: float = 1.0,
    lower: float | None = 0.0,
    upper: float | None = None,
    max_iter: int = 500,
    rtol: float = 1e-6,
    return_info: bool = False,
    progress: bool | None = None,
    callback: Callable | None = None,
) -> Array | tuple[Array, SolverInfo]:
    """Projected Landweber iteration (Landweber 1951; projected onto a box, e.g. Bertero &
    Boccacci 1998, §6): ``xₖ₊₁ = P(xₖ − τ Aᵀ(Axₖ − y))``, ``τ = relaxation / ‖A‖²``, ``P`` the
    projection on ``lower ≤ x ≤ upper`` (``None``: unbounded). Converges to a minimiser of
    ``½‖Ax − y‖²`` on the box for ``0 < relaxation < 2``; stopped early it regularises (the
    iteration count plays the part of λ). ``A (m, N)``, ``y (B, m)`` or ``(m,)``; returns
    ``(B, N)`` or ``(N,)`` (and a :class:`SolverInfo`, objective ``½‖Ax − y‖²``). ``progress``
    and ``callback`` as in :func:`fista_l1`.
    """
    op = as_operator(A, "A")
    y2, squeeze = _check(y, op.n_out, 0.0, max_iter, rtol)
    if not (isinstance(relaxation, (int, float)) and 0 < relaxation < 2):
        raise FieldError("relaxation", f"must be in (0, 2), got {relaxation!r}")
    L = operator_norm_sq(op, dtype=y2.dtype, device=y2.device)
    if not L > 0:
        raise FieldError("A", "the operator is zero")
    tau = float(relaxation) / L
    alg = _Landweber(op, y2, tau, lower, upper)
    info = run_iterations(alg, max_iter, rtol=rtol, progress=progress, callback=callback)
    out = alg.x[0] if squeeze else alg.x
    if return_info:
        return out, SolverInfo(info.n_iter, info.objective, info.converged, torch.zeros(y2.shape[0]), tau)
    return out
