"""Sparse non-negative recovery of an EGI from a light curve (issue 24, point 2).

``min ‖W (G a − y)‖²`` over ``a ≥ 0`` with ``W = diag(1/σ_t)`` (the photometric
uncertainties; none: unweighted) and, with ``closure``, three more rows ``w_c Nᵀ a = 0``: a
closed body's EGI has zero vector sum (``Σ a_k n_k = 0``, Minkowski), which its light curve alone
does not impose. Methods:

* ``nnls`` — Lawson–Hanson non-negative least squares (``scipy.optimize.nnls``);
* ``nnomp`` — non-negative orthogonal matching pursuit: the atom most positively correlated with
  the residual joins the support, the support is refitted by NNLS; stops at ``n_nonzero`` atoms
  or when the weighted residual reaches the noise (``χ² ≤ T``, the discrepancy principle);
* ``l1`` — ``min ½‖W(Ga − y)‖² + λ Σ a`` over ``a ≥ 0`` by FISTA (``λ = lam · ‖(WG)ᵀWy‖∞``);
* ``tv`` — ``min ½‖W(Ga − y)‖² + λ Σ_{(i,j)} |a_i − a_j|`` over ``a ≥ 0``: total variation on the
  sphere, over the edges joining each normal to its ``tv_neighbours`` nearest (a curved surface's
  EGI is a smooth density, a panel's a spike: TV keeps both sparse in their differences), by ADMM
  (``λ = lam · ‖(WG)ᵀWy‖∞``).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param

__all__ = ["recover_egi", "refine_egi", "sphere_differences", "grid_differences", "METHODS"]

METHODS = ("nnls", "nnomp", "l1", "tv")


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


def lam_param(lam: Any, field: str = "lam") -> float | str:
    """``lam`` of the ``l1`` and ``tv`` solves: a number ``>= 0`` or ``"discrepancy"``."""
    if isinstance(lam, str):
        if lam != "discrepancy":
            raise FieldError(field, f"expected a number >= 0 or 'discrepancy', got {lam!r}")
        return lam
    return float_param(lam, field, 0.0)


def recover_egi(G: Any, y: Any, *, sigma: Any = None, normals: Any = None, method: str = "nnls",
                closure: float = 0.0, n_nonzero: int | None = None, lam: float | str = 1e-3,
                max_iter: int = 5000, tv_neighbours: int = 6, differences: Any = None) -> tuple[np.ndarray, dict[str, Any]]:
    """The EGI ``a (K,) ≥ 0`` with ``G a ≈ y``: ``G (T, K)`` (an :class:`EGIOperator` — its
    normals are then used for the closure — or a matrix), ``y (T,)`` (the light curve per unit
    irradiance and range), ``sigma`` its 1σ (scalar or ``(T,)``), ``method`` of :data:`METHODS`,
    ``closure`` the weight of ``Σ a_k n_k = 0`` relative to ``‖WG‖`` (0: none); ``tv``'s edges are
    the normals' ``tv_neighbours`` nearest unless ``differences (E, K)`` (sparse; e.g.
    :func:`grid_differences` for an image) gives them. ``l1``'s and ``tv``'s ``lam`` is relative
    to ``‖(WG)ᵀWy‖∞``, or ``"discrepancy"``: the largest λ whose fit reaches the noise, ``χ² ≤ T``
    (Morozov's principle; bisection in log λ over [1e-9, 1], ~8 solves; needs ``sigma``).
    Returns ``(a,
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
    if not np.isfinite(y).all():
        raise FieldError("y", f"the light curve must be finite: {int((~np.isfinite(y)).sum())} NaN/inf samples (drop them first)")
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
        max_iter = int_param(max_iter, "max_iter", 1)
        if method == "l1":
            solve = lambda lam_: _nnl1(A, b, lam_, max_iter)  # noqa: E731
        else:
            if differences is None and normals is None:
                raise FieldError("normals", "the TV needs its edges: the normals (an EGIOperator or normals=) or differences=")
            D = differences if differences is not None else sphere_differences(normals, int_param(tv_neighbours, "tv_neighbours", 1, 32))
            if D.shape[1] != G.shape[1]:
                raise FieldError("differences", f"{D.shape[1]} columns for {G.shape[1]} unknowns")
            solve = lambda lam_: _nntv(A, b, D, lam_, max_iter)  # noqa: E731
        if lam_param(lam) == "discrepancy":
            if sigma is None:
                raise FieldError("lam", "'discrepancy' needs the noise: give sigma")
            a, info = _by_discrepancy(solve, A, b, T)
        else:
            a, info = solve(lam)
    r = (A[:T] @ a - b[:T])
    info.update(chi2=float(r @ r), n_nonzero=int((a > 1e-12 * max(float(a.max()), 1e-300)).sum()), method=method, closure_norm=float(
        np.linalg.norm(normals.T @ a)) if normals is not None else None)
    return a, info


def _by_discrepancy(solve: Any, A: np.ndarray, b: np.ndarray, T: int) -> tuple[np.ndarray, dict]:
    """The largest relative λ in [1e-9, 1] whose solve has ``χ² ≤ T`` (χ² grows with λ):
    bisection in log₁₀ λ to 0.05 decades, or to χ² within 2 % of ``T``. When even 1e-9
    misfits (a model error, not noise) that solve is returned, ``discrepancy_met`` False."""
    def chi2(x: np.ndarray) -> float:
        r = A[:T] @ x - b[:T]
        return float(r @ r)

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


def sphere_differences(normals: Any, k: int = 6) -> Any:
    """``D (E, K)`` sparse: one row ``e_i − e_j`` per edge joining each of the ``normals (K, 3)`` to
    its ``k`` nearest (by angle; each edge once) — the gradient of a function on the sphere's grid."""
    import scipy.sparse as sp
    from scipy.spatial import cKDTree

    N = np.asarray(normals, dtype=np.float64)
    k = min(int(k), len(N) - 1)
    if k < 1:
        return sp.csr_matrix((0, len(N)))
    _, nb = cKDTree(N).query(N, k=k + 1)
    i = np.repeat(np.arange(len(N)), k)
    j = nb[:, 1:].reshape(-1)
    edges = np.unique(np.sort(np.stack([i, j], 1), axis=1), axis=0)
    E = len(edges)
    rows = np.repeat(np.arange(E), 2)
    return sp.csr_matrix((np.tile([1.0, -1.0], E), (rows, edges.reshape(-1))), shape=(E, len(N)))


def grid_differences(shape: Sequence[int]) -> Any:
    """``D (E, prod(shape))`` sparse: the forward differences along each axis of a grid of
    ``shape`` (row-major, as ``x.reshape(-1)``), one row ``e_{i+1} − e_i`` per adjacent pair — the
    anisotropic TV's gradient of an image."""
    import scipy.sparse as sp

    shape = tuple(int(s) for s in shape)
    blocks = []
    for ax, n in enumerate(shape):
        d = sp.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))
        mats = [sp.identity(m) for m in shape]
        mats[ax] = d
        out = mats[0]
        for m in mats[1:]:
            out = sp.kron(out, m)
        blocks.append(out)
    return sp.vstack(blocks).tocsr()


