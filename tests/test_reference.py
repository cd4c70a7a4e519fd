"""Sensing-matrix estimation from reference satellites (Eq. 22–30) on small grids."""

import numpy as np
import pytest
import torch

from cssat.reference import (
    estimate_sensing_full_rank,
    estimate_sensing_min_norm,
    estimate_sensing_sparse,
    relative_error,
)
from cssat.sparse import DCT, dct_matrix


def _references(n_pixel, N, seed=0, dtype=torch.float64):
    """Non-negative 'images' with a black background and white noise, as columns."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(n_pixel, N, generator=g, dtype=dtype) * (torch.rand(n_pixel, N, generator=g, dtype=dtype) < 0.4)
    return X + 0.01 * torch.randn(n_pixel, N, generator=g, dtype=dtype)


def test_full_rank_recovers_phi_to_round_off():
    g = torch.Generator().manual_seed(1)
    X = _references(256, 256)
    phi = torch.randn(180, 256, generator=g, dtype=torch.float64) / 16
    phi_hat = estimate_sensing_full_rank(X, phi @ X)
    assert phi_hat.shape == (180, 256)
    assert relative_error(phi_hat, phi) < 1e-9
    # the same solve in float32 stays accurate to the conditioning of X
    phi32 = estimate_sensing_full_rank(X.float(), (phi @ X).float())
    assert relative_error(phi32.double(), phi) < 1e-2


def test_full_rank_refuses_singular_and_too_few_references():
    X = _references(64, 64)
    X[:, 5] = X[:, 7]  # two identical reference images
    with pytest.raises(ValueError, match=r"^X_ref: .*estimate_sensing_sparse"):
        estimate_sensing_full_rank(X, torch.randn(10, 64, dtype=torch.float64) @ X)
    X = _references(64, 50)
    with pytest.raises(ValueError, match=r"^X_ref: N=50 .*rank deficient"):
        estimate_sensing_full_rank(X, torch.zeros(10, 50, dtype=torch.float64))
    with pytest.raises(ValueError, match=r"^Y_ref"):
        estimate_sensing_full_rank(_references(64, 64), torch.zeros(10, 63, dtype=torch.float64))


def test_rank_deficient_recovers_a_phi_sparse_in_the_dct():
    """Φᵀ = ΨA with 4-sparse columns of A, N = 0.8 n_pixel references: Eq. 28 recovers Φ."""
    side, T0, m = 16, 4, 60
    n_pixel = side * side
    N = int(0.8 * n_pixel)
    g = torch.Generator().manual_seed(2)
    A = torch.zeros(n_pixel, m, dtype=torch.float64)
    for i in range(m):
        A[torch.randperm(n_pixel, generator=g)[:T0], i] = torch.randn(T0, generator=g, dtype=torch.float64)
    psi = torch.kron(dct_matrix(side), dct_matrix(side)).T  # Ψ: columns are 2-D DCT atoms (independent of cssat.DCT)
    phi = (psi @ A).T
    X = _references(n_pixel, N, seed=3)
    phi_hat, info = estimate_sensing_sparse(X, phi @ X, n_nonzero_coefs=T0, return_info=True)
    assert relative_error(phi_hat, phi) < 1e-8
    assert int(info.n_iter.max()) <= T0
    # Φ̂Ψ is the coefficient matrix Âᵀ itself (the CS dictionary of the reconstruction)
    torch.testing.assert_close(DCT((side, side)).adjoint(phi_hat), info.coefficients)
    # the minimum-norm baseline fits the references exactly but misses Φ off their span
    phi_mn = estimate_sensing_min_norm(X, phi @ X)
    torch.testing.assert_close(phi_mn @ X, phi @ X)
    assert relative_error(phi_mn, phi) > 0.1


def test_rank_deficient_error_constrained_mode_and_errors():
    X = _references(64, 50)
    g = torch.Generator().manual_seed(4)
    phi = torch.randn(8, 64, generator=g, dtype=torch.float64)
    Y = phi @ X
    tol = 1e-3 * float((Y * Y).sum(1).min())
    _, info = estimate_sensing_sparse(X, Y, tol=tol, return_info=True)
    assert bool((info.residual_sq <= tol * (1 + 1e-9)).all())
    with pytest.raises(ValueError, match="^n_nonzero_coefs: give T0"):
        estimate_sensing_sparse(X, Y)
    with pytest.raises(ValueError, match="^shape"):
        estimate_sensing_sparse(_references(60, 50), torch.zeros(3, 50, dtype=torch.float64), n_nonzero_coefs=2)


def test_min_norm_rows_lie_in_the_span_of_the_references():
    X = _references(100, 30)
    Y = torch.randn(5, 30, dtype=torch.float64, generator=torch.Generator().manual_seed(5))
    phi_mn = estimate_sensing_min_norm(X, Y)
    # compare with numpy's pseudo-inverse (an independent reference)
    np.testing.assert_allclose(phi_mn.numpy(), Y.numpy() @ np.linalg.pinv(X.numpy()), rtol=1e-8, atol=1e-10)


def test_the_pool_light_curves_are_each_repeats_products():
    """sim3 forms Φ x for the whole pool once when the repeats draw more images than the pool
    holds; a repeat's columns must be its Φ X_ref (to round-off), including across the blocks."""
    from cssat.experiments.estimators import _pool_light_curves, _share_light_curves

    g = torch.Generator().manual_seed(1)
    phi, flat = torch.randn(50, 64, generator=g), torch.rand(300, 64, generator=g)
    idx = torch.randperm(300, generator=g)[:120]
    got = _pool_light_curves(phi, flat, block=70)[:, idx]
    torch.testing.assert_close(got, phi @ flat[idx].T, rtol=1e-6, atol=1e-5)
    assert _share_light_curves(8000, 3277, 9) and _share_light_curves(32000, 13107, 9)
    assert not _share_light_curves(8000, 3277, 1)  # the m_n sweep's one repeat: forming 8000 would cost more
