"""Total variation by ADMM with an exact linear solve, and the discrepancy principle for its weight.

``min_x ½‖Ax − y‖² + λ TV(x)`` (``x ≥ 0`` when ``nonneg``), ``TV(x) = Σ_g ‖(Dx)_g‖₂`` for any
difference operator ``D`` (:mod:`cssat.sparse.differences`: the image gradient, grouped per pixel
— the isotropic TV —, or a graph's edges, each its own group — e.g. the EGI's normals on the
sphere), split as ``z₁ = Dx``, ``z₂ = x`` (Boyd et al. 2011, §6.4.1; Goldstein & Osher's split
Bregman): each iteration solves ``(AᵀA + ρ(DᵀD + I)) x = Aᵀy + ρDᵀ(z₁ − u₁) + ρ(z₂ − u₂)``
exactly — with the inverse of that ``N × N`` matrix formed once per operator, ``D`` and ``ρ`` and
reused by every signal, weight and call — then shrinks ``Dx + u₁`` group-wise by ``λ/ρ`` and
projects ``x + u₂`` on ``x ≥ 0``. One iteration on :mod:`cssat.sparse.iterate`'s runner.

Why beside the primal–dual :func:`~cssat.sparse.solvers.tv_pdhg`: a positive sensing matrix
centred on its common term (:class:`cssat.physics.Centered`) has ``‖A‖² ≈ 10⁴–10⁵`` in one
direction (the common mode) and ``~10⁻²–10`` in the directions that carry the image. A primal–dual
method's steps are ``∝ 1/‖K‖``, so in 2000 iterations its TV dual never reaches ``λ`` and the
result does not depend on ``λ`` at all (measured: 32², phase screen, ``λ`` from 0.02 to 3 ×
‖Aᵀb‖∞ gave the same image). The exact solve is blind to that spread: the same cases converge in
100–700 iterations and respond to ``λ``. The cost is the ``N × N`` inverse (``N ≤``
:data:`ADMM_MAX_PIXELS`): ~1 s at 64² on 2 cores, then one matrix product per iteration.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable, Sequence

import torch
from torch import Tensor

from cssat._checks import FieldError
from cssat.sparse.differences import Differences, ImageGradient, image_shape
from cssat.sparse.iterate import Iteration, RunInfo, run_iterations
from cssat.sparse.operators import LinearOperator, as_operator

if TYPE_CHECKING:
    from cssat._types import OperatorLike

__all__ = ["tv_admm", "tv_discrepancy", "scale_rows", "relative_weight", "flat_fit", "inverse_variance", "ADMM_MAX_PIXELS",
           "DEFAULT_RHO"]

#: the largest image (pixels) ADMM's ``N × N`` inverse is formed for (8192² float64: 512 MiB)
ADMM_MAX_PIXELS = 8192
#: iterations of each warm-started solve of the λ search (the chosen λ is solved to ``rtol`` after)
SEARCH_ITER = 300
#: the search stops when, after a weight that fitted better than the flat image, a 10× weaker one
#: lowers the misfit by less than 1 %: the data misfit
#: the model itself (a moving scene, a wrong Φ), and no weight will fit to the noise
STALL = 0.99
#: ADMM's over-relaxation (1: none; 1.5–1.8 is the usual choice)
RELAXATION = 1.6
#: ``ρ = DEFAULT_RHO · λ`` (absolute): ADMM's penalty follows the weight. Measured on centred
#: phase-screen systems at 32², λ from 1e-4 to 1 × ‖Aᵀb‖∞: 10 converges in 100–480 iterations to
#: rtol 1e-4, 1 in 565–2900, 0.1 not in 3000; a fixed ρ converges only near one λ
DEFAULT_RHO = 10.0


def scale_rows(op: LinearOperator, y: Tensor) -> tuple[LinearOperator | Tensor, Tensor]:
    """The rows a relative weight ``λ = lam · ‖Aᵀy‖∞`` is measured on: all of them, or the
    operator's ``scale_rows`` (a :class:`cssat.physics.Centered` system's fluctuation rows: its
    total-flux row would otherwise set λ by the flux alone). Returns ``(A_rows, y_rows)``."""
    rows = getattr(op, "scale_rows", None)
    if rows is None:
        return op, y
    return op.matrix()[rows], y[..., rows]


def relative_weight(op: LinearOperator, y: Tensor, lam: float) -> Tensor:
    """``lam · ‖A_rᵀ y_r‖∞`` per signal ``(B,)`` on :func:`scale_rows`' rows."""
    A, yr = scale_rows(op, y)
    g = yr @ A if isinstance(A, Tensor) else A.adjoint(yr)
    return lam * g.abs().amax(-1)


