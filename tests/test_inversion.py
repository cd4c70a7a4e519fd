"""Issue 24: the EGI sensing operator against the light curve computed facet by facet."""

from __future__ import annotations

import numpy as np
import pytest
import torch


def _views(T=300, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, T, 3))
    return v / np.linalg.norm(v, axis=2, keepdims=True)


@pytest.mark.parametrize("model", ["astra_like", "tess_like", "box"])
def test_a_meshs_shadowless_light_curve_is_the_egi_operator_times_its_egi(model):
    """facet_brightness (Eq. 8–9, cs = 0, no shadows) per unit irradiance and range, summed over
    facets, equals G @ a for the mesh's EGI — to round-off."""
    from dataclasses import replace

    from cssat.inversion import egi, egi_operator
    from cssat.optics import facet_brightness
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
    from cssat.scene import box, get_model

    mesh = box((1.5, 1.0, 0.7), divisions=2) if model == "box" else get_model(model)
    mesh = replace(mesh, cs=np.zeros(len(mesh)), _cache={})  # the Lambertian part: linear in the EGI
    s, o = _views()
    y = facet_brightness(mesh, s, o, range_km=1e-3).sum(1).numpy() / SOLAR_IRRADIANCE_W_M2  # r = 1 m
    normals, areas = egi(mesh)
    G = egi_operator(s, o, normals)
    assert np.allclose(G(torch.as_tensor(areas)[None])[0].numpy(), y, rtol=1e-9, atol=1e-15)
    assert areas.sum() == pytest.approx(float((mesh.areas * mesh.cd).sum()), rel=1e-12)


def test_the_operator_is_linear_batched_and_has_its_adjoint():
    from cssat.inversion import egi_operator, fibonacci_sphere

    s, o = _views(50, 1)
    N = fibonacci_sphere(200)
    G = egi_operator(s, o, N)
    a = torch.rand(3, 200, dtype=torch.float64)
    y = torch.rand(3, 50, dtype=torch.float64)
    assert torch.allclose((G(a) * y).sum(1), (a * G.adjoint(y)).sum(1), rtol=1e-12)  # ⟨Ga, y⟩ = ⟨a, Gᵀy⟩
    assert G.matrix().shape == (50, 200) and (G.matrix() >= 0).all()


def test_the_fibonacci_sphere_is_uniform():
    from cssat.inversion import fibonacci_sphere

    N = fibonacci_sphere(4000).numpy()
    assert np.allclose(np.linalg.norm(N, axis=1), 1.0)
    assert np.abs(N.mean(0)).max() < 1e-3  # no preferred direction
    # equal area: the fraction of points in a polar cap equals the cap's area fraction (1 − cos θ)/2
    for deg in (10, 45, 90):
        frac = (N[:, 2] > np.cos(np.radians(deg))).mean()
        assert frac == pytest.approx((1 - np.cos(np.radians(deg))) / 2, abs=1e-3)


def _sparse_case(T=1000, K=800, seed=3, closed=True):
    from cssat.inversion import egi_operator, fibonacci_sphere

    rng = np.random.default_rng(seed)
    s, o = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, T, 3)))
    N = fibonacci_sphere(K).numpy()
    if closed:  # a box: six faces on the grid's exact ±axes, opposite areas equal (Σ a n = 0)
        axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
        N = np.vstack([N, axes])
        idx = np.arange(K, K + 6)
        a = np.zeros(K + 6)
        a[idx] = np.repeat(rng.uniform(1, 4, 3), 2)
    else:
        idx = rng.choice(K, 6, replace=False)
        a = np.zeros(K)
        a[idx] = rng.uniform(1, 5, 6)
    G = egi_operator(s, o, N)
    return G, a, idx