def _nntv(A: np.ndarray, b: np.ndarray, D: Any, lam: float, max_iter: int, tol: float = 1e-7) -> tuple[np.ndarray, dict]:
    """``min ½‖Aa − b‖² + λ‖Da‖₁`` over ``a ≥ 0`` by ADMM (Boyd et al. 2011, §6): the splitting
    ``Da = z``, ``a = u ≥ 0``; the ``a`` step is one Cholesky solve with ``AᵀA + ρ(DᵀD + I)``
    (factored once per ρ), ``z`` a soft threshold, ``u`` a clip; ρ starts at ``10⁻³‖A‖²`` and is
    balanced between the primal and dual residuals every 50 steps (×2 or ÷2 when one is 10×
    the other); stops when both are under ``tol`` relative (Boyd's §3.3 criterion)."""
    import scipy.linalg as sla

    lam = float_param(lam, "lam", 0.0)
    K = A.shape[1]
    AtA, Atb = A.T @ A, A.T @ b
    lam_abs = lam * float(np.abs(Atb).max())
    DtD = (D.T @ D).toarray() if D.shape[0] else np.zeros((K, K))
    rho = 1e-3 * max(float(np.linalg.eigvalsh(AtA)[-1]), 1e-300)
    chol = sla.cho_factor(AtA + rho * (DtD + np.eye(K)))
    z, p = np.zeros(D.shape[0]), np.zeros(D.shape[0])
    u, q = np.zeros(K), np.zeros(K)
    it, n_rho = 0, 1
    for it in range(1, max_iter + 1):
        a = sla.cho_solve(chol, Atb + rho * (D.T @ (z - p) + u - q))
        Da = D @ a
        z_old, u_old = z, u
        v = Da + p
        z = np.sign(v) * np.maximum(np.abs(v) - lam_abs / rho, 0.0)
        u = np.maximum(a + q, 0.0)
        p, q = p + Da - z, q + a - u
        r = np.sqrt(np.sum((Da - z) ** 2) + np.sum((a - u) ** 2))
        s_ = rho * np.sqrt(np.sum((D.T @ (z - z_old)) ** 2) + np.sum((u - u_old) ** 2))
        scale_p = max(np.sqrt(np.sum(Da ** 2) + np.sum(a ** 2)), np.sqrt(np.sum(z ** 2) + np.sum(u ** 2)), 1e-300)
        scale_d = max(rho * np.sqrt(np.sum((D.T @ p) ** 2) + np.sum(q ** 2)), 1e-300)
        if r <= tol * scale_p and s_ <= tol * scale_d:
            break
        if it % 50 == 0 and (r > 10 * s_ * scale_p / scale_d or s_ > 10 * r * scale_d / scale_p):
            f = 2.0 if r / scale_p > s_ / scale_d else 0.5
            rho *= f
            p, q = p / f, q / f  # the scaled duals follow ρ
            chol = sla.cho_factor(AtA + rho * (DtD + np.eye(K)))
            n_rho += 1
    return u, {"solver_iterations": it, "solver_lam_abs": lam_abs, "tv_edges": int(D.shape[0]), "solver_rho_changes": n_rho - 1}


