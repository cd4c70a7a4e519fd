"""The convex shape of an EGI (the Minkowski problem).

A convex polyhedron is determined, up to translation, by its facets' normals ``n_k`` and areas
``a_k`` (Minkowski 1897) when ``Σ a_k n_k = 0``. Little's (1983) convex program finds it: over
the support heights ``h`` of ``P(h) = {x : n_k·x ≤ h_k}``, maximise ``log V(h)`` on the plane
``Σ a_k h_k = 1``; ``∂V/∂h_k`` is the area of facet ``k``, so at the optimum the facet areas are
proportional to ``a`` (the Lagrange condition). Solved here by projected gradient ascent with
backtracking (``V`` and the facet areas by qhull's halfspace intersection), the polytope kept
centred on its centroid; the result is scaled so that its surface is ``Σ a_k``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError

__all__ = ["minkowski", "polytope", "invert_convex", "ConvexInversion", "convex_iou"]


def polytope(normals: np.ndarray, heights: np.ndarray, *, edges: bool = False) -> tuple:
    """``P(h) = {x : n_k·x ≤ h_k}`` (the origin inside): ``(vertices (V, 3), triangles (F, 3),
    volume, facet areas (K,))`` — facet ``k``'s area is 0 when its plane does not touch ``P``;
    with ``edges`` also ``(i, j, length)``: each ordered pair of adjacent facets and the length
    of their common edge (the mixed-volume Hessian's entries, :func:`_volume_hessian`)."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection  # heavy: scipy.spatial, only for polytope()

    hs = np.hstack([normals, -heights[:, None]])
    pts = HalfspaceIntersection(hs, np.zeros(3)).intersections
    hull = ConvexHull(pts)
    S = hull.simplices
    tri = pts[S]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    cross *= np.sign(np.einsum("ij,ij->i", cross, tri.mean(1)))[:, None]  # qhull's triangles are unoriented: outward
    tri_area = 0.5 * np.linalg.norm(cross, axis=1)
    # each hull triangle lies on the plane of the constraint its normal matches best
    owner = np.argmax((cross / np.maximum(2 * tri_area[:, None], 1e-300)) @ normals.T, axis=1)
    areas = np.bincount(owner, weights=tri_area, minlength=len(normals))
    if not edges:
        return pts, S, float(hull.volume), areas
    # triangle s's edge opposite its vertex k borders triangle neighbors[s, k]: a facets' edge
    # where the owners differ (each ordered pair once, from its own side)
    s_i = np.repeat(np.arange(len(S)), 3)
    k_i = np.tile(np.arange(3), len(S))
    i, j = owner[s_i], owner[hull.neighbors.reshape(-1)]
    length = np.linalg.norm(pts[S[s_i, (k_i + 1) % 3]] - pts[S[s_i, (k_i + 2) % 3]], axis=1)
    d = i != j
    return pts, S, float(hull.volume), areas, (i[d], j[d], length[d])


def _volume_hessian(normals: np.ndarray, edges: tuple, K: int) -> Any:
    """``∂²V/∂h_i∂h_j = ∂A_i/∂h_j`` (sparse ``(K, K)``): ``ℓ_ij / sin θ_ij`` for adjacent facets,
    ``−Σ_j ℓ_ij cot θ_ij`` on the diagonal (so that ``H N = 0``: a translation changes no area)."""
    import scipy.sparse as sp  # heavy: scipy.sparse, only for _volume_hessian()

    i, j, length = edges
    c = np.einsum("ij,ij->i", normals[i], normals[j]).clip(-1.0, 1.0)
    sn = np.sqrt(1.0 - c * c).clip(1e-12)
    rows = np.concatenate([i, i])
    cols = np.concatenate([j, i])
    return sp.csc_matrix((np.concatenate([length / sn, -length * c / sn]), (rows, cols)), shape=(K, K))


def _centroid(pts: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    tri = pts[simplices]
    vol = np.abs(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))) / 6.0  # the origin is inside: cones from it
    return (vol[:, None] * tri.sum(1) / 4.0).sum(0) / vol.sum()


def _encloses(N: np.ndarray) -> bool:
    """Whether the origin is strictly inside the normals' convex hull (they are in no closed
    hemisphere, so their halfspaces bound a body)."""
    from scipy.spatial import ConvexHull  # heavy: scipy.spatial, only for _encloses()

    try:
        hull = ConvexHull(N)
    except Exception:  # coplanar normals: a hemisphere's edge
        return False
    return bool((hull.equations[:, 3] < -1e-9).all())


