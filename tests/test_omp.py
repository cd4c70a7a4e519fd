import numpy as np
import pytest
import torch
from sklearn.linear_model import orthogonal_mp, orthogonal_mp_gram

from cssat.sparse import batch_omp


def problem(m=50, n=90, B=40, seed=0, scale=True):
    rng = np.random.default_rng(seed)
    D = rng.standard_normal((m, n))
    if scale:  # atoms deliberately not normalised
        D *= rng.uniform(0.3, 3.0, n)
    Y = rng.standard_normal((B, m))
    return D, Y


try:
    import numba  # noqa: F401

    KERNEL_KWARGS = [{"precompute": True, "backend": "torch"}, {"precompute": True, "backend": "numba"},
                     {"precompute": False}]
except ImportError:
    KERNEL_KWARGS = [{"precompute": True, "backend": "torch"}, {"precompute": False}]


def support(c):
    return c != 0


KERNELS = [
    pytest.param({"precompute": True, "backend": "torch"}, id="gram-torch"),
    pytest.param({"precompute": True, "backend": "numba"}, id="gram-numba"),
    pytest.param({"precompute": False}, id="nogram"),
]


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("mode", [{"n_nonzero_coefs": 12}, {"tol": 8.0}, {"tol": 2.0, "n_nonzero_coefs": 20}])
def test_matches_sklearn_orthogonal_mp(kernel, mode):
    if kernel.get("backend") == "numba":
        pytest.importorskip("numba")
    D, Y = problem()
    got = batch_omp(torch.tensor(D), torch.tensor(Y), **kernel, **mode).numpy()
    if "tol" in mode and "n_nonzero_coefs" in mode:
        # scikit-learn has no capped error mode: it is the error mode truncated at the cap
        ref_full = orthogonal_mp(D, Y.T, tol=mode["tol"]).T
        ref = np.where((ref_full != 0).sum(1, keepdims=True) <= 20, ref_full, orthogonal_mp(D, Y.T, n_nonzero_coefs=20).T)
    else:
        ref = orthogonal_mp(D, Y.T, **mode).T
    assert np.array_equal(support(got), support(ref))
    np.testing.assert_allclose(got, ref, atol=1e-8, rtol=0)


@pytest.mark.parametrize("mode", [{"n_nonzero_coefs": 15}, {"tol": 5.0}])
@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_matches_sklearn_orthogonal_mp_gram_with_precomputed_inputs(mode, backend):
    if backend == "numba":
        pytest.importorskip("numba")
    D, Y = problem(m=64, n=128, B=30, seed=1)
    G, DtY = D.T @ D, Y @ D
    kw = dict(mode)
    if "tol" in kw:
        kw["norms_squared"] = (Y**2).sum(1)
    ref = orthogonal_mp_gram(G, DtY.T, **kw).T
    got = batch_omp(torch.tensor(D), torch.tensor(Y), gram=torch.tensor(G), Dty=torch.tensor(DtY), backend=backend,
                    **mode).numpy()
    assert np.array_equal(support(got), support(ref))
    np.testing.assert_allclose(got, ref, atol=1e-8, rtol=0)


def test_residual_info_is_the_true_residual_and_meets_tol():
    D, Y = problem(seed=2)
    tol = 4.0
    for kern in KERNEL_KWARGS:
        c, info = batch_omp(torch.tensor(D), torch.tensor(Y), tol=tol, **kern, return_info=True)
        res = ((torch.tensor(Y) - c @ torch.tensor(D).T) ** 2).sum(1)
        torch.testing.assert_close(info.residual_sq, res, atol=1e-9, rtol=1e-9)
        assert bool((res <= tol + 1e-9).all())
        assert torch.equal(info.n_iter, (c != 0).sum(1))
        assert info.path == ("gram" if kern.get("precompute") else "nogram")