def _inverse(gram: Tensor, D: Differences, rho: float) -> Tensor:
    """``(AᵀA + ρ(DᵀD + I))⁻¹ (N, N)`` by Cholesky from the Gram ``AᵀA``, in its dtype and device."""
    Q = D.laplacian(gram.dtype, gram.device)
    Q += torch.eye(D.n, dtype=gram.dtype, device=gram.device)
    Q *= rho
    Q += gram
    L, info = torch.linalg.cholesky_ex(Q)
    if int(info) != 0:
        raise FieldError("rho", f"AᵀA + ρ(DᵀD + I) is not positive definite in {gram.dtype} at ρ = {rho:.3g}: use float64")
    return torch.cholesky_inverse(L)


def factor(op: LinearOperator, D: Differences, rho: float) -> Tensor:
    """``Q⁻¹`` of ``op`` and ``D`` at ``rho``, cached on the operator (its Gram ``AᵀA`` and the
    last few factors)."""
    if D.n > ADMM_MAX_PIXELS:
        raise FieldError("method", f"ADMM forms an N × N inverse; N = {D.n} > {ADMM_MAX_PIXELS}: use method=pdhg")
    cache = op.__dict__.setdefault("_tv_admm", {})
    if "gram" not in cache:
        A = op.matrix()
        cache["gram"] = A.T @ A
    key = (float(rho), D.key)
    if key not in cache:
        for k in [k for k in cache if k != "gram"][:-2]:  # keep the Gram and the two latest factors
            del cache[k]
        cache[key] = _inverse(cache["gram"], D, float(rho))
    return cache[key]


class _ADMM(Iteration):
    """``x (B, N)``, the split variables ``z₁ = Dx (B, G, *E)``, ``z₂ = x (B, N)`` and their scaled duals."""

    label = "TV (ADMM)"

    def __init__(self, op, y, D, lam_abs, rho, Qinv, nonneg, start=None):
        """``start``: :meth:`state` of a run at another weight (its scaled duals rescaled to ``rho``)."""
        B = y.shape[0]
        self.op, self.y, self.D, self.rho, self.Qinv, self.nonneg = op, y, D, rho, Qinv, nonneg
        self.lam_abs = lam_abs
        self.Aty = op.adjoint(y)
        if start is None:
            z = torch.zeros(B, op.n_in, dtype=y.dtype, device=y.device)
            p = torch.zeros_like(D.forward(z))
            start = (z, p, p.clone(), z.clone(), z.clone(), rho)
        self.x, self.z1, self.u1, self.z2, self.u2, rho0 = start
        self.thresh = (lam_abs / rho).reshape(B, *[1] * (self.z1.ndim - 1))
        self.u1, self.u2 = self.u1 * (rho0 / rho), self.u2 * (rho0 / rho)  # u = dual / ρ

    def state(self) -> tuple:
        return self.x, self.z1, self.u1, self.z2, self.u2, self.rho

    def step(self, k: int) -> Tensor:
        rho = self.rho
        rhs = self.Aty - rho * self.D.divergence(self.z1 - self.u1) + rho * (self.z2 - self.u2)
        x = rhs @ self.Qinv  # Q is symmetric
        g = self.D.forward(x)
        a = RELAXATION  # over-relaxation (Boyd et al. §3.4.3): Dx and x replaced by a·(them) + (1 − a)·z
        gr, xr = a * g + (1 - a) * self.z1, a * x + (1 - a) * self.z2
        v = gr + self.u1
        norm = torch.sqrt((v * v).sum(1, keepdim=True))
        z1 = v * torch.clamp(1 - self.thresh / norm.clamp_min(torch.finfo(v.dtype).tiny), min=0)
        self.u1 = v - z1
        z2 = (xr + self.u2).clamp_min(0) if self.nonneg else xr + self.u2
        self.u2 = self.u2 + xr - z2
        scale = x.norm(dim=1).clamp_min(torch.finfo(x.dtype).tiny)
        primal = torch.sqrt((g - z1).flatten(1).pow(2).sum(1) + (x - z2).pow(2).sum(1)) / scale
        change = (x - self.x).norm(dim=1) / scale
        self.x, self.z1, self.z2 = x, z1, z2
        return torch.maximum(primal, change)

    def image(self) -> Tensor:
        """The iterate ``(B, N)`` (the projected one when ``nonneg``)."""
        return self.z2 if self.nonneg else self.x

    def residual(self) -> Tensor:
        """``‖Ax − y‖²`` per signal ``(B,)`` of :meth:`image`."""
        r = self.op(self.image()) - self.y
        return (r * r).sum(1)

    def objective(self) -> float:
        return float((0.5 * self.residual() + self.lam_abs * self.D.norm(self.image())).sum())


