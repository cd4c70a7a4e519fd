import numpy as np
import pytest
import scipy.fft
import torch

from conftest import dot_test
from cssat.sparse import DCT, ComposedOperator, GaussianSensing, MatrixOperator, sensing_dictionary

SHAPES = [(7,), (16,), (8, 8), (6, 10), (4, 5, 6)]


@pytest.mark.parametrize("shape", SHAPES)
def test_dct_matches_scipy_dctn(shape):
    rng = np.random.default_rng(1)
    x = rng.standard_normal((3, *shape))
    op = DCT(shape)
    ref = scipy.fft.dctn(x, axes=tuple(range(1, len(shape) + 1)), norm="ortho")
    got = op.adjoint(torch.tensor(x)).numpy()
    np.testing.assert_allclose(got, ref, atol=1e-12)
    # synthesis is the inverse DCT
    back = op(torch.tensor(ref)).numpy()
    np.testing.assert_allclose(back, x, atol=1e-12)
    ref_inv = scipy.fft.idctn(x, axes=tuple(range(1, len(shape) + 1)), norm="ortho")
    np.testing.assert_allclose(op(torch.tensor(x)).numpy(), ref_inv, atol=1e-12)


@pytest.mark.parametrize("shape", SHAPES)
def test_dct_flat_and_shaped_layouts_agree(shape):
    op = DCT(shape)
    x = torch.randn(2, *shape, dtype=torch.float64)
    flat = op.adjoint(x.reshape(2, -1))
    assert flat.shape == (2, op.n_in)
    torch.testing.assert_close(flat, op.adjoint(x).reshape(2, -1))


@pytest.mark.parametrize("shape", SHAPES)
def test_dct_matrix_is_orthonormal_and_consistent(shape):
    op = DCT(shape)
    psi = op.matrix(dtype=torch.float64)
    eye = torch.eye(op.n_in, dtype=torch.float64)
    torch.testing.assert_close(psi.T @ psi, eye, atol=1e-12, rtol=0)
    torch.testing.assert_close(psi @ psi.T, eye, atol=1e-12, rtol=0)
    g = torch.randn(4, op.n_in, dtype=torch.float64)
    torch.testing.assert_close(op(g), g @ psi.T)  # forward = Ψγ
    # the generic LinearOperator.matrix (via the adjoint) agrees with the Kronecker construction
    from cssat.sparse.operators import LinearOperator

    torch.testing.assert_close(LinearOperator.matrix(op, dtype=torch.float64), psi)


def test_operators_pass_dot_product_test():
    ops = [DCT(s) for s in SHAPES]
    ops.append(GaussianSensing(30, 64, seed=3, dtype=torch.float64))
    ops.append(MatrixOperator(torch.randn(5, 9, dtype=torch.float64)))
    ops.append(GaussianSensing(30, 64, seed=3, dtype=torch.float64) @ DCT((8, 8)))
    for op in ops:
        assert dot_test(op) < 1e-12, type(op).__name__


def test_operators_follow_input_dtype():
    op = GaussianSensing(20, 36, seed=1, dtype=torch.float64) @ DCT((6, 6))
    for dt in (torch.float32, torch.float64):
        assert op(torch.randn(2, 36, dtype=dt)).dtype == dt
        assert op.adjoint(torch.randn(2, 20, dtype=dt)).dtype == dt


def test_gaussian_statistics_reproducibility_and_nesting():
    a = GaussianSensing(400, 500, seed=7, dtype=torch.float64).matrix()
    b = GaussianSensing(400, 500, seed=7, dtype=torch.float64).matrix()
    c = GaussianSensing(100, 500, seed=7, dtype=torch.float64).matrix()
    d = GaussianSensing(400, 500, seed=8, dtype=torch.float64).matrix()
    assert torch.equal(a, b)
    assert torch.equal(a[:100], c)  # rows do not depend on m: nested measurement sets
    assert not torch.equal(a, d)
    # N(0, 1/n): mean and variance within ~5 standard errors (200k samples)
    n_el = a.numel()
    assert abs(float(a.mean())) < 5 * (1 / 500) ** 0.5 / n_el**0.5
    assert abs(float(a.var()) * 500 - 1) < 5 * (2 / n_el) ** 0.5
    # rows are independent: off-diagonal correlations of rows are small
    corr = torch.corrcoef(a[:50])
    assert float((corr - torch.eye(50, dtype=a.dtype)).abs().max()) < 0.25