@pytest.mark.parametrize("dtype,tol", [(torch.float64, 1e-10), (torch.float32, 1e-4)])
def test_exact_recovery_of_sparse_signals_from_gaussian_measurements(dtype, tol):
    g = torch.Generator().manual_seed(5)
    m, n, k, B = 128, 256, 8, 64  # m ≈ 2 k ln(n): OMP recovers all with high probability
    D = torch.randn(m, n, generator=g, dtype=dtype) / m**0.5
    X = torch.zeros(B, n, dtype=dtype)
    for b in range(B):
        idx = torch.randperm(n, generator=g)[:k]
        X[b, idx] = torch.randn(k, generator=g, dtype=dtype).sign() * (1 + torch.rand(k, generator=g, dtype=dtype))
    Y = X @ D.T
    for kern in KERNEL_KWARGS:
        got = batch_omp(D, Y, n_nonzero_coefs=k, **kern)
        assert torch.equal(got != 0, X != 0)
        assert float((got - X).abs().max()) < tol
        # error-constrained with a tiny tolerance finds the same codes
        got_e = batch_omp(D, Y, tol=1e-12 if dtype == torch.float64 else 1e-6, **kern)
        assert torch.equal(got_e != 0, X != 0)


def test_batched_equals_one_signal_at_a_time_and_chunking_is_invisible():
    D, Y = problem(B=17, seed=3)
    Dt, Yt = torch.tensor(D), torch.tensor(Y)
    for path in (True, False):
        kw = {"precompute": path, "backend": "torch"}
        full = batch_omp(Dt, Yt, tol=3.0, chunk_size=5, **kw)
        for b in range(17):
            one = batch_omp(Dt, Yt[b], tol=3.0, **kw)
            assert one.shape == (90,)
            torch.testing.assert_close(full[b], one, atol=1e-12, rtol=0)
        torch.testing.assert_close(full, batch_omp(Dt, Yt, tol=3.0, chunk_size=64, **kw), atol=1e-12, rtol=0)


def test_gram_and_nogram_paths_agree_in_float32():
    D, Y = problem(m=100, n=200, B=50, seed=4)
    Dt, Yt = torch.tensor(D, dtype=torch.float32), torch.tensor(Y, dtype=torch.float32)
    a = batch_omp(Dt, Yt, n_nonzero_coefs=20, precompute=True)
    b = batch_omp(Dt, Yt, n_nonzero_coefs=20, precompute=False)
    assert a.dtype == torch.float32
    same = (a != 0).eq(b != 0).all(1)
    assert float(same.double().mean()) >= 0.95  # near-ties may flip in float32
    torch.testing.assert_close(a[same], b[same], atol=1e-3, rtol=1e-3)


def test_zero_signal_gives_zero_code():
    D, Y = problem(B=4)
    Y[1] = 0
    for kern in KERNEL_KWARGS:
        for kw in ({"n_nonzero_coefs": 5}, {"tol": 0.0}):
            c, info = batch_omp(torch.tensor(D), torch.tensor(Y), **kern, return_info=True, **kw)
            assert torch.count_nonzero(c[1]) == 0 and int(info.n_iter[1]) == 0
            assert torch.isfinite(c).all()


def test_linearly_dependent_atoms_stop_cleanly():
    rng = np.random.default_rng(6)
    base = rng.standard_normal((20, 6))
    D = np.concatenate([base, base[:, :3] * 2.0, base @ rng.standard_normal((6, 5))], axis=1)  # rank 6
    Y = rng.standard_normal((10, 20))
    for kern in KERNEL_KWARGS:
        c, info = batch_omp(torch.tensor(D), torch.tensor(Y), n_nonzero_coefs=12, **kern, return_info=True)
        assert torch.isfinite(c).all()
        assert int(info.n_iter.max()) <= 6
        # the fit is the least-squares projection onto the 6-dimensional span
        proj = base @ np.linalg.lstsq(base, Y.T, rcond=None)[0]
        np.testing.assert_allclose((c.numpy() @ D.T), proj.T, atol=1e-8)


