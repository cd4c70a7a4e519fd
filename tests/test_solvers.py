"""ℓ1 (FISTA) and total-variation (Chambolle–Pock) reconstruction (issue 7, first part)."""

import numpy as np
import pytest
import torch

from cssat.sparse import GaussianSensing
from cssat.sparse.solvers import fista_l1, operator_norm_sq, tv_divergence, tv_gradient, tv_pdhg


def test_fista_matches_scikit_learn_lasso():
    sklearn = pytest.importorskip("sklearn.linear_model")
    g = torch.Generator().manual_seed(0)
    m, n = 60, 150
    A = torch.randn(m, n, generator=g, dtype=torch.float64) / m**0.5
    gamma = torch.zeros(n, dtype=torch.float64)
    gamma[torch.randperm(n, generator=g)[:6]] = torch.randn(6, generator=g, dtype=torch.float64)
    y = A @ gamma
    est, info = fista_l1(A, y, lam=0.01, max_iter=20000, rtol=1e-12, return_info=True)
    lam_abs = float(info.lam[0])
    # scikit-learn's Lasso minimises (1/2m)‖y − Aw‖² + α‖w‖₁: the same problem with α = λ/m
    ref = sklearn.Lasso(alpha=lam_abs / m, fit_intercept=False, tol=1e-14, max_iter=200000).fit(A.numpy(), y.numpy()).coef_
    np.testing.assert_allclose(est.numpy(), ref, atol=1e-6)
    assert info.converged


def test_fista_recovers_an_exactly_sparse_signal_and_decreases_the_objective():
    g = torch.Generator().manual_seed(1)
    m, n = 80, 200
    A = torch.randn(m, n, generator=g, dtype=torch.float64) / m**0.5
    gamma = torch.zeros(2, n, dtype=torch.float64)
    for b in range(2):
        gamma[b, torch.randperm(n, generator=g)[:8]] = torch.randn(8, generator=g, dtype=torch.float64)
    est, info = fista_l1(A, gamma @ A.T, lam=1e-6, max_iter=20000, rtol=1e-12, return_info=True)
    assert float((est - gamma).norm() / gamma.norm()) < 1e-3
    assert info.objective[-1] < 1e-3 * info.objective[0]


def test_tv_recovers_a_piecewise_constant_image():
    img = torch.zeros(16, 16, dtype=torch.float64)
    img[3:9, 2:12] = 1.0
    img[10:14, 5:15] = 0.4
    phi = GaussianSensing(200, 256, seed=3, dtype=torch.float64)
    y = phi(img.reshape(-1))
    est, info = tv_pdhg(phi, y, (16, 16), lam=1e-4, max_iter=5000, rtol=1e-9, return_info=True)
    assert info.converged and float((est - img).norm() / img.norm()) < 1e-3
    assert info.objective[-1] < info.objective[0]
    assert bool((est >= 0).all())


def test_tv_gradient_and_divergence_are_adjoint():
    g = torch.Generator().manual_seed(4)
    x = torch.randn(3, 7, 9, generator=g, dtype=torch.float64)
    p = torch.randn(3, 2, 7, 9, generator=g, dtype=torch.float64)
    lhs = (tv_gradient(x) * p).sum()
    rhs = -(x * tv_divergence(p)).sum()
    assert abs(float(lhs - rhs)) < 1e-12 * float(lhs.abs() + rhs.abs())


def test_operator_norm_matches_the_largest_singular_value():
    A = torch.randn(40, 70, generator=torch.Generator().manual_seed(5), dtype=torch.float64)
    s = torch.linalg.svdvals(A)[0] ** 2
    assert operator_norm_sq(A, n_iter=200) == pytest.approx(float(s) * 1.01, rel=1e-3)


@pytest.mark.parametrize(
    "call, field",
    [
        (lambda A, y: fista_l1(A, y, lam=-1.0), "lam"),
        (lambda A, y: fista_l1(A, y, max_iter=0), "max_iter"),
        (lambda A, y: tv_pdhg(A, y, (4, 4), lam=-0.1), "lam"),
        (lambda A, y: tv_pdhg(A, y, (4, 4), max_iter=0), "max_iter"),
        (lambda A, y: tv_pdhg(A, y, (4, 5)), "shape"),
        (lambda A, y: fista_l1(A, y[:-1]), "y"),
    ],
)
def test_bad_parameters_are_refused(call, field):
    A = torch.randn(10, 16, dtype=torch.float64)
    y = torch.randn(10, dtype=torch.float64)
    with pytest.raises(ValueError, match=f"^{field}"):
        call(A, y)


def test_pnp_with_a_soft_threshold_denoiser_is_ista_and_matches_fista():
    """PnP-PGD whose 'denoiser' is soft thresholding in the DCT at λ/L is ISTA for the ℓ1
    problem, so it must reach FISTA's minimiser."""
    from cssat.sparse import DCT
    from cssat.sparse.solvers import pnp_pgd

    n = 8
    psi = DCT((n, n))
    g = torch.Generator().manual_seed(6)
    phi = torch.randn(40, n * n, generator=g, dtype=torch.float64) / 8
    img = psi(torch.where(torch.rand(n * n, generator=g) < 0.1, torch.randn(n * n, generator=g, dtype=torch.float64), 0.0)[None])[0]
    y = phi @ img
    A = phi @ psi.matrix(dtype=torch.float64)
    gamma, info = fista_l1(A, y, lam=0.05, max_iter=20000, rtol=1e-13, return_info=True)
    L = operator_norm_sq(phi)
    thr = float(info.lam[0]) / L

    def soft(x, s):
        c = psi.adjoint(x.reshape(1, -1))
        return psi(torch.sign(c) * torch.clamp(c.abs() - s, min=0)).reshape(n, n)

    x, pinfo = pnp_pgd(phi, y, (n, n), soft, sigmas=[thr] * 20000, return_info=True)
    torch.testing.assert_close(x.reshape(-1), psi(gamma[None])[0], atol=1e-6, rtol=0)
    # a batch of light curves gives, row by row, the single-curve results
    batch = pnp_pgd(phi, torch.stack([y, 2 * y]), (n, n), soft, sigmas=[thr] * 50)
    for b, yb in enumerate((y, 2 * y)):
        torch.testing.assert_close(batch[b], pnp_pgd(phi, yb, (n, n), soft, sigmas=[thr] * 50))
    with pytest.raises(ValueError, match="^sigmas"):
        pnp_pgd(phi, y, (n, n), soft, sigmas=[])
