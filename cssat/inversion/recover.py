"""Sparse non-negative recovery of an EGI from a light curve (issue 24, point 2).

``min ‖W (G a − y)‖²`` over ``a ≥ 0`` with ``W = diag(1/σ_t)`` (the photometric
uncertainties; none: unweighted) and, with ``closure``, three more rows ``w_c Nᵀ a = 0``: a
closed body's EGI has zero vector sum (``Σ a_k n_k = 0``, Minkowski), which its light curve alone
does not impose. Methods:

* ``nnls`` — Lawson–Hanson non-negative least squares (``scipy.optimize.nnls``);
* ``nnomp`` — non-negative orthogonal matching pursuit: the atom most positively correlated with
  the residual joins the support, the support is refitted by NNLS; stops at ``n_nonzero`` atoms
  or when the weighted residual reaches the noise (``χ² ≤ T``, the discrepancy principle);
* ``l1`` — ``min ½‖W(Ga − y)‖² + λ Σ a`` over ``a ≥ 0`` by FISTA (``λ = lam · ‖(WG)ᵀWy‖∞``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param

__all__ = ["recover_egi", "METHODS"]

METHODS = ("nnls", "nnomp", "l1")


def _system(G: np.ndarray, y: np.ndarray, sigma: Any, normals: np.ndarray | None, closure: float) -> tuple[np.ndarray, np.ndarray]:
    T = len(y)
    w = np.ones(T) if sigma is None else 1.0 / np.broadcast_to(np.asarray(sigma, dtype=np.float64), (T,))
    if not np.isfinite(w).all() or (w <= 0).any():
        raise FieldError("sigma", "the uncertainties must be finite and > 0")
    A, b = G * w[:, None], y * w
    if closure > 0:
        if normals is None:
            raise FieldError("closure", "the closure constraint needs the normals")
        scale = closure * np.linalg.norm(A, 2) / math.sqrt(max(len(normals), 1))
        A = np.vstack([A, scale * np.asarray(normals, dtype=np.float64).T])
        b = np.concatenate([b, np.zeros(3)])
    return A, b


def recover_egi(G: Any, y: Any, *, sigma: Any = None, normals: Any = None, method: str = "nnls",
                closure: float = 0.0, n_nonzero: int | None = None, lam: float = 1e-3,
                max_iter: int = 5000) -> tuple[np.ndarray, dict[str, Any]]:
    """The EGI ``a (K,) ≥ 0`` with ``G a ≈ y``: ``G (T, K)`` (an :class:`EGIOperator` — its
    normals are then used for the closure — or a matrix), ``y (T,)`` (the light curve per unit
    irradiance and range), ``sigma`` its 1σ (scalar or ``(T,)``), ``method`` of :data:`METHODS`,
    ``closure`` the weight of ``Σ a_k n_k = 0`` relative to ``‖WG‖`` (0: none). Returns ``(a,
    info)`` with ``chi2`` (the weighted residual's square norm, without the closure rows),
    ``n_nonzero`` and the method's own counts."""
    from scipy.optimize import nnls

    from cssat.metrics import _np  # tensors or arrays as float64 arrays

    method = choice_param(method, "method", METHODS)
    closure = float_param(closure, "closure", 0.0)
    if hasattr(G, "matrix"):
        normals = getattr(G, "normals", None) if normals is None else normals
        G = G.matrix()
    G, y = _np(G), _np(y).reshape(-1)
    if G.ndim != 2 or G.shape[0] != len(y):
        raise FieldError("y", f"{len(y)} samples for an operator of shape {G.shape}")
    if normals is not None:
        normals = _np(normals)
    A, b = _system(G, y, sigma, normals, closure)
    T = len(y)
    if method == "nnls":
        a, _ = nnls(A, b, maxiter=max(50 * A.shape[1], 1000))
        info: dict[str, Any] = {}
    elif method == "nnomp":
        a, info = _nnomp(A, b, T, n_nonzero, sigma is not None)
    else:
        a, info = _nnl1(A, b, lam, int_param(max_iter, "max_iter", 1))
    r = (A[:T] @ a - b[:T])
    info.update(chi2=float(r @ r), n_nonzero=int((a > 1e-12 * max(float(a.max()), 1e-300)).sum()), method=method, closure_norm=float(
        np.linalg.norm(normals.T @ a)) if normals is not None else None)
    return a, info


def _nnomp(A: np.ndarray, b: np.ndarray, T: int, n_nonzero: int | None, weighted: bool) -> tuple[np.ndarray, dict]:
    from scipy.optimize import nnls

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
    lam = float_param(lam, "lam", 0.0)
    L = np.linalg.norm(A, 2) ** 2
    lam_abs = lam * float(np.abs(A.T @ b).max())
    x = z = np.zeros(A.shape[1])
    t = 1.0
    it = 0
    for it in range(1, max_iter + 1):
        g = A.T @ (A @ z - b)
        x_new = np.maximum(z - (g + lam_abs) / L, 0.0)
        t_new = (1 + math.sqrt(1 + 4 * t * t)) / 2
        z = x_new + (t - 1) / t_new * (x_new - x)
        change = np.linalg.norm(x_new - x) / max(np.linalg.norm(x_new), 1e-300)
        x, t = x_new, t_new
        if change < 1e-10:
            break
    return x, {"solver_iterations": it, "solver_lam_abs": lam_abs}