@pytest.mark.parametrize("method", ["nnls", "nnomp", "l1"])
def test_a_sparse_egi_is_recovered_from_a_noiseless_light_curve(method):
    """1,000 random geometries, six facets on an 800-point grid: each method finds the support;
    NNLS and NN-OMP the areas to round-off (ℓ1 to its bias)."""
    from cssat.inversion import recover_egi

    G, a, idx = _sparse_case(closed=False)
    y = G.matrix().numpy() @ a
    got, info = recover_egi(G, y, method=method, lam=1e-6)
    big = np.flatnonzero(got > (1e-3 if method != "l1" else 3e-2) * got.max())
    assert set(big) == set(idx), (method, big, idx)
    tol = 1e-8 if method != "l1" else 2e-2  # ℓ1 shrinks, and FISTA stops at a relative change of 1e-10
    assert np.allclose(got[idx], a[idx], rtol=tol), (method, got[idx], a[idx])


def test_weights_and_the_closure_constraint():
    """With noise of known σ, weighted NN-OMP stops at χ² ≤ T; the closure constraint holds the
    recovered EGI's vector sum near 0 (a closed body's) without losing the fit."""
    from cssat.inversion import recover_egi

    G, a, idx = _sparse_case(closed=True)
    rng = np.random.default_rng(0)
    clean = G.matrix().numpy() @ a
    sigma = 0.01 * clean.max()
    y = clean + sigma * rng.normal(size=clean.shape)
    got, info = recover_egi(G, y, sigma=sigma, method="nnomp")
    assert info["chi2"] <= len(y) * (1 + 1e-9)
    free, _ = recover_egi(G, y, sigma=sigma, method="nnls")
    closed, cinfo = recover_egi(G, y, sigma=sigma, method="nnls", closure=10.0)
    N = G.normals.numpy()
    assert np.linalg.norm(N.T @ closed) < 0.2 * np.linalg.norm(N.T @ free) + 1e-9
    assert cinfo["chi2"] < 1.2 * len(y)
    with pytest.raises(__import__("cssat")._checks.FieldError):
        recover_egi(G, y, sigma=-1.0)


def test_the_nonnegative_solvers_take_a_problem():
    from cssat.recon import NNLS, NNOMP, Problem

    G, a, idx = _sparse_case(closed=False)
    y = G.matrix()[None] @ torch.as_tensor(a)
    for solver in (NNLS(), NNOMP()):
        x, info = solver(Problem(G, (len(a),)), y.reshape(-1))
        assert np.allclose(x.numpy(), a, atol=1e-8) and info["solver_n_nonzero"] == 6


def _support_hausdorff(A, B, n=20000):
    """The Hausdorff distance of two convex bodies: max over directions of |h_A(u) − h_B(u)|
    (support functions from the vertices)."""
    from cssat.inversion import fibonacci_sphere

    U = fibonacci_sphere(n).numpy()
    return float(np.abs((A.vertices @ U.T).max(0) - (B.vertices @ U.T).max(0)).max())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_egi_of_a_convex_polyhedron_gives_it_back(seed):
    """Minkowski: a random convex polyhedron's own EGI → the same polyhedron (Hausdorff ≤ 1e-3
    of its size; centroids aligned), its volume and surface."""
    import trimesh

    from cssat.inversion import egi, minkowski
    from cssat.scene.mesh import Mesh

    truth = trimesh.convex.convex_hull(np.random.default_rng(seed).normal(size=(30 + 50 * seed, 3)) * [3.0, 1.0, 0.5])
    N, a = egi(Mesh(truth.vertices, truth.faces, 1.0, 0.0))
    mesh, info = minkowski(N, a)
    truth.apply_translation(-truth.center_mass)
    mesh.apply_translation(-mesh.center_mass)
    assert _support_hausdorff(mesh, truth) <= 1e-3 * truth.scale
    assert mesh.volume == pytest.approx(truth.volume, rel=1e-4) and mesh.area == pytest.approx(truth.area, rel=1e-6)