def _differences(op: LinearOperator, shape: Sequence[int] | Differences) -> tuple[Differences, tuple[int, ...]]:
    """The difference operator and the unknown's shape: an image ``(H, W)``'s gradient, or ``D`` itself."""
    if isinstance(shape, Differences):
        D, out = shape, (shape.n,)
    else:
        out = image_shape(shape, op.n_in)
        D = ImageGradient(out)
    if D.n != op.n_in:
        raise FieldError("differences", f"{D.n} columns for the operator's {op.n_in} unknowns")
    return D, out


def tv_admm(phi: OperatorLike, y: Tensor, shape: Sequence[int] | Differences, *, lam: float = 1e-4, nonneg: bool = True,
            max_iter: int = 1000, rtol: float = 1e-5, rho: float | None = None, lam_abs: Tensor | None = None,
            start: tuple | None = None, progress: bool | None = None,
            callback: Callable | None = None) -> tuple[Tensor, RunInfo, Iteration]:
    """TV by ADMM with an exact solve: ``min ½‖Φx − y‖² + λ Σ_g ‖(Dx)_g‖₂`` (``x ≥ 0`` when
    ``nonneg``); on images (``shape (H, W)``: ``D = ∇``, the isotropic TV, the same problem as
    :func:`~cssat.sparse.solvers.tv_pdhg`) or on any :class:`~cssat.sparse.differences.Differences`
    given as ``shape`` (a graph's edges: the anisotropic TV).

    ``phi (m, N)`` an operator with a dense :meth:`matrix` (``N ≤`` :data:`ADMM_MAX_PIXELS`);
    ``y (B, m)``; ``λ = lam · ‖Φ_rᵀ y_r‖∞`` per signal on :func:`scale_rows`' rows (or
    ``lam_abs (B,)`` absolute). ``rho`` (default :data:`DEFAULT_RHO` × the mean absolute
    weight). Stops when the relative primal
    residual and the relative change of ``x`` are both ``≤ rtol``. Returns ``(images (B, H, W)``
    — or ``(B, N)`` for a ``Differences`` —, ``run info, the algorithm)`` — the last carries the
    state to warm-start another weight (``start=alg.state()``).
    """
    op = as_operator(phi, "phi")
    D, out_shape = _differences(op, shape)
    y2 = y.reshape(-1, op.n_out)
    if lam_abs is None:
        lam_abs = relative_weight(op, y2, lam)
    lam_abs = lam_abs.reshape(-1).to(y2)
    if rho is None:
        rho = DEFAULT_RHO * float(lam_abs.mean())
    if not (math.isfinite(rho) and rho > 0):
        raise FieldError("lam", f"ADMM needs a weight > 0 (ρ follows it), got λ = {lam_abs.tolist()}")
    Qinv = factor(op, D, rho)
    alg = _ADMM(op, y2, D, lam_abs, rho, Qinv.to(y2), nonneg, start)
    info = run_iterations(alg, max_iter, rtol=rtol, progress=progress, callback=callback)
    return alg.image().reshape(-1, *out_shape), info, alg


def flat_fit(op: LinearOperator, y: Tensor, weights: Tensor | None = None, nonneg: bool = True) -> Tensor:
    """The constant image that fits ``y (B, m)`` best in (weighted) least squares: ``α𝟙`` with
    ``α = ⟨A𝟙, W y⟩ / ⟨A𝟙, W A𝟙⟩`` (``α ≥ 0`` when ``nonneg``); ``(B, N)``. The estimate that
    knows only the total flux: what a TV weight → ∞ gives."""
    ones = torch.ones(1, op.n_in, dtype=y.dtype, device=y.device)
    a1 = op(ones)[0]
    w = torch.ones_like(a1) if weights is None else weights.to(a1)
    alpha = (y * (w * a1)).sum(-1) / (a1 * w * a1).sum().clamp_min(torch.finfo(a1.dtype).tiny)
    if nonneg:
        alpha = alpha.clamp_min(0)
    return alpha[:, None] * ones


def inverse_variance(var: Tensor) -> Tensor | None:
    """Least-squares weights ``1/σᵢ²`` (floored at 1e-12 of the largest variance); ``None`` —
    unweighted — when every variance is 0 (noiseless)."""
    top = float(var.max())
    return None if not top > 0 else 1.0 / var.clamp_min(top * 1e-12)