def test_gaussian_bad_sizes():
    with pytest.raises(ValueError, match="m:"):
        GaussianSensing(0, 10)
    with pytest.raises(ValueError, match="n:"):
        GaussianSensing(3, 0)
    with pytest.raises(ValueError, match="dtype"):
        GaussianSensing(3, 4, dtype=torch.int32)


def test_composition_materialised_equals_dense_product():
    phi = GaussianSensing(40, 48, seed=2, dtype=torch.float64)
    psi = DCT((6, 8))
    dense = phi.matrix() @ psi.matrix(dtype=torch.float64)
    comp = ComposedOperator(phi, psi)
    torch.testing.assert_close(comp.matrix(dtype=torch.float64), dense)
    torch.testing.assert_close(sensing_dictionary(phi, (6, 8)), dense)
    g = torch.randn(3, 48, dtype=torch.float64)
    torch.testing.assert_close(comp(g), g @ dense.T)
    with pytest.raises(ValueError, match="inner"):
        ComposedOperator(phi, DCT((5, 5)))


def test_shape_errors_name_the_argument():
    with pytest.raises(ValueError, match="x: trailing shape"):
        DCT((4, 4)).adjoint(torch.randn(2, 15))
    with pytest.raises(ValueError, match=r"x: expected rows \(B, 5\), images \(B, C, H, W\)"):
        GaussianSensing(3, 5)(torch.randn(2, 4))
    with pytest.raises(ValueError, match=r"x: expected .*or \(B, \*\(1, 2, 3\)\)"):
        GaussianSensing(3, (1, 2, 3))(torch.randn(2, 5))
    with pytest.raises(ValueError, match="y: last dimension"):
        GaussianSensing(3, 5).A_dagger(torch.randn(2, 4))
    with pytest.raises(ValueError, match="shape"):
        DCT((2, 2, 2, 2))


def test_omp_solver_on_a_batch_equals_the_explicit_matrices():
    from cssat.recon import OMP
    from cssat.sparse import batch_omp

    phi = GaussianSensing(150, 256, seed=4, dtype=torch.float64)
    g = torch.Generator().manual_seed(0)
    x = torch.rand(2, 256, generator=g, dtype=torch.float64)
    y = phi(x)
    img, info = OMP(n_nonzero_coefs=30)(phi, y, (16, 16))
    gamma = info["coefficients"]
    assert img.shape == (2, 16, 16) and gamma.shape == (2, 256)
    ref = batch_omp(phi.matrix() @ DCT((16, 16)).matrix(dtype=torch.float64), y, n_nonzero_coefs=30)
    torch.testing.assert_close(gamma, ref, atol=1e-10, rtol=0)
    torch.testing.assert_close(img.reshape(2, -1), DCT((16, 16))(ref), atol=1e-10, rtol=0)
    assert info["omp_atoms"] == 30


def test_odct_dictionary():
    from cssat.sparse import odct_matrix

    d = odct_matrix(8, 16)
    assert d.shape == (8, 16)
    torch.testing.assert_close(torch.linalg.vector_norm(d, dim=0), torch.ones(16, dtype=torch.float64))
    torch.testing.assert_close(d[:, 0], torch.full((8,), 8**-0.5, dtype=torch.float64))
    torch.testing.assert_close(d[:, 1:].sum(0), torch.zeros(15, dtype=torch.float64), atol=1e-12, rtol=0)
    # column k is a cosine of frequency k/16 (mean removed): check one against the formula
    v = torch.cos(torch.pi * torch.arange(8, dtype=torch.float64) * 3 / 16)
    v = v - v.mean()
    torch.testing.assert_close(d[:, 3], v / v.norm())
    assert torch.linalg.matrix_rank(d) == 8  # spans R^8: overcomplete