def test_the_volume_hessian_is_the_finite_difference_of_the_facet_areas():
    """Minkowski's Newton step uses ``∂A_i/∂h_j`` from the facets' common edges: it equals the
    central finite difference of the facet areas (qhull), ``H h = 2A`` (areas are of degree 2
    in h) and ``H N = 0`` (a translation changes no area)."""
    import trimesh

    from cssat.inversion.shape import _volume_hessian, polytope

    rng = np.random.default_rng(4)
    N = np.asarray(trimesh.convex.convex_hull(rng.normal(size=(25, 3))).face_normals)
    N = np.unique(np.round(N, 9), axis=0)
    h = 1.0 + 0.3 * rng.random(len(N))
    _, _, _, A, E = polytope(N, h, edges=True)
    H = _volume_hessian(N, E, len(N)).toarray()
    eps = 1e-6
    fd = np.stack([(polytope(N, h + eps * e)[3] - polytope(N, h - eps * e)[3]) / (2 * eps) for e in np.eye(len(N))], 1)
    assert np.abs(H - fd).max() <= 1e-6 * np.abs(fd).max()
    assert np.allclose(H @ h, 2 * A, atol=1e-10 * A.max()) and np.abs(H @ N).max() <= 1e-7 * np.abs(H).max()


def test_minkowski_solves_a_many_faceted_body_quickly():
    """A convex hull of 700 points on an ellipsoid (~1,400 facets: the dense EGI of a smooth
    body, as TV gives) comes back from its EGI (Hausdorff ≤ 1e-3 of its size), converged."""
    import time

    import trimesh

    from cssat.inversion import egi, minkowski
    from cssat.scene.mesh import Mesh

    p = np.random.default_rng(9).normal(size=(700, 3))
    truth = trimesh.convex.convex_hull(p / np.linalg.norm(p, axis=1, keepdims=True) * [2.0, 1.0, 0.6])
    N, a = egi(Mesh(truth.vertices, truth.faces, 1.0, 0.0))
    mesh, info = minkowski(N, a)
    assert len(N) > 1000 and info["converged"], (len(N), info)
    truth.apply_translation(-truth.center_mass)
    mesh.apply_translation(-mesh.center_mass)
    assert _support_hausdorff(mesh, truth) <= 1e-3 * truth.scale
    assert info["iterations"] < 40  # Newton's steps; the gradient ascent it replaced: 3,000 steps, not converged


def test_minkowski_refuses_what_is_no_body():
    from cssat._checks import FieldError
    from cssat.inversion import minkowski

    with pytest.raises(FieldError, match="at least 4"):
        minkowski(np.eye(3), np.ones(3))
    with pytest.raises(FieldError):
        minkowski(np.array([[0, 0, 1.0], [0.1, 0, 1.0], [0, 0.1, 1.0], [0.1, 0.1, 1.0]]), np.ones(4))  # a hemisphere


def test_invert_convex_recovers_a_box_from_its_light_curve():
    """A box's Lambert light curve over 1,000 random geometries (no noise, no shadows): the
    recovered convex shape's volume IoU with the truth ≥ 0.9 (grid snapping of 1,000 normals
    costs a few per cent)."""
    from cssat.inversion import egi, egi_operator, invert_convex
    from cssat.scene import box

    b = box((3.0, 1.5, 1.0), cd=1.0, cs=0.0)
    N, a = egi(b)
    rng = np.random.default_rng(11)
    s, o = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, 1000, 3)))
    flux = egi_operator(s, o, N).matrix().numpy() @ a
    inv = invert_convex(flux, s, o, n_normals=1000)
    assert np.sqrt(np.mean(inv.residual ** 2)) < 0.05 * flux.std()
    truth = b.to_trimesh()
    got = inv.mesh
    got.apply_scale((truth.volume / got.volume) ** (1 / 3))
    got.apply_translation(-got.center_mass)
    truth.apply_translation(-truth.center_mass)
    pts = np.random.default_rng(0).uniform(-2.5, 2.5, size=(200_000, 3))
    inside = lambda m: np.all(pts @ m.facets_normal.T <= (m.facets_origin * m.facets_normal).sum(1) + 1e-12, axis=1)  # noqa: E731
    i1, i2 = inside(truth), inside(got)
    assert (i1 & i2).sum() / (i1 | i2).sum() >= 0.9
    assert abs(inv.areas.sum() - a.sum()) < 0.05 * a.sum()