def minkowski(normals: Any, areas: Any, *, max_iter: int = 200, tol: float = 1e-9) -> tuple[Any, dict[str, Any]]:
    """The convex polyhedron whose facets have ``normals (K, 3)`` and ``areas (K,) ≥ 0`` (zero
    areas are dropped), as a ``trimesh.Trimesh`` centred on its centroid, and ``info``
    (``iterations``, ``area_error``: the largest |facet area − a_k| over Σa, ``closure``: |Σ a n|
    over Σa, ``converged``). The EGI is closed first (the least change to ``Σ a n = 0``: a measured
    one is not quite closed, and no body has it then); the heights are found by Newton's method
    on the convex form of Little's program, ``min w·h − ⅓ log V(h)`` (Lachand-Robert & Oudet 2005
    solve the same program by gradients; the exact Hessian, sparse over the facets' adjacency,
    converges in ~10 steps: 0.03–0.05 s for 40–90 facets, 0.4 s for 600, 13 s for 6,000), until every facet's
    share of the surface is within ``tol`` of ``a_k/Σa``. The normals with area must not all lie
    in a closed hemisphere."""
    import trimesh  # heavy: trimesh, only for minkowski()

    N = np.asarray(normals, dtype=np.float64)
    a = np.asarray(areas, dtype=np.float64)
    if N.ndim != 2 or N.shape[1] != 3 or a.shape != (len(N),) or not np.isfinite(N).all() or not np.isfinite(a).all():
        raise FieldError("areas", f"expected normals (K, 3) and areas (K,), got {N.shape} and {a.shape}")
    if (a < 0).any():
        raise FieldError("areas", "areas must be >= 0")
    keep = a > 1e-12 * a.max() if a.size and a.max() > 0 else np.zeros(len(a), bool)
    if keep.sum() < 4:
        raise FieldError("areas", f"a closed convex body needs at least 4 facets with area, got {int(keep.sum())}")
    N = N[keep] / np.linalg.norm(N[keep], axis=1, keepdims=True)
    a = a[keep]
    # one facet per direction: normals within 1e-6 rad are one plane (their areas add up)
    uniq, inv = np.unique(np.round(N, 6), axis=0, return_inverse=True)
    if len(uniq) < len(N):
        inv = inv.reshape(-1)
        a_sum = np.bincount(inv, weights=a)
        N = np.stack([np.bincount(inv, weights=a * N[:, i]) for i in range(3)], 1)
        N /= np.linalg.norm(N, axis=1, keepdims=True)
        a = a_sum
    if not _encloses(N):
        raise FieldError("normals", "the normals with area lie in a closed hemisphere: they enclose no body")
    total = a.sum()
    closure = float(np.linalg.norm(a @ N) / total)
    w = a / total
    # a body's EGI is closed (Σ w n = 0); one measured is not quite, and Little's program has no
    # maximum then (a translation changes Σ w h but not V): close it first, by alternating
    # projections onto Σ w n = 0 and w ≥ 0 (the change is of the order of `closure`)
    P = np.linalg.pinv(N.T)
    for _ in range(200):
        if np.linalg.norm(w @ N) <= 1e-13:
            break
        w = np.clip(w - P @ (N.T @ w), 0.0, None)
    w /= w.sum()
    live = w > 1e-14  # closing can empty a facet: no plane of the body then
    N, w = N[live], w[live]
    # Newton on the convex form of Little's program: F(h) = w·h − ⅓ log V(h) (V^⅓ is concave by
    # Brunn–Minkowski), whose minimum has A(h) = 3V w; ∇F = w − A/3V, ∇²F = (AAᵀ/V² − H/V)/3 with
    # H the mixed-volume Hessian (sparse: facet adjacency), translations (H N = 0) pinned. Damped
    # as Kitagawa, Mérigot & Thibert's Newton for semi-discrete optimal transport (JEMS 2019), the
    # same structure: a step is halved until every facet keeps a share ≥ ε₀ of the surface (so the
    # Hessian stays non-singular) and |∇F| falls by (1 − t/2). Starts at h = 1, where every plane
    # touches (each is tangent to the unit sphere at its own normal).
    import scipy.sparse as sp  # heavy: scipy.sparse, only for minkowski()
    import scipy.sparse.linalg as spla  # heavy: scipy.sparse, only for minkowski()

    K = len(N)
    h = np.ones(K)
    try:
        pts, simp, V, A, E = polytope(N, h, edges=True)
    except Exception as err:  # qhull: an unbounded intersection
        raise FieldError("normals", f"these normals do not enclose a body (they lie in a hemisphere?): {err}") from None
    Q, _ = np.linalg.qr(N)  # the translations h → h + N c
    eps0 = 0.5 * min(float(w.min()), float((A / A.sum()).min()))
    it, converged = 0, False

    def grad(A_: np.ndarray, V_: float) -> np.ndarray:
        g_ = w - A_ / (3.0 * V_)
        return g_ - Q @ (Q.T @ g_)

    g = grad(A, V)
    for it in range(1, max_iter + 1):
        if np.abs(A / A.sum() - w).max() < tol:  # the facets' areas ∝ a: the Lagrange condition
            converged = True
            break
        Hs = -_volume_hessian(N, E, K) / (3.0 * V)
        # the Hessian's scale: its mean diagonal, or a share of its largest entry where the
        # facets meet at right angles (a box: cos θ = 0 zeroes the diagonal, and a shift of
        # 1e-12 × 0 left the translations' null space exactly singular)
        scale = max(float(np.abs(Hs.diagonal()).mean()), 1e-3 * float(np.abs(Hs.data).max(initial=0.0)), 1e-300)
        U = np.column_stack([A / (V * np.sqrt(3.0)), np.sqrt(scale) * Q])  # the rank-one term and the pin
        lu = spla.splu((Hs + 1e-12 * scale * sp.identity(K, format="csc")).tocsc())
        Sg, SU = lu.solve(g), lu.solve(U)  # Woodbury: (S + U Uᵀ)⁻¹ g
        dh = -(Sg - SU @ np.linalg.solve(np.eye(U.shape[1]) + U.T @ SU, U.T @ Sg))
        gn, t, step = float(np.linalg.norm(g)), 1.0, None
        while t > 1e-12:
            hn = h + t * dh
            try:
                out = polytope(N, hn, edges=True)
            except Exception:  # qhull on a degenerate step: a shorter one
                out = None
            if out is not None and out[2] > 0:
                gnew = grad(out[3], out[2])
                if (out[3] / out[3].sum()).min() >= eps0 and np.linalg.norm(gnew) <= (1 - t / 2) * gn:
                    step = (hn, out, gnew)
                    break
            t *= 0.5
        if step is None:  # no step decreases |∇F|: the program's round-off floor
            break
        h, (pts, simp, V, A, E), g = step
        c = pts.mean(0)  # re-centred: the origin stays inside
        h, pts = h - N @ c, pts - c
    scale = np.sqrt(total / A.sum())
    mesh = trimesh.convex.convex_hull((pts - _centroid(pts, simp)) * scale)  # outward, watertight, centred
    err = float(np.abs(np.bincount(np.flatnonzero(live), A * scale ** 2, len(a)) - a).max() / total)  # against the areas given, before closing
    return mesh, {"iterations": it, "area_error": err, "closure": closure, "converged": converged}


