"""Sparse non-negative recovery of an EGI from a light curve.

``min ‖W (G a − y)‖²`` over ``a ≥ 0`` with ``W = diag(1/σ_t)`` (the photometric
uncertainties; none: unweighted) and, with ``closure``, three more rows ``w_c Nᵀ a = 0``: a
closed body's EGI has zero vector sum (``Σ a_k n_k = 0``, Minkowski), which its light curve alone
does not impose. The solves are :mod:`cssat.sparse.nonneg`'s (``nnls``, ``nnomp``, ``l1`` by
FISTA, ``tv`` by the one ADMM over the graph joining each normal to its ``tv_neighbours``
nearest: a curved surface's EGI is a smooth density, a panel's a spike, and TV keeps both sparse
in their differences); this module gives them the EGI's closure and its sphere, and refines the
atoms off the grid (:func:`refine_egi`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.inversion.egi import egi_operator, geometry_matrix, lambert_scale
from cssat.metrics import float64_array  # tensors or arrays as float64 arrays
from cssat.sparse.differences import grid_differences, knn_differences
from cssat.sparse.nonneg import METHODS, lam_param, nonneg_solve, weighted_system

__all__ = ["recover_egi", "refine_egi", "sphere_differences", "grid_differences", "METHODS", "lam_param"]


def sphere_differences(normals: Any, k: int = 6) -> Any:
    """``D (E, K)`` sparse: one row ``e_i − e_j`` per edge joining each of the ``normals (K, 3)`` to
    its ``k`` nearest (by angle; each edge once) — the gradient of a function on the sphere's grid."""
    return knn_differences(normals, k)


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
    (Morozov's principle; needs ``sigma``). Returns ``(a, info)`` with ``chi2`` (the weighted
    residual's square norm, without the closure rows), ``n_nonzero``, ``closure_norm`` and the
    method's own counts."""
    method = choice_param(method, "method", METHODS)
    closure = float_param(closure, "closure", 0.0)
    if hasattr(G, "matrix"):
        normals = getattr(G, "normals", None) if normals is None else normals
        G = G.matrix()
    G, y = float64_array(G), float64_array(y).reshape(-1)
    if G.ndim != 2 or G.shape[0] != len(y):
        raise FieldError("y", f"{len(y)} samples for an operator of shape {G.shape}")
    if not np.isfinite(y).all():
        raise FieldError("y", f"the light curve must be finite: {int((~np.isfinite(y)).sum())} NaN/inf samples (drop them first)")
    if normals is not None:
        normals = float64_array(normals)
    if closure > 0 and normals is None:
        raise FieldError("closure", "the closure constraint needs the normals")
    A, b = weighted_system(G, y, sigma, None if normals is None else normals.T, closure)
    if method == "tv" and differences is None:
        if normals is None:
            raise FieldError("normals", "the TV needs its edges: the normals (an EGIOperator or normals=) or differences=")
        differences = sphere_differences(normals, int_param(tv_neighbours, "tv_neighbours", 1, 32))
    a, info = nonneg_solve(A, b, len(y), method=method, weighted=sigma is not None, n_nonzero=n_nonzero, lam=lam,
                           max_iter=max_iter, differences=differences)
    info["closure_norm"] = float(np.linalg.norm(normals.T @ a)) if normals is not None else None
    return a, info


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
    from scipy.optimize import least_squares  # heavy: scipy.optimize, only for refine_egi()

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
        from scipy.optimize import nnls  # heavy: scipy.optimize, only for refine_egi()

        Gm = egi_operator(S, O, Nm, brdf).matrix().numpy() * w[:, None]
        am, _ = nnls(np.vstack([Gm, sr * np.eye(len(am))]), np.concatenate([w * y, np.zeros(len(am))]),
                     maxiter=max(50 * len(am), 1000))
        r = Gm @ am - w * y
        merged += len(a) - len(am)
        N, a, chi2 = Nm[am > 0], am[am > 0], float(r @ r)
    return N, a, {"chi2": chi2, "atoms_merged": merged, "nfev": nfev}
