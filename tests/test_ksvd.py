"""Sparse K-SVD training and denoising (issue 4)."""

import math

import numpy as np
import pytest
import torch
from conftest import dot_test

from cssat.sparse import (
    KroneckerOperator,
    SparseDictionary,
    accumulate_patches,
    estimate_sigma,
    extract_patches,
    ksvd,
    ksvd_denoise,
    odct_base,
    odct_matrix,
    sparse_ksvd,
)


def _smooth_image(n: int = 48, seed: int = 0) -> np.ndarray:
    """A piecewise-smooth test image on a 0–255 scale: a gradient, a disc and a bar."""
    y, x = np.mgrid[0:n, 0:n] / n
    img = 60 + 80 * x + 40 * y
    img = img + 90 * ((x - 0.55) ** 2 + (y - 0.45) ** 2 < 0.06)
    img = img - 70 * ((np.abs(x - 0.25) < 0.06) & (y > 0.3))
    return img.astype(np.float64)


def _synthetic(p_side=8, L=40, n=1200, k=3, noise=0.0, seed=0):
    """Signals that are ``k``-sparse over a known sparse dictionary ``D = B A``."""
    g = torch.Generator().manual_seed(seed)
    base = odct_base((p_side, p_side), dtype=torch.float64)
    K0 = base.n_in
    A = torch.zeros(K0, L, dtype=torch.float64)
    for j in range(L):
        rows = torch.randperm(K0, generator=g)[:4]
        A[rows, j] = torch.randn(4, generator=g, dtype=torch.float64)
    D = base(A.T).T
    D = D / D.norm(dim=0)
    codes = torch.zeros(n, L, dtype=torch.float64)
    for i in range(n):
        cols = torch.randperm(L, generator=g)[:k]
        codes[i, cols] = torch.randn(k, generator=g, dtype=torch.float64).sign() * (1 + torch.rand(k, generator=g, dtype=torch.float64))
    X = codes @ D.T + noise * torch.randn(n, D.shape[0], generator=g, dtype=torch.float64)
    return X, D, base


def test_sparse_dictionary_operator_matches_its_matrix_and_gram():
    base = odct_base((4, 5), (6, 7), dtype=torch.float64)
    g = torch.Generator().manual_seed(1)
    A = torch.randn(base.n_in, 9, generator=g, dtype=torch.float64)
    D = SparseDictionary(base, A)
    M = D.matrix()
    brute = torch.kron(odct_matrix(4, 6), odct_matrix(5, 7)) @ A  # independent: the full Kronecker
    torch.testing.assert_close(M, brute)
    torch.testing.assert_close(D.gram(), brute.T @ brute)
    x = torch.randn(3, 9, generator=g, dtype=torch.float64)
    torch.testing.assert_close(D(x), x @ brute.T)
    assert dot_test(D) < 1e-12


def test_training_lowers_the_error_every_iteration():
    X, _, base = _synthetic(noise=0.05)
    _, info = sparse_ksvd(X, base, n_atoms=40, atom_sparsity=4, n_nonzero_coefs=3, n_iter=8,
                          init="data", seed=0, return_info=True)
    rmse = info.rmse
    assert len(rmse) == 8
    assert all(b < a for a, b in zip(rmse, rmse[1:])), rmse
    assert rmse[-1] < 0.6 * rmse[0]


def test_trained_atoms_are_sparse_and_normalised():
    X, _, base = _synthetic(noise=0.05)
    D, info = sparse_ksvd(X, base, n_atoms=40, atom_sparsity=4, tol=X.shape[1] * 0.06**2, n_iter=4,
                          init="data", seed=0, return_info=True)
    assert int((D.atoms != 0).sum(0).max()) <= 4
    torch.testing.assert_close(D.matrix().norm(dim=0), torch.ones(40, dtype=torch.float64))
    assert len(info.mean_atoms) == 4 and all(m > 0 for m in info.mean_atoms)


def test_plain_ksvd_recovers_a_generating_dictionary():
    """Aharon, Elad & Bruckstein's (2006) synthetic experiment: a random 20 × 50 dictionary,
    1500 combinations of 3 atoms with noise at 20 dB SNR; K-SVD finds most generating atoms
    (|dᵢᵀd̂ⱼ| > 0.99)."""
    g = torch.Generator().manual_seed(3)
    Dtrue = torch.randn(20, 50, generator=g, dtype=torch.float64)
    Dtrue /= Dtrue.norm(dim=0)
    codes = torch.zeros(1500, 50, dtype=torch.float64)
    for i in range(1500):
        codes[i, torch.randperm(50, generator=g)[:3]] = torch.randn(3, generator=g, dtype=torch.float64)
    clean = codes @ Dtrue.T
    X = clean + 0.1 * clean.std() * torch.randn(clean.shape, generator=g, dtype=torch.float64)
    D, info = ksvd(X, 50, n_nonzero_coefs=3, n_iter=40, seed=0, return_info=True)
    found = ((Dtrue.T @ D.matrix()).abs().max(dim=1).values > 0.99).double().mean()
    assert found >= 0.85, (found, info.rmse[-1])