class ConvexInversion:
    """What :func:`invert_convex` returns: the recovered EGI (``normals (K, 3)``, ``areas
    (K,)``, only the non-zero ones), the convex ``mesh`` (``trimesh.Trimesh``, or ``None`` when
    fewer than 4 normals carry area), the light curve's ``residual (T,)`` (flux − fit) and the
    solver's and the Minkowski step's ``info``."""

    def __init__(self, normals: np.ndarray, areas: np.ndarray, mesh: Any, residual: np.ndarray, info: dict,
                 lobe_areas: np.ndarray | None = None, brdf: Any = None):
        self.normals, self.areas, self.mesh, self.residual, self.info = normals, areas, mesh, residual, info
        self.lobe_areas, self.brdf = lobe_areas, brdf

    def predict(self, sun_body: Any, obs_body: Any) -> np.ndarray:
        """The fitted light curve ``(T,)`` (the flux's units) for body-frame ``sun_body``,
        ``obs_body (T, 3)``: e.g. a night held out of the fit."""
        from cssat.inversion.egi import egi_light_curve  # heavy: cssat.inversion.egi imports torch

        return egi_light_curve(sun_body, obs_body, self.normals, self.areas, self.brdf, self.lobe_areas)

    def __repr__(self) -> str:
        return f"ConvexInversion({len(self.areas)} normals, area {self.areas.sum():.4g}, rms residual " \
               f"{float(np.sqrt(np.mean(self.residual ** 2))):.3g})"


