"""Non-negative recovery in the unknown's own basis: ``min ‖W (A x − y)‖² (+ a prior)`` over ``x ≥ 0``.

``W = diag(1/σ_t)`` (the noise's uncertainties; none: unweighted) and, optionally, exact linear
constraints ``C x = 0`` as ``k`` more rows of weight ``w_c`` (e.g. a closed body's EGI sums to a
zero vector). Methods (:data:`METHODS`):

* ``nnls`` — Lawson–Hanson non-negative least squares (``scipy.optimize.nnls``);
* ``nnomp`` — non-negative orthogonal matching pursuit: the atom most positively correlated with
  the residual joins the support, the support is refitted by NNLS; stops at ``n_nonzero`` atoms
  or when the weighted residual reaches the noise (``χ² ≤ T``, the discrepancy principle);
* ``l1`` — ``min ½‖W(Ax − y)‖² + λ Σ x`` over ``x ≥ 0`` by FISTA
  (:func:`~cssat.sparse.solvers.fista_l1` with ``nonneg``; ``λ = lam · ‖(WA)ᵀWy‖∞``);
* ``tv`` — ``min ½‖W(Ax − y)‖² + λ Σ_(i,j) |x_i − x_j|`` over ``x ≥ 0`` on a graph's edges ``D``
  (:mod:`cssat.sparse.differences`: a grid's, or points' nearest neighbours), by the one ADMM
  of :func:`~cssat.sparse.tv_admm.tv_admm`.

``lam="discrepancy"``: the largest λ whose fit reaches the noise, ``χ² ≤ T`` (Morozov's
principle; TV by :func:`~cssat.sparse.tv_admm.tv_discrepancy`'s warm-started walk, ℓ1 by bisection).
Nothing here knows what the unknown is.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.sparse.differences import GraphDifferences
from cssat.sparse.operators import MatrixOperator
from cssat.sparse.solvers import fista_l1
from cssat.sparse.tv_admm import tv_admm, tv_discrepancy

__all__ = ["METHODS", "lam_param", "weighted_system", "nonneg_solve", "fit_summary"]

METHODS = ("nnls", "nnomp", "l1", "tv")
#: the TV solve's relative primal residual and change at the end (ADMM)
TV_RTOL = 1e-9


def lam_param(lam: Any, field: str = "lam") -> float | str:
    """``lam`` of the ``l1`` and ``tv`` solves: a number ``>= 0`` or ``"discrepancy"``."""
    if isinstance(lam, str):
        if lam != "discrepancy":
            raise FieldError(field, f"expected a number >= 0 or 'discrepancy', got {lam!r}")
        return lam
    return float_param(lam, field, 0.0)


def weighted_system(A: np.ndarray, y: np.ndarray, sigma: Any = None, equalities: np.ndarray | None = None,
                    weight: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(W A; w_c C)``, ``(W y; 0)``: the rows weighted by ``1/σ`` (``sigma`` scalar or ``(T,)``;
    ``None``: 1) and the constraints ``C (k, K)`` appended with ``w_c = weight ‖WA‖₂ / √K`` when
    ``weight > 0``."""
    T = len(y)
    w = np.ones(T) if sigma is None else 1.0 / np.broadcast_to(np.asarray(sigma, dtype=np.float64), (T,))
    if not np.isfinite(w).all() or (w <= 0).any():
        raise FieldError("sigma", "the uncertainties must be finite and > 0")
    Aw, b = A * w[:, None], y * w
    if weight > 0 and equalities is not None:
        C = np.asarray(equalities, dtype=np.float64)
        scale = weight * np.linalg.norm(Aw, 2) / math.sqrt(max(C.shape[1], 1))
        Aw = np.vstack([Aw, scale * C])
        b = np.concatenate([b, np.zeros(len(C))])
    return Aw, b


def nonneg_solve(A: np.ndarray, b: np.ndarray, n_data: int, *, method: str = "nnls", weighted: bool = False,
                 n_nonzero: int | None = None, lam: float | str = 1e-3, max_iter: int = 5000,
                 differences: Any = None) -> tuple[np.ndarray, dict[str, Any]]:
    """``x (K,) ≥ 0`` for the system ``A (R, K)``, ``b (R,)`` of :func:`weighted_system` whose first
    ``n_data`` rows are the data (``weighted``: they are whitened, so ``χ² ≤ n_data`` is the noise
    level) and the rest exact constraints; ``differences (E, K)`` the ``tv`` method's edges.
    Returns ``(x, info)`` with ``chi2`` (over the data rows), ``n_nonzero``, ``method`` and the
    method's own counts."""
    from scipy.optimize import nnls  # heavy: scipy.optimize, only for nonneg_solve()

    method = choice_param(method, "method", METHODS)
    T = int(n_data)
    if method == "nnls":
        x, _ = nnls(A, b, maxiter=max(50 * A.shape[1], 1000))
        info: dict[str, Any] = {}
    elif method == "nnomp":
        x, info = _nnomp(A, b, T, n_nonzero, weighted)
    else:
        max_iter = int_param(max_iter, "max_iter", 1)
        lam = lam_param(lam)
        if lam == "discrepancy" and not weighted:
            raise FieldError("lam", "'discrepancy' needs the noise: give sigma")
        if method == "l1":
            solve = lambda lam_: _nnl1(A, b, lam_, max_iter)  # noqa: E731
            x, info = _by_discrepancy(solve, A, b, T) if lam == "discrepancy" else solve(lam)
        else:
            if differences is None:
                raise FieldError("differences", "the TV needs its edges (a graph's differences)")
            if differences.shape[1] != A.shape[1]:
                raise FieldError("differences", f"{differences.shape[1]} columns for {A.shape[1]} unknowns")
            x, info = _nntv(A, b, T, differences, lam, max_iter)
    info.update(fit_summary(A, b, T, x), method=method)
    return x, info