def test_denoise_improves_a_noisy_image_and_estimates_sigma():
    img = _smooth_image()
    noisy = img + np.random.default_rng(0).normal(0, 20, img.shape)
    out, info = ksvd_denoise(noisy, n_iter=5, return_info=True)
    assert isinstance(out, np.ndarray) and out.shape == img.shape
    assert info.sigma_estimated and abs(info.sigma - 20) < 4
    mse = lambda a: float(np.mean((a - img) ** 2))  # noqa: E731
    assert mse(out) < 0.25 * mse(noisy)


def test_denoising_a_noiseless_image_changes_it_little():
    img = _smooth_image()
    out = ksvd_denoise(torch.tensor(img), n_iter=3)
    assert out.dtype == torch.float64
    rms = float(torch.sqrt(torch.mean((out - torch.tensor(img)) ** 2)))
    assert rms < 2.0  # on a 0–255 scale (the noise estimate of a clean image is not zero)


def test_denoise_is_deterministic_by_seed():
    img = _smooth_image(40)
    noisy = torch.tensor(img + np.random.default_rng(1).normal(0, 15, img.shape), dtype=torch.float32)
    a = ksvd_denoise(noisy, 15.0, n_iter=3, seed=4)
    b = ksvd_denoise(noisy, 15.0, n_iter=3, seed=4)
    assert torch.equal(a, b)


def test_3d_denoise_of_a_stack_uses_cubes_and_beats_the_noisy_slices():
    img = _smooth_image(32)
    rng = np.random.default_rng(2)
    stack = np.stack([img + rng.normal(0, s, img.shape) for s in (10, 20, 30)])
    out, info = ksvd_denoise(stack, n_iter=2, n_atoms=200, n_train=4000, return_info=True)
    assert out.shape == stack.shape and info.block_size == (3, 8, 8)
    # each slice gains: ≥ 2 dB at σ = 10, ≥ 6 dB at σ = 20 and 30 (measured 3.1, 8.6, 9.8 dB); a
    # denoiser that returns its input gains 0 dB and fails
    for k, bar in enumerate((2.0, 6.0, 6.0)):
        gain = 10 * np.log10(np.mean((stack[k] - img) ** 2) / np.mean((out[k] - img) ** 2))
        assert gain >= bar, (k, gain)


def test_estimate_sigma_of_white_noise():
    g = torch.Generator().manual_seed(0)
    for s in (0.5, 3.0):
        assert estimate_sigma(s * torch.randn(256, 256, generator=g)) == pytest.approx(s, rel=0.03)
    stack = torch.stack([s * torch.randn(128, 128, generator=g) for s in (1.0, 2.0, 3.0)])
    assert estimate_sigma(stack) == pytest.approx(math.sqrt((1 + 4 + 9) / 3), rel=0.04)


def test_weighted_average_of_accumulated_patches_is_exact_for_a_constant_step():
    x = torch.arange(11 * 13, dtype=torch.float64).reshape(11, 13)
    total, count = accumulate_patches(extract_patches(x, (3, 5), (2, 4)), x.shape, (3, 5), (2, 4))
    torch.testing.assert_close(total / count, x)
    lam = 0.7
    torch.testing.assert_close((lam * x + total) / (lam + count), x)


@pytest.mark.parametrize(
    "call, field",
    [
        (lambda: ksvd_denoise(np.zeros((6, 6))), "block_size"),
        (lambda: ksvd_denoise(np.zeros((16, 16)), block_size=20), "block_size"),
        (lambda: ksvd_denoise(np.zeros((16, 16)), 0.0), "sigma"),
        (lambda: ksvd_denoise(np.zeros((16, 16)), -1.0), "sigma"),
        (lambda: ksvd_denoise(np.zeros(16)), "image_or_volume"),
        (lambda: ksvd_denoise(np.zeros((2, 2, 16, 16))), "image_or_volume"),
        (lambda: ksvd_denoise(np.full((16, 16), np.nan)), "image_or_volume"),
        (lambda: ksvd_denoise(np.zeros((16, 16)), 1.0, block_size=(8, 8, 8)), "block_size"),
        (lambda: ksvd_denoise(np.zeros((16, 16)), 1.0, gain=0), "gain"),
        (lambda: sparse_ksvd(torch.zeros(3, 5), KroneckerOperator([torch.eye(5)]), atom_sparsity=1, tol=1.0), "n_atoms"),
        (lambda: sparse_ksvd(torch.zeros(10, 4), KroneckerOperator([torch.eye(5)]), atom_sparsity=1, tol=1.0), "X"),
        (lambda: sparse_ksvd(torch.zeros(10, 5), KroneckerOperator([torch.eye(5)]), n_atoms=3, atom_sparsity=9, tol=1.0), "atom_sparsity"),
    ],
)
def test_errors_name_the_field(call, field):
    with pytest.raises(ValueError, match=field):
        call()