def test_exact_fit_stops_with_tol_zero_and_more_atoms_than_needed():
    rng = np.random.default_rng(7)
    D = rng.standard_normal((30, 60))
    x = np.zeros(60)
    x[[3, 17, 40]] = [1.0, -2.0, 0.5]
    y = D @ x
    for kern in KERNEL_KWARGS:
        c, info = batch_omp(torch.tensor(D), torch.tensor(y), tol=0.0, **kern, return_info=True)
        assert torch.isfinite(c).all()
        np.testing.assert_allclose(c.numpy(), x, atol=1e-10)
        # a square, full-rank system: m atoms fit any signal exactly, then the search stops
        D2 = rng.standard_normal((10, 10))
        y2 = rng.standard_normal(10)
        c2, info2 = batch_omp(torch.tensor(D2), torch.tensor(y2), n_nonzero_coefs=10, **kern, return_info=True)
        assert torch.isfinite(c2).all()
        np.testing.assert_allclose(D2 @ c2.numpy(), y2, atol=1e-10)
        assert float(info2.residual_sq) < 1e-10 * (y2 @ y2)


def test_sklearn_default_sparsity_when_nothing_given():
    D, Y = problem(m=40, n=100, B=3)
    c = batch_omp(torch.tensor(D), torch.tensor(Y))
    assert int((c != 0).sum(1).max()) == 10


def test_bad_arguments_are_refused_with_their_name():
    D, Y = problem(B=2)
    Dt, Yt = torch.tensor(D), torch.tensor(Y)
    with pytest.raises(ValueError, match="n_nonzero_coefs"):
        batch_omp(Dt, Yt, n_nonzero_coefs=0)
    with pytest.raises(ValueError, match="n_nonzero_coefs"):
        batch_omp(Dt, Yt, n_nonzero_coefs=91)
    with pytest.raises(ValueError, match="tol"):
        batch_omp(Dt, Yt, tol=-1.0)
    with pytest.raises(ValueError, match="Y: expected shape"):
        batch_omp(Dt, Yt[:, :10])
    bad = Yt.clone()
    bad[0, 3] = float("nan")
    with pytest.raises(ValueError, match="Y: .*NaN"):
        batch_omp(Dt, bad, n_nonzero_coefs=3)
    bad[0, 3] = float("inf")
    with pytest.raises(ValueError, match="Y: .*NaN or Inf"):
        batch_omp(Dt, bad, n_nonzero_coefs=3)
    with pytest.raises(ValueError, match="D:"):
        batch_omp(Dt[0], Yt)
    with pytest.raises(ValueError, match="precompute"):
        batch_omp(Dt, Yt, precompute="yes")
    with pytest.raises(ValueError, match="gram"):
        batch_omp(Dt, Yt, gram=torch.eye(5, dtype=Dt.dtype))




@pytest.mark.parametrize("threads", [1, 2])
def test_a_lone_signal_split_among_threads_matches_scikit_learn(threads, monkeypatch):
    """One signal with 2 threads takes the kernel whose correlation updates are split among the
    threads (chunks of 2048 atoms, so n = 5000 makes uneven chunks); the code must be
    scikit-learn's and the same, bit for bit, as the one-thread run and as that signal in a batch."""
    pytest.importorskip("numba")
    import cssat.sparse.omp as omp_mod

    monkeypatch.setattr(omp_mod, "_CAP0", 8)  # the work buffers grow several times up to K
    D, Y = problem(m=300, n=5000, B=3, seed=3)
    Dt, Yt = torch.tensor(D), torch.tensor(Y)
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        lone = batch_omp(Dt, Yt[1], n_nonzero_coefs=120, backend="numba")
    finally:
        torch.set_num_threads(old)
    in_batch = batch_omp(Dt, Yt, n_nonzero_coefs=120, backend="numba")[1]
    assert torch.equal(lone, in_batch)
    ref = orthogonal_mp(D, Y[1], n_nonzero_coefs=120)
    np.testing.assert_allclose(lone.numpy(), ref, atol=1e-8)


