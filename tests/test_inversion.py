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