def _solve_with(solver: Any, G: Any, y: np.ndarray, sigma: Any, closure: float) -> tuple[np.ndarray, dict[str, Any]]:
    """The EGI by a solver object (``x, info = solver(problem, y)``, e.g. the ``solver`` group's)
    on ``Problem(G, (K,), noise_sigma=sigma)``, its ``closure`` set to this one's when it has one;
    ``info`` as :func:`~cssat.inversion.recover_egi`'s (``chi2`` on the weighted data rows,
    ``n_nonzero``, ``method``: the solver's name, ``closure_norm``) plus the solver's own."""
    import torch  # heavy: torch (~1 s); the module imports without it

    from cssat.sparse.nonneg import fit_summary, weighted_system  # heavy: cssat.sparse.nonneg imports torch
    from cssat.sparse.problem import Problem  # heavy: cssat.sparse.problem imports torch

    if hasattr(solver, "closure"):
        solver.closure = closure
    x, sinfo = solver(Problem(G, (G.n_in,), noise_sigma=sigma), torch.as_tensor(y, dtype=torch.float64))
    a = np.asarray(x.detach().cpu().numpy() if hasattr(x, "detach") else x, dtype=np.float64).reshape(-1)
    A, b = weighted_system(G.matrix().numpy(), y, sigma)
    info = {k: v for k, v in sinfo.items() if k not in ("solver_chi2", "solver_n_nonzero")}
    info.update(fit_summary(A, b, len(y), a), method=getattr(solver, "name", type(solver).__name__),
                closure_norm=float(np.linalg.norm(G.equalities() @ a)))
    return a, info


def invert_convex(flux: Any, sun_body: Any, obs_body: Any, *, brdf: Any = "lambert", n_normals: int = 1000,
                  sigma: Any = None, method: str = "nnls", closure: float = 1.0, refine: bool | None = None,
                  solver: Any = None, **recover_options: Any) -> ConvexInversion:
    """The convex shape of a light curve: ``flux (T,)`` per unit irradiance and range (for
    ``brdf="lambert"``: ``Σ_f A_f (albedo/π) max(0, s·n_f) max(0, o·n_f)``, so the areas come
    back in the flux's units × albedo), ``sun_body``/``obs_body (T, 3)`` body-frame unit vectors;
    the EGI on a ``n_normals`` Fibonacci grid by :func:`~cssat.inversion.recover_egi` (``method``,
    weights ``1/sigma``, ``closure``; ``recover_options``: its ``lam``, ``n_nonzero``,
    ``max_iter``, ``tv_neighbours``) — or by ``solver``, a solver object (``x, info =
    solver(problem, y)``: ``cssat.recon.NNLS()``, ``NNTV(lam="discrepancy")``, … the ``solver``
    config group's) on the EGI operator, instead of ``method`` —, with ``refine`` its atoms moved off the grid
    (:func:`~cssat.inversion.recover.refine_egi`: neighbours within 1.5 grid spacings merged,
    directions and areas fitted by least squares; ``None``: for the sparse methods, not for
    ``tv``, whose EGI is a density on the grid rather than a few facets; not for ``Lobes``), then
    :func:`minkowski`. ``brdf``: a :mod:`cssat.optics.brdf` object or its name (default parameters,
    albedo 1 for Lambert), or ``"lobes"``/a :class:`~cssat.inversion.egi.Lobes` (an EGI per
    scattering lobe; the shape from their sum)."""
    from cssat.inversion.egi import Lobes, egi_operator, fibonacci_sphere, split_lobes  # heavy: imports torch
    from cssat.inversion.recover import recover_egi  # heavy: cssat.inversion.recover imports torch
    from cssat.optics.brdf import BRDFS, Lambert  # heavy: cssat.optics.brdf imports torch

    if isinstance(brdf, str):
        if brdf not in BRDFS and brdf != "lobes":
            raise FieldError("brdf", f"expected one of {sorted([*BRDFS, 'lobes'])} or a BRDF object, got {brdf!r}")
        brdf = Lambert(1.0) if brdf == "lambert" else Lobes() if brdf == "lobes" else BRDFS[brdf]()
    N = fibonacci_sphere(n_normals)
    G = egi_operator(sun_body, obs_body, N, brdf)
    y = np.asarray(flux, dtype=np.float64).reshape(-1)
    allowed = ("lam", "n_nonzero", "max_iter", "tv_neighbours")
    for k in recover_options:
        if k not in allowed:
            raise FieldError(k, f"not an option of the EGI solve; allowed: {', '.join(allowed)}")
    if solver is not None:
        if recover_options:
            raise FieldError(next(iter(recover_options)), "an option of recover_egi's methods: give it to the solver instead")
        a, info = _solve_with(solver, G, y, sigma, closure)
        method = "tv" if info["method"] == "nntv" else info["method"]
    else:
        a, info = recover_egi(G, y, sigma=sigma, method=method, closure=closure, **recover_options)
    normals, areas, lobe_areas, keep = split_lobes(a, N.numpy(), brdf)
    Gm = G.matrix().numpy()
    model = Gm @ a
    if refine is None:
        refine = method != "tv" and lobe_areas is None
    elif refine and lobe_areas is not None:
        raise FieldError("refine", "the atoms' refinement moves one BRDF's EGI; not for an EGI per lobe (brdf=Lobes)")
    if refine and keep.any():
        from cssat.inversion.recover import refine_egi  # heavy: cssat.inversion.recover imports torch

        spacing = np.degrees(np.sqrt(4 * np.pi / len(N)))
        S_, O_ = (np.asarray(v, dtype=np.float64) for v in (sun_body, obs_body))
        normals, areas, rinfo = refine_egi(S_, O_, y, normals, areas, sigma=sigma, brdf=brdf, closure=closure,
                                           merge_deg=1.5 * spacing)
        info.update(grid_chi2=info["chi2"], chi2=rinfo["chi2"], refined_atoms=len(areas), atoms_merged=rinfo["atoms_merged"],
                    refine_nfev=rinfo["nfev"])
        model = egi_operator(S_, O_, normals, brdf).matrix().numpy() @ areas
    mesh = None
    if keep.sum() >= 4:
        mesh, minfo = minkowski(normals, areas)
        info.update({f"minkowski_{k}": v for k, v in minfo.items()})
    return ConvexInversion(normals, areas, mesh, y - model, info, lobe_areas, brdf)