@pytest.mark.filterwarnings("ignore:Orthogonal matching pursuit ended prematurely")  # the zero signal
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("mode", [{"n_nonzero_coefs": 25}, {"tol": 3.0}, {"tol": 3.0, "n_nonzero_coefs": 10}])
def test_numba_and_torch_kernels_agree(dtype, mode, monkeypatch):
    pytest.importorskip("numba")
    import cssat.sparse.omp as omp_mod

    monkeypatch.setattr(omp_mod, "_CAP0", 4)  # exercise the growth of the work buffers
    D, Y = problem(m=60, n=150, B=33, seed=8)
    Dt, Yt = torch.tensor(D, dtype=dtype), torch.tensor(Y, dtype=dtype)
    Y0 = Yt.clone()
    Y0[5] = 0
    a, ia = batch_omp(Dt, Y0, backend="numba", return_info=True, **mode)
    b, ib = batch_omp(Dt, Y0, backend="torch", precompute=True, return_info=True, **mode)
    assert ia.path == ib.path == "gram"
    same = ((a != 0) == (b != 0)).all(1)
    if dtype == torch.float64:
        assert bool(same.all())
        torch.testing.assert_close(a, b, atol=1e-10, rtol=0)
        torch.testing.assert_close(ia.residual_sq, ib.residual_sq, atol=1e-9, rtol=1e-9)
        ref = orthogonal_mp(D, Y0.numpy().T, **mode).T if len(mode) == 1 else None
        if ref is not None:
            np.testing.assert_allclose(a.numpy(), ref, atol=1e-8)
    else:
        assert float(same.double().mean()) >= 0.9
        torch.testing.assert_close(a[same], b[same], atol=1e-3, rtol=1e-3)
    assert torch.equal(ia.n_iter[same], ib.n_iter[same])
    assert int(ia.n_iter[5]) == 0 and torch.count_nonzero(a[5]) == 0


def test_numba_backend_errors():
    D, Y = problem(B=2)
    with pytest.raises(ValueError, match="backend"):
        batch_omp(torch.tensor(D), torch.tensor(Y), backend="fortran")
    with pytest.raises(ValueError, match="backend: 'numba' runs the Gram path"):
        batch_omp(torch.tensor(D), torch.tensor(Y), backend="numba", precompute=False)


def test_blocked_gram_equals_dense_product():
    from cssat.sparse import gram_matrix

    D = torch.randn(37, 1300, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    G = gram_matrix(D, block=300)
    torch.testing.assert_close(G, D.T @ D, atol=1e-12, rtol=0)
    assert torch.equal(G, G.T)


def test_threaded_matrix_vector_product_matches_float64():
    from cssat.sparse._omp_torch import correlate as _correlate

    g = torch.Generator().manual_seed(1)
    Dt = torch.randn(2100, 2048, generator=g)  # large enough for the threaded split
    r = torch.randn(1, 2048, generator=g)
    torch.set_num_threads(2)
    try:
        got = _correlate(Dt, r)
    finally:
        torch.set_num_threads(1)
    ref = (Dt.double() @ r[0].double()).float()
    torch.testing.assert_close(got[0], ref, rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("threads", [1, 2])
def test_the_sparse_gram_is_numpys_dense_product(threads):
    """The sparse Gram kernel (rows' outer products over their non-zeros) against numpy's DᵀD,
    with empty rows, an empty column and rows of one entry; exactly symmetric; the dense
    branch gives the same to round-off; a bad `sparse` value is named."""
    pytest.importorskip("numba")
    from cssat.sparse import gram_matrix

    rng = np.random.default_rng(4)
    D = rng.standard_normal((70, 300)) * (rng.random((70, 300)) < 0.04)
    D[3] = 0
    D[:, 17] = 0
    D[9] = 0
    D[9, 5] = 2.5
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        G = gram_matrix(torch.tensor(D), sparse=True)
    finally:
        torch.set_num_threads(old)
    np.testing.assert_allclose(G.numpy(), D.T @ D, rtol=1e-12, atol=1e-12)
    assert torch.equal(G, G.T)
    torch.testing.assert_close(gram_matrix(torch.tensor(D), sparse=False), G, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="sparse: expected 'auto', True or False"):
        gram_matrix(torch.tensor(D), sparse="yes")