def test_observability_of_simple_geometries():
    """One geometry repeated: one combination of the EGI (rank 1). An observer fixed in the body
    frame with the Sun anywhere: exactly the hemisphere facing the observer is ever seen."""
    from cssat.inversion import fibonacci_sphere, observability

    N = fibonacci_sphere(2000)
    s = np.tile([[0.6, 0.0, 0.8]], (50, 1))
    o = np.tile([[0.0, 0.6, 0.8]], (50, 1))
    assert observability(s, o, N)["effective_rank"] == 1
    rng = np.random.default_rng(2)
    s = rng.normal(size=(500, 3))
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    ob = observability(s, np.tile([[0.0, 0.0, 1.0]], (500, 1)), N)
    assert np.array_equal(ob["seen"], (N[:, 2] > 0).numpy())
    assert ob["leverage"][~ob["seen"]].max() < 1e-20  # what is never seen cannot be told


def test_a_stabilised_geo_satellite_sees_half_the_sphere_and_a_tumbler_all_of_it():
    """The README's verdict: nadir pointing at GEO keeps the observer on the Earth side of the
    body frame — half the sphere is never seen, and one night gives a few tens of independent
    combinations; a tumbling body shows the whole sphere and several times the rank."""
    from cssat.inversion import fibonacci_sphere, observability
    from cssat.optics import simulate_light_curve
    from cssat.scene import box, make_scenario
    from cssat.scene.attitudes import Nadir, Tumbling

    N = fibonacci_sphere(1000)
    sc = make_scenario(start_utc="2020-04-01T18:00:00", n_steps=720, step_s=60.0)
    out = {}
    for name, att in (("geo", Nadir()), ("tumbling", Tumbling())):
        lc = simulate_light_curve(box((1.0, 1.0, 1.0)), sc, attitude=att, shadows=False)
        out[name] = observability(lc.sun, lc.observer, N)
    assert abs(out["geo"]["seen"].mean() - 0.5) < 0.02 and out["tumbling"]["seen"].all()
    assert out["tumbling"]["effective_rank"] > 5 * out["geo"]["effective_rank"]


def _spinning_flux(mesh, period, t, pole=(40.0, 30.0)):
    """The light curve of ``mesh`` spinning about ``pole`` with the Sun and the observer fixed in
    inertial space (synodic = sidereal period), at times ``t`` (s)."""
    from cssat.optics import facet_brightness
    from cssat.scene.attitude import spin_frame

    F = spin_frame(t, pole[0], pole[1], period)
    s_in = np.array([0.8, 0.6, 0.0])
    o_in = np.array([0.6, 0.8, 0.0]) / np.linalg.norm([0.6, 0.8, 0.0])
    return facet_brightness(mesh, F @ s_in, F @ o_in, range_km=1.0).sum(1).numpy()


def _three_nights(seed=1):
    rng = np.random.default_rng(seed)
    return np.sort(np.concatenate([d * 86400.0 + rng.uniform(0, 6 * 3600.0, 300) for d in range(3)]))


def test_the_period_of_an_asymmetric_spinning_body():
    """A box with one wing (no central symmetry: two unequal maxima a turn): the periodogram's
    peak is at half the period; the odd harmonics resolve it, to 1e-4 of the period."""
    from cssat.inversion import estimate_period
    from cssat.scene import box, merge, panel

    body = merge([box((1.0, 1.0, 1.0), cs=0.0), panel((3.0, 0, 0), (0, 0, 1.0), (0.5, 0.0, -0.5), cs=0.0, two_sided=False)])
    t = _three_nights()
    y = _spinning_flux(body, 437.0, t)
    out = estimate_period(t, y / y.max(), min_period_s=60, max_period_s=3600)
    assert abs(out["period_s"] / 437.0 - 1) < 1e-4, out
    assert out["period_err_s"] < 0.1


