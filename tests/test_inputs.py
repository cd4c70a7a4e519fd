"""What users hold goes in (issue 13, point 7): numpy arrays, integer tensors, trimesh meshes;
what cannot work is refused clearly (float16 in OMP, NaN in a dictionary)."""

import numpy as np
import pytest
import torch

from cssat.sparse import DCT, GaussianSensing, KroneckerOperator, batch_omp, ksvd_denoise


def test_integer_inputs_are_promoted_not_truncated():
    x = torch.arange(64)
    torch.testing.assert_close(DCT((8, 8))(x), DCT((8, 8))(x.to(torch.float32)))
    assert float(DCT((8, 8)).adjoint(x).abs().sum()) > 0  # no silent zeros
    phi = GaussianSensing(5, 16, seed=1)
    torch.testing.assert_close(phi(torch.ones(16, dtype=torch.uint8)), phi(torch.ones(16)))
    k = KroneckerOperator([torch.eye(3), torch.ones(2, 2)])
    torch.testing.assert_close(k(torch.arange(6)), k(torch.arange(6.0)))


def test_numpy_in_numpy_out():
    rng = np.random.default_rng(0)
    x = rng.random(64)
    out = DCT((8, 8))(x)
    assert isinstance(out, np.ndarray)
    from scipy.fft import idctn

    np.testing.assert_allclose(out, idctn(x.reshape(8, 8), norm="ortho").ravel(), atol=1e-12)
    D = rng.standard_normal((30, 60))
    y = D[:, [3, 17, 40]] @ np.array([1.0, -2.0, 0.5])
    g = batch_omp(D, y, n_nonzero_coefs=3)
    assert isinstance(g, np.ndarray) and set(np.flatnonzero(g)) == {3, 17, 40}


def test_omp_refuses_float16_and_nan_on_every_path():
    D = torch.randn(20, 40, dtype=torch.float64)
    y = D[:, :2].sum(1)
    with pytest.raises(TypeError, match="float16"):
        batch_omp(D.half(), y.half(), n_nonzero_coefs=2)
    bad = D.clone()
    bad[3, 5] = float("nan")
    for kw in ({"precompute": True, "backend": "torch"}, {"precompute": False}, {"backend": "auto"}):
        with pytest.raises(ValueError, match="^D: .*NaN"):
            batch_omp(bad, y, n_nonzero_coefs=2, **kw)


def test_ksvd_on_a_stack_of_one_image_is_its_2d_denoising():
    img = np.random.default_rng(2).random((16, 16))
    one = ksvd_denoise(img[None], 0.1, n_iter=2, seed=0)
    assert one.shape == (1, 16, 16)
    np.testing.assert_array_equal(one[0], ksvd_denoise(img, 0.1, n_iter=2, seed=0))


def test_optics_accept_a_trimesh():
    import trimesh

    from cssat.optics import facet_brightness, render
    from cssat.scene import Mesh, as_mesh, astra_like

    ours = astra_like()
    tm = ours.to_trimesh()
    tm.face_attributes["cd"] = ours.cd
    tm.face_attributes["cs"] = ours.cs
    sun = obs = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    torch.testing.assert_close(facet_brightness(tm, sun, obs), facet_brightness(ours, sun, obs))
    torch.testing.assert_close(render(tm, sun, obs, 16), render(ours, sun, obs, 16))
    box = trimesh.creation.box((1, 2, 3))
    m = Mesh.from_trimesh(box, cd=0.5)
    assert len(m) == 12 and np.allclose(m.cd, 0.5) and m.areas.sum() == pytest.approx(2 * (2 + 3 + 6))
    with pytest.raises(TypeError, match="^mesh"):
        as_mesh("satellite.obj")


def test_numpy_through_the_solvers_the_estimators_and_the_measurement():
    from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement
    from cssat.recon import OMP
    from cssat.reference import estimate_sensing_full_rank
    from cssat.sparse.solvers import fista_l1, tv_pdhg

    rng = np.random.default_rng(3)
    A = rng.standard_normal((40, 64)) / 8
    y = A @ rng.standard_normal(64)
    g = fista_l1(A, y, lam=1e-3, max_iter=50)
    assert isinstance(g, np.ndarray) and g.shape == (64,)
    np.testing.assert_allclose(g, fista_l1(torch.as_tensor(A), torch.as_tensor(y), lam=1e-3, max_iter=50).numpy())
    x, info = tv_pdhg(A, y, (8, 8), max_iter=20, return_info=True)
    assert isinstance(x, np.ndarray) and x.shape == (8, 8) and info.n_iter == 20
    X = rng.standard_normal((16, 16))
    phi = rng.standard_normal((5, 16))
    np.testing.assert_allclose(estimate_sensing_full_rank(X, phi @ X), phi, atol=1e-9)
    img, info = OMP(n_nonzero_coefs=5)(A, y, (8, 8))
    assert isinstance(img, np.ndarray) and img.shape == (8, 8)
    meas = Measurement(GaussianAtmosphere().operator(30, 64, seed=0, dtype=torch.float64), GaussianNoise(relative=0.1))
    out = meas(rng.random((8, 8)))
    assert isinstance(out, np.ndarray) and out.shape == (30,)
