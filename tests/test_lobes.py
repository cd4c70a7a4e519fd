"""An EGI per scattering lobe (issue 36, point 3): cssat.inversion.egi.Lobes against a
brute-force sum written here, scipy's NNLS, and a glinting body the Lambert EGI cannot fit."""

import math

import numpy as np
import pytest

from cssat._checks import FieldError
from cssat.inversion import invert_convex
from cssat.inversion.egi import Lobes, egi_operator, fibonacci_sphere, geometry_matrix, split_lobes


def _unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _geometry(T, seed):
    rng = np.random.default_rng(seed)
    return _unit(rng.normal(size=(T, 3))), _unit(rng.normal(size=(T, 3)))


def _brute(S, O, N, shininess, floor=0.1):
    """G[t, l·K + k] by loops: μ₀μ/π for the diffuse lobe, μ₀μ (n+8)/(8π) (n̂·ĥ)ⁿ for each lobe,
    0 where (n̂·ĥ)ⁿ < floor."""
    T, K = len(S), len(N)
    G = np.zeros((T, (1 + len(shininess)) * K))
    for t in range(T):
        h = S[t] + O[t]
        h = h / np.linalg.norm(h)
        for k in range(K):
            mu0, mu = max(S[t] @ N[k], 0.0), max(O[t] @ N[k], 0.0)
            G[t, k] = mu0 * mu / math.pi
            for j, n in enumerate(shininess):
                lobe = max(h @ N[k], 0.0) ** n
                G[t, (j + 1) * K + k] = mu0 * mu * (n + 8) / (8 * math.pi) * (lobe if lobe >= floor else 0.0)
    return G


def test_lobe_matrix_against_a_brute_force_sum():
    S, O = _geometry(40, 0)
    N = fibonacci_sphere(30).numpy()
    for floor in (0.1, 0.0):
        lob = Lobes([20, 150], floor=floor)
        ref = _brute(S, O, N, [20, 150], floor)
        assert (ref[:, 30:] > 0).sum() > 20  # the lobes are seen
        np.testing.assert_allclose(geometry_matrix(S, O, N, lob), ref, rtol=1e-12, atol=1e-15)
        op = egi_operator(S, O, N, lob)  # the torch path: the BRDF classes (Lambert(1), BlinnPhong(0, 1, n))
        np.testing.assert_allclose(op.matrix().numpy(), ref, rtol=1e-9, atol=1e-15)
    assert op.n_lobes == 3 and tuple(op.normals.shape) == (90, 3)
    # the closure sees every (lobe, normal) column; the TV joins neighbours within a lobe only
    np.testing.assert_allclose(op.equalities(), np.tile(N.T, 3))
    D = op.differences(4).tocoo()
    assert D.shape[1] == 90 and np.all(D.row.size > 0)
    lobe_of = np.asarray(D.col) // 30
    for r in np.unique(D.row):
        assert len(set(lobe_of[D.row == r])) == 1


def test_a_glinting_body_is_fitted_to_the_noise_and_its_lobes_split():
    """Normals on the inversion's own grid (an inverse crime on purpose: this checks the solve, not
    the grid): diffuse areas on 12 normals, a shininess-100 lobe on 4 of them (glints 10-50x the
    diffuse flux). The lobe EGI fits to the noise with the true split; the Lambert EGI cannot."""
    rng = np.random.default_rng(3)
    K = 300
    N = fibonacci_sphere(K).numpy()
    S, O = _geometry(1500, 1)
    idx = rng.choice(K, 12, replace=False)
    a = np.zeros(2 * K)
    a[idx] = rng.uniform(0.5, 2.0, 12)
    a[K + idx[:4]] = rng.uniform(0.2, 0.6, 4)
    clean = _brute(S, O, N, [100]) @ a
    sigma = 0.01 * clean.mean() + 0.0 * clean
    y = clean + sigma * rng.normal(size=clean.shape)
    lob = invert_convex(y, S, O, brdf=Lobes([100]), n_normals=K, sigma=sigma, closure=0.0)
    lam = invert_convex(y, S, O, brdf="lambert", n_normals=K, sigma=sigma, closure=0.0, refine=False)
    chi2 = lambda r: float(np.mean((r / sigma) ** 2))  # noqa: E731
    assert chi2(lob.residual) < 1.2
    assert chi2(lam.residual) > 10 * chi2(lob.residual)
    # the same fit as scipy's NNLS on the brute-force matrix (weights 1/σ)
    from scipy.optimize import nnls

    x, rnorm = nnls(_brute(S, O, N, [100]) / sigma[:, None], y / sigma, maxiter=100 * K)
    assert chi2(lob.residual) * len(y) == pytest.approx(rnorm ** 2, rel=1e-6)
    # each lobe's total area comes back (diffuse within 3 %; the specular one, seen only near glints, within 15 %)
    assert lob.lobe_areas.shape == (2, len(lob.areas))
    assert lob.lobe_areas[0].sum() == pytest.approx(a[:K].sum(), rel=0.03)
    assert lob.lobe_areas[1].sum() == pytest.approx(a[K:].sum(), rel=0.15)
    np.testing.assert_allclose(lob.areas, lob.lobe_areas.sum(0))
    assert lob.lobe_areas.max() < 10 * a.max()  # no unseen glint explains a residual with a huge area
    # predict() is the fit on the samples it fitted
    np.testing.assert_allclose(y - lob.predict(S, O), lob.residual, rtol=1e-9, atol=1e-12 * clean.max())


def test_split_lobes_keeps_normals_with_area_in_any_lobe():
    N = fibonacci_sphere(5).numpy()
    a = np.array([1.0, 0, 0, 2.0, 0, 0, 3.0, 0, 0, 0])  # diffuse on 0 and 3, specular on 1
    normals, areas, lobes, keep = split_lobes(a, N, Lobes([50]))
    np.testing.assert_array_equal(keep, [True, True, False, True, False])
    np.testing.assert_allclose(areas, [1.0, 3.0, 2.0])
    np.testing.assert_allclose(lobes, [[1.0, 0.0, 2.0], [0.0, 3.0, 0.0]])
    assert split_lobes(a[:5], N, None)[2] is None


@pytest.mark.parametrize("bad", [[], [0.5], ["x"], [float("nan")], [1e6]])
def test_bad_lobes_name_the_field(bad):
    with pytest.raises(FieldError, match="shininess"):
        Lobes(bad)
    with pytest.raises(FieldError, match="floor"):
        Lobes([100], floor=1.0)


def test_the_atoms_refinement_is_refused_for_lobes():
    S, O = _geometry(50, 2)
    with pytest.raises(FieldError, match="refine"):
        invert_convex(np.ones(50), S, O, brdf="lobes", n_normals=50, refine=True)