@pytest.mark.parametrize("shapes", [[(4, 6)], [(4, 6), (3, 5)], [(2, 3), (3, 4), (4, 2)]])
def test_kronecker_operator_equals_the_dense_kronecker_product(shapes):
    from cssat.sparse import KroneckerOperator

    g = torch.Generator().manual_seed(1)
    mats = [torch.randn(*s, generator=g, dtype=torch.float64) for s in shapes]
    op = KroneckerOperator(mats)
    dense = mats[0]
    for m in mats[1:]:
        dense = torch.kron(dense, m)
    torch.testing.assert_close(op.matrix(dtype=torch.float64), dense)
    x = torch.randn(5, op.n_in, generator=g, dtype=torch.float64)
    torch.testing.assert_close(op(x), x @ dense.T)
    assert dot_test(op) < 1e-12


def test_images_in_deepinv_layout():
    """(B, C, H, W) and (B, H, W) images are flattened in C order; with a shape for n the
    adjoint and A_dagger give the images back."""
    phi = GaussianSensing(30, 48, seed=4, dtype=torch.float64)
    shaped = GaussianSensing(30, (3, 4, 4), seed=4, dtype=torch.float64)
    torch.testing.assert_close(shaped.matrix(), phi.matrix())  # the same draws
    x = torch.randn(5, 3, 4, 4, dtype=torch.float64)
    ref = x.reshape(5, 48) @ phi.matrix().T
    torch.testing.assert_close(phi(x), ref)
    torch.testing.assert_close(shaped.A(x), ref)
    y = torch.randn(5, 30, dtype=torch.float64)
    assert shaped.adjoint(y).shape == (5, 3, 4, 4) and phi.adjoint(y).shape == (5, 48)
    torch.testing.assert_close(shaped.A_adjoint(y).reshape(5, 48), y @ phi.matrix())
    gray = GaussianSensing(30, 16, seed=1, dtype=torch.float64)
    img = torch.randn(2, 1, 4, 4, dtype=torch.float64)
    torch.testing.assert_close(gray(img), gray(img.reshape(2, 4, 4)))  # (B, 1, H, W) as (B, H, W): (B, m)
    assert gray(img[0, 0]).shape == (30,)  # one (H, W) image: one light curve
    assert gray(torch.randn(7, 2, 16, dtype=torch.float64)).shape == (7, 2, 30)  # rows keep their batch axes
    psi = DCT((4, 4))
    comp = gray @ psi
    torch.testing.assert_close(comp(img), comp(img.reshape(2, 16)))


@pytest.mark.parametrize("m,n", [(40, 24), (24, 40), (30, 30)])
def test_a_dagger_is_the_minimum_norm_least_squares_solution(m, n):
    rng = np.random.default_rng(m + n)
    M = rng.standard_normal((m, n))
    if m == n:  # rank deficient: the minimum-norm solution is the one asked for
        M[:, -5:] = M[:, :5]
    y = rng.standard_normal((3, m))
    ref = np.linalg.lstsq(M, y.T, rcond=None)[0].T  # numpy's SVD solve, the reference
    op = MatrixOperator(torch.tensor(M))
    np.testing.assert_allclose(op.A_dagger(torch.tensor(y)).numpy(), ref, atol=1e-8)
    np.testing.assert_allclose(op.A_dagger(y), ref, atol=1e-8)  # numpy in, numpy out
    # the matrix-free CGLS of any operator converges to the same solution
    comp = ComposedOperator(op, MatrixOperator(torch.eye(n, dtype=torch.float64)))
    np.testing.assert_allclose(comp.A_dagger(torch.tensor(y), max_iter=500, rtol=1e-12).numpy(), ref, atol=1e-6)
    psi = DCT((4, 6))
    x = torch.randn(2, 24, dtype=torch.float64)
    torch.testing.assert_close(psi.A_dagger(psi(x)), x)  # orthonormal: Ψ⁺ = Ψᵀ


def test_reprs_show_sizes_and_seed():
    assert repr(GaussianSensing(5, 16, seed=7)).startswith("GaussianSensing(m=5, n=16, seed=7")
    assert "shape=(4, 4)" in repr(DCT((4, 4)))
    assert "n_out=5, n_in=16" in repr(GaussianSensing(5, 16) @ DCT((4, 4)))