def test_a_centrally_symmetric_body_shows_half_its_period():
    """A box is centrally symmetric: its Lambert light curve repeats every half turn, so the
    light curve alone gives P/2 (the known ambiguity), not doubled."""
    from cssat.inversion import estimate_period
    from cssat.scene import box

    t = _three_nights(2)
    y = _spinning_flux(box((2.0, 1.0, 0.5), cs=0.0), 600.0, t, pole=(10.0, 60.0))
    out = estimate_period(t, y / y.max(), min_period_s=60, max_period_s=3600)
    assert abs(out["period_s"] / 300.0 - 1) < 1e-4 and not out["doubled"], out


def test_geometry_matrix_is_the_operator_s_matrix():
    """The search loops' numpy ``G`` (batched over leading axes) equals ``egi_operator``'s for a
    Lambert surface of any albedo and for a non-Lambert BRDF; a brute-force sum for one entry."""
    from cssat.inversion.egi import egi_operator, fibonacci_sphere, geometry_matrix
    from cssat.optics.brdf import Lambert, Phong

    rng = np.random.default_rng(2)
    S = rng.normal(size=(2, 7, 3))
    O = rng.normal(size=(2, 7, 3))
    S /= np.linalg.norm(S, axis=-1, keepdims=True)
    O /= np.linalg.norm(O, axis=-1, keepdims=True)
    N = fibonacci_sphere(16).numpy()
    for brdf in (None, Lambert(0.7), Phong()):
        G = geometry_matrix(S, O, N, brdf)
        assert G.shape == (2, 7, 16)
        for b in range(2):
            assert np.allclose(G[b], egi_operator(S[b], O[b], N, brdf).matrix().numpy(), rtol=1e-12, atol=0)
    s, o, n = S[1, 3], O[1, 3], N[5]
    assert geometry_matrix(S, O, N, Lambert(0.7))[1, 3, 5] == pytest.approx(0.7 / np.pi * max(s @ n, 0) * max(o @ n, 0))


def test_nonnegative_tv_on_the_sphere_against_a_qp_solver():
    """``recover_egi(method="tv")`` minimises ½‖Ga − y‖² + λ Σ_edges |a_i − a_j| over a ≥ 0: its
    objective equals scipy's SLSQP on the QP reformulation (variables a ≥ 0 and t ≥ |Da|) to 1e-6,
    and the edges are each normal's nearest neighbours (brute force). The registry's ``nntv``
    solver gives the same EGI from a Problem."""
    from scipy.optimize import minimize

    from cssat.inversion import egi_operator, fibonacci_sphere, recover_egi
    from cssat.inversion.recover import sphere_differences
    from cssat.recon import NNTV, Problem

    rng = np.random.default_rng(5)
    K, T = 24, 60
    N = fibonacci_sphere(K).numpy()
    s, o = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, T, 3)))
    G = egi_operator(s, o, N)
    truth = np.where(N[:, 2] > 0.5, 1.0, 0.0)  # a cap of constant density: piecewise constant on the sphere
    y = G.matrix().numpy() @ truth + 0.01 * rng.normal(size=T)
    D = sphere_differences(N, 3).toarray()
    # the edges: each normal to its 3 nearest by angle, brute force
    cos = N @ N.T
    np.fill_diagonal(cos, -2)
    want = {tuple(sorted((i, int(j)))) for i in range(K) for j in np.argsort(-cos[i])[:3]}
    got_edges = {tuple(sorted(np.flatnonzero(r))) for r in D}
    assert got_edges == want
    lam_rel = 0.05
    a, info = recover_egi(G, y, method="tv", lam=lam_rel, tv_neighbours=3, max_iter=200000)
    Gm = G.matrix().numpy()
    lam = info["solver_lam_abs"]
    assert lam == pytest.approx(lam_rel * np.abs(Gm.T @ y).max())
    f = lambda x: 0.5 * np.sum((Gm @ x - y) ** 2) + lam * np.abs(D @ x).sum()  # noqa: E731
    E = D.shape[0]

    def obj(v):
        return 0.5 * np.sum((Gm @ v[:K] - y) ** 2) + lam * v[K:].sum()

    def grad(v):
        return np.concatenate([Gm.T @ (Gm @ v[:K] - y), np.full(E, lam)])

    cons = [{"type": "ineq", "fun": lambda v: v[K:] - D @ v[:K], "jac": lambda v: np.hstack([-D, np.eye(E)])},
            {"type": "ineq", "fun": lambda v: v[K:] + D @ v[:K], "jac": lambda v: np.hstack([D, np.eye(E)])}]
    v0 = np.concatenate([np.full(K, 0.5), np.full(E, 1.0)])
    ref = minimize(obj, v0, jac=grad, constraints=cons, bounds=[(0, None)] * K + [(None, None)] * E, method="SLSQP",
                   options={"maxiter": 2000, "ftol": 1e-14})
    assert ref.success, ref.message
    assert f(a) == pytest.approx(ref.fun, rel=1e-6) and a.min() >= 0
    assert np.allclose(a, ref.x[:K], atol=1e-3 * a.max())
    x, _ = NNTV(lam=lam_rel, tv_neighbours=3, max_iter=200000)(Problem(G, (K,)), torch.as_tensor(y))
    assert np.allclose(x.numpy(), a, atol=1e-9 * a.max())