def convex_iou(a: Any, b: Any, *, match_volume: bool = True, align_centroids: bool = True) -> float:
    """The volume intersection over union of two convex bodies (their convex hulls: ``trimesh``
    meshes or ``(V, 3)`` points), exact: the intersection of two convex polytopes is the
    intersection of their halfspaces (scipy's qhull). ``match_volume``: ``b`` scaled about its
    centroid to ``a``'s volume first; ``align_centroids``: both moved to their centroids."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection  # heavy: scipy.spatial, only for convex_iou()

    def hull(x):
        pts = np.asarray(getattr(x, "vertices", x), dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4 or not np.isfinite(pts).all():
            raise FieldError("mesh", f"expected a mesh or points (V >= 4, 3), got shape {pts.shape}")
        h = ConvexHull(pts)
        return pts[h.vertices], h

    pa, ha = hull(a)
    pb, hb = hull(b)
    ca = _centroid(pa - pa.mean(0), ConvexHull(pa - pa.mean(0)).simplices) + pa.mean(0)
    cb = _centroid(pb - pb.mean(0), ConvexHull(pb - pb.mean(0)).simplices) + pb.mean(0)
    if align_centroids:
        pa, pb = pa - ca, pb - cb
        ca = cb = np.zeros(3)
    if match_volume:
        pb = cb + (pb - cb) * (ha.volume / hb.volume) ** (1 / 3)
    ha, hb = ConvexHull(pa), ConvexHull(pb)
    inner = ca if align_centroids else None
    eqs = np.vstack([ha.equations, hb.equations])
    if inner is None or not (eqs[:, :3] @ inner + eqs[:, 3] < -1e-12).all():
        from scipy.optimize import linprog  # heavy: scipy.optimize; a point strictly inside both: the Chebyshev centre

        norm = np.linalg.norm(eqs[:, :3], axis=1)
        res = linprog([0, 0, 0, -1], A_ub=np.hstack([eqs[:, :3], norm[:, None]]), b_ub=-eqs[:, 3],
                      bounds=[(None, None)] * 3 + [(0, None)])
        if not res.success or res.x[3] <= 1e-12:
            return 0.0  # disjoint, or touching
        inner = res.x[:3]
    pts = HalfspaceIntersection(eqs, inner).intersections
    vi = ConvexHull(pts).volume
    return float(vi / (ha.volume + hb.volume - vi))