def fit_summary(A: np.ndarray, b: np.ndarray, n_data: int, x: np.ndarray) -> dict[str, Any]:
    """``chi2`` — the square norm of the residual on the first ``n_data`` rows of the system
    (:func:`weighted_system`'s data rows, without its constraints) — and ``n_nonzero``, the
    entries of ``x`` above ``1e-12 × max x``."""
    r = A[:n_data] @ x - b[:n_data]
    return {"chi2": float(r @ r), "n_nonzero": int((x > 1e-12 * max(float(x.max()), 1e-300)).sum())}


def _by_discrepancy(solve: Any, A: np.ndarray, b: np.ndarray, T: int) -> tuple[np.ndarray, dict]:
    """The largest relative λ in [1e-9, 1] whose solve has ``χ² ≤ T`` (χ² grows with λ):
    bisection in log₁₀ λ to 0.05 decades, or to χ² within 2 % of ``T``. When even 1e-9
    misfits (a model error, not noise) that solve is returned, ``discrepancy_met`` False."""
    def chi2(x: np.ndarray) -> float:
        return fit_summary(A, b, T, x)["chi2"]

    lo, hi = -9.0, 0.0
    a, info = solve(10.0 ** lo)
    best, n = (a, info, 10.0 ** lo), 1
    met = chi2(a) <= T
    if met:
        a, info = solve(1.0)
        n += 1
        if chi2(a) <= T:
            best, lo = (a, info, 1.0), hi
        while hi - lo > 0.05:
            mid = 0.5 * (lo + hi)
            a, info = solve(10.0 ** mid)
            n += 1
            c = chi2(a)
            if c <= T:
                lo, best = mid, (a, info, 10.0 ** mid)
                if c >= 0.98 * T:
                    break
            else:
                hi = mid
    a, info, lam = best
    info = dict(info, solver_lam=lam, discrepancy_met=met, discrepancy_solves=n)
    return a, info


def _nnomp(A: np.ndarray, b: np.ndarray, T: int, n_nonzero: int | None, weighted: bool) -> tuple[np.ndarray, dict]:
    from scipy.optimize import nnls  # heavy: scipy.optimize, only for _nnomp()

    K = A.shape[1]
    cap = min(K, A.shape[0]) if n_nonzero is None else int_param(n_nonzero, "n_nonzero", 1, K)
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = np.inf
    support: list[int] = []
    a = np.zeros(K)
    r = b.copy()
    target = float(T) if weighted else 0.0  # χ² ≈ T at the noise when the rows are weighted by 1/σ
    while len(support) < cap:
        corr = (A.T @ r) / norms
        corr[support] = -np.inf
        k = int(np.argmax(corr))
        if not corr[k] > 0:
            break
        support.append(k)
        coef, _ = nnls(A[:, support], b, maxiter=max(50 * len(support), 1000))
        a[:] = 0
        a[support] = coef
        r = b - A @ a
        if float(r[:T] @ r[:T]) <= target * (1 + 1e-12) or float(r @ r) <= 1e-24 * float(b @ b):  # fitted to round-off
            break
    return a, {"omp_atoms": len(support)}


def _nnl1(A: np.ndarray, b: np.ndarray, lam: float, max_iter: int) -> tuple[np.ndarray, dict]:
    """FISTA over ``x ≥ 0`` on the one runner, with the exact Lipschitz constant ``‖A‖₂²``."""
    lam = float_param(lam, "lam", 0.0)
    L = float(np.linalg.norm(A, 2) ** 2)
    x, info = fista_l1(torch.as_tensor(A), torch.as_tensor(b), lam=lam, max_iter=max_iter, rtol=1e-10, lipschitz=L,
                       nonneg=True, return_info=True)
    return x.numpy(), {"solver_iterations": info.n_iter, "solver_lam_abs": float(info.lam[0])}


def _nntv(A: np.ndarray, b: np.ndarray, T: int, D: Any, lam: float | str, max_iter: int) -> tuple[np.ndarray, dict]:
    """TV on the graph ``D`` over ``x ≥ 0`` by :func:`~cssat.sparse.tv_admm.tv_admm` (``λ``
    relative to ``‖Aᵀb‖∞``) or, for ``"discrepancy"``, :func:`~cssat.sparse.tv_admm.tv_discrepancy`
    with ``τ = 1`` (``χ² ≤ T`` on the whitened data rows; the constraint rows exact), its walk
    over ``10⁰ … 10⁻⁹`` refined to 2 % of the target."""
    op, bt, graph = MatrixOperator(torch.as_tensor(A)), torch.as_tensor(b), GraphDifferences(D)
    if lam == "discrepancy":
        var = torch.zeros(len(b), dtype=bt.dtype)
        var[:T] = 1.0
        x, info = tv_discrepancy(op, bt, graph, var, nonneg=True, max_iter=max_iter, rtol=TV_RTOL, tau=1.0,
                                 lams=[10.0 ** -k for k in range(10)], bisections=6, close=0.02)
        info = dict(info, discrepancy_met=info["solver_discrepancy_met"])
    else:
        lam = float_param(lam, "lam", 0.0)
        xs, run, alg = tv_admm(op, bt[None], graph, lam=lam, nonneg=True, max_iter=max_iter, rtol=TV_RTOL)
        x, info = xs[0], {"solver_iterations": run.n_iter, "solver_lam_abs": float(alg.lam_abs[0]),
                          "solver_converged": run.converged}
    return x.numpy(), dict(info, tv_edges=int(D.shape[0]))