def test_nonnegative_tv_on_an_image_grid_against_numpy_diff_and_a_qp_solver():
    """On a pixel problem ``nntv`` takes the image's grid: ``grid_differences`` is numpy's
    ``diff`` along each axis, and the solve's objective equals SLSQP's on the QP reformulation."""
    from scipy.optimize import minimize

    from cssat._checks import FieldError
    from cssat.inversion.recover import grid_differences
    from cssat.recon import NNTV

    rng = np.random.default_rng(2)
    H, W = 4, 5
    img = rng.normal(size=(H, W))
    D = grid_differences((H, W))
    assert np.allclose(D @ img.reshape(-1), np.concatenate([np.diff(img, axis=0).reshape(-1), np.diff(img, axis=1).reshape(-1)]))
    K, T = H * W, 14  # fewer samples than pixels
    truth = np.zeros((H, W))
    truth[1:3, 1:4] = 1.0
    A = rng.normal(size=(T, K))
    y = A @ truth.reshape(-1) + 0.01 * rng.normal(size=T)
    x, _ = NNTV(lam=0.02, max_iter=200000)(torch.as_tensor(A), torch.as_tensor(y), (H, W))
    a = x.numpy().reshape(-1)
    assert x.shape == (H, W) and a.min() >= 0
    Dm = D.toarray()
    E = Dm.shape[0]
    lam = 0.02 * np.abs(A.T @ y).max()
    obj = lambda v: 0.5 * np.sum((A @ v[:K] - y) ** 2) + lam * v[K:].sum()  # noqa: E731
    cons = [{"type": "ineq", "fun": lambda v: v[K:] - Dm @ v[:K], "jac": lambda v: np.hstack([-Dm, np.eye(E)])},
            {"type": "ineq", "fun": lambda v: v[K:] + Dm @ v[:K], "jac": lambda v: np.hstack([Dm, np.eye(E)])}]
    ref = minimize(obj, np.concatenate([np.full(K, 0.5), np.ones(E)]),
                   jac=lambda v: np.concatenate([A.T @ (A @ v[:K] - y), np.full(E, lam)]), constraints=cons,
                   bounds=[(0, None)] * K + [(None, None)] * E, method="SLSQP", options={"maxiter": 2000, "ftol": 1e-12})
    assert ref.success, ref.message
    f = 0.5 * np.sum((A @ a - y) ** 2) + lam * np.abs(Dm @ a).sum()
    assert f == pytest.approx(ref.fun, rel=1e-6)
    with pytest.raises(FieldError, match="solver"):
        NNTV()(torch.as_tensor(A), torch.as_tensor(y), (K,))