def tv_discrepancy(phi: OperatorLike, y: Tensor, shape: Sequence[int] | Differences, noise_var: Tensor, *,
                   nonneg: bool = True, max_iter: int = 1000, rtol: float = 1e-5, tau: float | None = None,
                   lams: Sequence[float] | None = None, rho: float | None = None, bisections: int = 3,
                   close: float | None = None, progress: bool | None = None) -> tuple[Tensor, dict[str, Any]]:
    """TV with its weight chosen by Morozov's discrepancy principle: the largest ``λ`` whose
    solution fits the data to the noise, ``‖Φx_λ − y‖² ≤ τ Σᵢ σᵢ²`` (Engl, Hanke & Neubauer 1996,
    §4.3), ``τ`` (default ``1 + 2√(2/m)``: the noise's own χ² spread, two standard deviations,
    so that the truth itself passes). ``λ = ∞`` — the flat image of the total flux
    (:func:`flat_fit`) — is the first candidate: when it already fits to the noise, the data hold
    nothing beyond the flux and that is the answer; otherwise ``lams`` (relative, default
    ``10⁰, 10⁻¹, …, 10⁻⁶``) are walked down with warm starts (:data:`SEARCH_ITER` iterations at
    ``10 rtol``) and the crossing is refined by ``bisections`` bisections in ``log λ`` (stopping
    early at a weight that fits with a misfit over ``(1 − close) τ Σσ²``, when ``close`` is given);
    the chosen weight is then solved to ``rtol``. When a weaker weight stops lowering a misfit it had begun to lower
    (:data:`STALL`) the walk stops there, unmet (``solver_discrepancy_met`` false): the model cannot fit the data.

    ``y (m,)`` one signal; ``noise_var`` the noise variance of each sample of ``y`` (``(m,)`` or
    a scalar, ``y``'s units squared; 0 for exact rows); ``shape`` an image's ``(H, W)`` or a
    :class:`~cssat.sparse.differences.Differences` (as :func:`tv_admm`). Returns ``(image (H, W)``
    — ``(N,)`` for a ``Differences`` —, ``info)`` with ``solver_lam`` (relative,
    ``inf`` for the flat image), ``solver_lam_abs``, ``solver_residual`` and ``solver_noise_norm``
    (``Σ σᵢ²``), ``solver_discrepancy_met``, ``solver_converged``, ``solver_iterations`` (all solves).
    """
    op = as_operator(phi, "phi")
    D, out_shape = _differences(op, shape)
    y2 = y.reshape(1, op.n_out)
    var = torch.as_tensor(noise_var, dtype=y2.dtype, device=y2.device).expand(op.n_out)
    if not bool(torch.isfinite(var).all()) or bool((var < 0).any()):
        raise FieldError("noise_var", "expected finite variances >= 0")
    tau = 1 + 2 * math.sqrt(2 / op.n_out) if tau is None else float(tau)
    target = tau * float(var.sum())
    flat = flat_fit(op, y2, inverse_variance(var), nonneg)
    r_flat = float(((op(flat) - y2) ** 2).sum())
    info: dict[str, Any] = {"solver_noise_norm": target, "solver_residual_flat": r_flat, "solver_iterations": 0}
    if r_flat <= target:
        info.update(solver_lam=math.inf, solver_lam_abs=math.inf, solver_residual=r_flat, solver_discrepancy_met=True,
                    solver_converged=True)
        return flat.reshape(out_shape), info
    ref = float(relative_weight(op, y2, 1.0)[0])
    grid = list(lams) if lams is not None else [10.0 ** -k for k in range(7)]
    solves: dict[float, tuple] = {}
    start = None

    def solve(lam: float, tol: float = 10 * rtol, iters: int = min(max_iter, SEARCH_ITER)):
        nonlocal start
        x, run, alg = tv_admm(op, y2, D, nonneg=nonneg, max_iter=iters, rtol=tol, rho=rho,
                              lam_abs=torch.tensor([lam * ref], dtype=y2.dtype, device=y2.device), start=start,
                              progress=progress)
        start = alg.state()
        info["solver_iterations"] += run.n_iter
        solves[lam] = (x[0].reshape(out_shape), float(alg.residual()[0]), run.converged)
        return solves[lam]

    hi, last = None, r_flat
    for lam in grid:  # from strong to weak: the first that fits to the noise
        res = solve(lam)[1]
        if res <= target:
            break
        if last < STALL * r_flat and res > STALL * last:  # it fitted better, and a weaker prior no longer
            break  # helps: the model, not λ, misfits
        hi, last = lam, res
    lo = lam
    if hi is not None and solves[lo][1] <= target:
        for _ in range(int(bisections)):  # bisect log λ between a weight that misfits (hi) and one that fits (lo)
            mid = math.sqrt(hi * lo)
            res = solve(mid)[1]
            if res <= target:
                lo = mid
                if close is not None and res >= (1 - close) * target:
                    break
            else:
                hi = mid
    x, res, conv = solve(lo, rtol, max_iter)
    info.update(solver_lam=lo, solver_lam_abs=lo * ref, solver_residual=res, solver_discrepancy_met=res <= target,
                solver_converged=conv)
    return x, info