def _merge_atoms(N: np.ndarray, a: np.ndarray, merge_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Greedy clusters of the atoms within ``merge_deg`` of the heaviest unassigned one: one atom
    each, at the area-weighted mean normal with the summed area."""
    order = np.argsort(-a)
    free = np.ones(len(a), bool)
    cos = np.cos(np.radians(merge_deg))
    out_n, out_a = [], []
    for i in order:
        if not free[i]:
            continue
        group = free & (N @ N[i] >= cos)
        free &= ~group
        m = (a[group, None] * N[group]).sum(0)
        out_n.append(m / max(np.linalg.norm(m), 1e-300))
        out_a.append(a[group].sum())
    return np.array(out_n), np.array(out_a)


def refine_egi(sun_body: Any, obs_body: Any, y: Any, normals: Any, areas: Any, *, sigma: Any = None, brdf: Any = None,
               closure: float = 0.0, merge_deg: float | None = None, max_nfev: int = 200,
               ridge: float = 1e-6) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Off the grid: the EGI's atoms moved on the sphere and re-weighted to fit the light curve.

    A grid of normals splits a facet whose normal falls between grid points over its neighbours
    (the grid's floor: a 1,000-point grid is ~6° apart). Here the atoms within ``merge_deg``
    (default: 1.5 × the spacing of a Fibonacci grid of ``len(normals_grid)`` — pass it) are
    merged, then every atom's direction and area are fitted by bounded least squares (scipy's
    ``least_squares``, trust-region reflective, ``a ≥ 0``): ``min ‖W (Σ_k a_k G(n_k) − y)‖²``
    (plus the closure rows ``w_c Σ a_k n_k`` when ``closure > 0``), the Jacobian analytic for a
    Lambert BRDF (``∂G/∂n = f ((o·n) s + (s·n) o)`` where both are positive), by differences
    otherwise. The merged start is kept only if the refined fit is not worse than the unmerged
    atoms refined alike; atoms that end within 0.5° of each other are merged last (their areas
    refitted by NNLS). ``ridge``: a penalty ``μ Σ a_k²`` with ``μ = ridge × the median
    ‖W G_k‖²`` of the starting atoms — an atom the geometry barely sees (lit while seen only at
    grazing angles) would otherwise take any area the closure asks for (hundreds of m² in one
    seed of the default experiment); a well-seen atom's data curvature is ~1/ridge times the
    penalty's, so it barely moves. Returns ``(normals (J, 3), areas (J,), info)`` with ``chi2``
    (weighted, without the closure rows), ``atoms_merged`` and ``nfev``."""
    from scipy.optimize import least_squares

    from cssat.inversion.egi import egi_operator, geometry_matrix, lambert_scale

    S, O = np.asarray(sun_body, dtype=np.float64), np.asarray(obs_body, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64).reshape(-1)
    N0, a0 = np.asarray(normals, dtype=np.float64), np.asarray(areas, dtype=np.float64)
    T = len(y)
    w = np.ones(T) if sigma is None else 1.0 / np.broadcast_to(np.asarray(sigma, dtype=np.float64), (T,))
    if N0.ndim != 2 or N0.shape[1] != 3 or a0.shape != (len(N0),) or S.shape != (T, 3) or O.shape != (T, 3):
        raise FieldError("normals", f"expected normals (J, 3), areas (J,), sun/obs (T, 3), y (T,): got {N0.shape}, "
                                    f"{a0.shape}, {S.shape}, {O.shape}, {y.shape}")
    lam = lambert_scale(brdf)
    G0 = egi_operator(S, O, N0, brdf).matrix().numpy() * w[:, None]
    wc = closure * np.linalg.norm(G0, 2) / np.sqrt(max(len(N0), 1)) if closure > 0 else 0.0
    sr = float(np.sqrt(float_param(ridge, "ridge", 0.0) * np.median((G0 ** 2).sum(0)))) if len(N0) else 0.0

    def fit(N_start, a_start):
        J = len(a_start)
        # tangent frames of the starting normals: n(u, v) = (n0 + u e1 + v e2)/|·|
        ref = np.where(np.abs(N_start[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
        e1 = np.cross(N_start, ref)
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = np.cross(N_start, e1)

        def unpack(x):
            u, v, a = x[:J], x[J:2 * J], x[2 * J:]
            m = N_start + u[:, None] * e1 + v[:, None] * e2
            r = np.linalg.norm(m, axis=1, keepdims=True)
            return m / r, r, a

        def resid(x):
            N, _, a = unpack(x)
            out = [w * (geometry_matrix(S, O, N, brdf) @ a - y)]
            if wc > 0:
                out.append(wc * (a @ N))
            if sr > 0:
                out.append(sr * a)
            return np.concatenate(out)

        def jac(x):
            N, r, a = unpack(x)
            sn, on = S @ N.T, O @ N.T
            act = (sn > 0) & (on > 0)
            G = lam * np.where(act, sn * on, 0.0)
            # dG/dn (T, J, 3), projected through dn/du = (e − n (n·e))/r
            dGdn = lam * act[..., None] * (on[..., None] * S[:, None, :] + sn[..., None] * O[:, None, :])
            cols = []
            for e in (e1, e2):
                dn = (e - N * np.einsum("jk,jk->j", N, e)[:, None]) / r
                cols.append(w[:, None] * a[None, :] * np.einsum("tjk,jk->tj", dGdn, dn))
            Jm = np.hstack(cols + [w[:, None] * G])
            if wc > 0:
                ccols = []
                for e in (e1, e2):
                    dn = (e - N * np.einsum("jk,jk->j", N, e)[:, None]) / r
                    ccols.append(wc * (a[:, None] * dn).T)  # (3, J)
                Jm = np.vstack([Jm, np.hstack(ccols + [wc * N.T])])
            if sr > 0:
                Jm = np.vstack([Jm, np.hstack([np.zeros((J, 2 * J)), sr * np.eye(J)])])
            return Jm

        x0 = np.concatenate([np.zeros(2 * J), a_start])
        lo = np.concatenate([np.full(2 * J, -np.inf), np.zeros(J)])
        res = least_squares(resid, x0, jac=jac if lam is not None else "2-point", bounds=(lo, np.inf), method="trf",
                            x_scale="jac", max_nfev=max_nfev)
        N, _, a = unpack(res.x)
        r = res.fun[:T]
        return N, a, float(r @ r), int(res.nfev)

    if merge_deg is None:
        merge_deg = 0.0
    candidates = [fit(N0, a0)]
    merged = 0
    if merge_deg > 0:
        Nm, am = _merge_atoms(N0, a0, merge_deg)
        if len(am) < len(a0):
            cand = fit(Nm, am)
            if cand[2] <= candidates[0][2] * (1 + 1e-6):
                candidates = [cand]
                merged = len(a0) - len(am)
    N, a, chi2, nfev = candidates[0]
    keep = a > 1e-9 * max(float(a.max()), 1e-300)
    N, a = N[keep], a[keep]
    # atoms that converged onto one facet (within 0.5°) become one: their areas refitted by NNLS
    Nm, am = _merge_atoms(N, a, 0.5)
    if len(am) < len(a):
        from scipy.optimize import nnls

        Gm = egi_operator(S, O, Nm, brdf).matrix().numpy() * w[:, None]
        am, _ = nnls(np.vstack([Gm, sr * np.eye(len(am))]), np.concatenate([w * y, np.zeros(len(am))]),
                     maxiter=max(50 * len(am), 1000))
        r = Gm @ am - w * y
        merged += len(a) - len(am)
        N, a, chi2 = Nm[am > 0], am[am > 0], float(r @ r)
    return N, a, {"chi2": chi2, "atoms_merged": merged, "nfev": nfev}