def test_tv_by_the_discrepancy_principle_recovers_a_smooth_egi_that_nnls_spikes():
    """A triaxial ellipsoid's EGI is a smooth density on the sphere (area per normal = 1/K, its
    Gaussian curvature's inverse: (abc)² (Σ n_i²/a_i²)², analytic). From 400 noisy samples on 300
    normals TV with λ by the discrepancy principle fits to the noise (χ²/T in [0.9, 1], computed
    here) and recovers the density to < 25 % — under half NNLS's error, whose solution is spikes."""
    from cssat._checks import FieldError
    from cssat.inversion import egi_operator, fibonacci_sphere, recover_egi

    rng = np.random.default_rng(3)
    T, K = 400, 300
    s, o = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, T, 3)))
    N = fibonacci_sphere(K).numpy()
    ax = np.array([2.0, 1.0, 0.6])
    truth = ax.prod() ** 2 * ((N ** 2 / ax ** 2).sum(1)) ** 2 * 4 * np.pi / K
    G = egi_operator(s, o, N)
    Gm = G.matrix().numpy()
    y0 = Gm @ truth
    sig = 0.003 * np.abs(y0).mean()
    y = y0 + sig * rng.standard_normal(T)
    tv, info = recover_egi(G, y, method="tv", sigma=sig, lam="discrepancy")
    r = (Gm @ tv - y) / sig
    assert 0.9 <= r @ r / T <= 1.0 and info["discrepancy_met"], (r @ r / T, info)
    nn, _ = recover_egi(G, y, method="nnls", sigma=sig)
    err = lambda x: np.linalg.norm(x - truth) / np.linalg.norm(truth)  # noqa: E731
    assert err(tv) < 0.25 and err(tv) < 0.5 * err(nn), (err(tv), err(nn))
    with pytest.raises(FieldError, match="lam"):
        recover_egi(G, y, method="tv", lam="discrepancy")  # no noise given
    with pytest.raises(FieldError, match="lam"):
        recover_egi(G, y, method="l1", sigma=sig, lam="morozov")
    with pytest.raises(FieldError, match="y: the light curve must be finite"):
        recover_egi(G, np.where(np.arange(T) == 7, np.nan, y), method="tv", sigma=sig)


def test_nonnegative_l1_solver_against_l_bfgs_b():
    """The registry's ``nnl1`` minimises ½‖Ga − y‖² + λ Σ a over a ≥ 0 (λ relative to ‖Gᵀy‖∞):
    its objective equals scipy's L-BFGS-B with bounds on the same smooth program to 1e-6."""
    from scipy.optimize import minimize

    from cssat.inversion import egi_operator, fibonacci_sphere
    from cssat.recon import NNL1, Problem

    rng = np.random.default_rng(8)
    K, T = 32, 80
    N = fibonacci_sphere(K).numpy()
    s, o = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, T, 3)))
    G = egi_operator(s, o, N)
    Gm = G.matrix().numpy()
    truth = np.zeros(K)
    truth[rng.choice(K, 5, replace=False)] = rng.uniform(1, 3, 5)
    y = Gm @ truth + 0.01 * rng.normal(size=T)
    x, _ = NNL1(lam=0.02, max_iter=100000)(Problem(G, (K,)), torch.as_tensor(y))
    a = x.numpy()
    lam = 0.02 * np.abs(Gm.T @ y).max()
    f = lambda v: 0.5 * np.sum((Gm @ v - y) ** 2) + lam * v.sum()  # noqa: E731
    ref = minimize(f, np.ones(K), jac=lambda v: Gm.T @ (Gm @ v - y) + lam, bounds=[(0, None)] * K, method="L-BFGS-B",
                   options={"ftol": 1e-15, "gtol": 1e-12, "maxiter": 10000})
    assert a.min() >= 0 and f(a) == pytest.approx(ref.fun, rel=1e-6)
