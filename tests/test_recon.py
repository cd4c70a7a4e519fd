"""The reconstruction registry: solver and denoiser objects, their checks, and plugging in your own."""

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_module

from cssat.experiments import run_experiment
from cssat.recon import L1, OMP, TV, NLMDenoiser, NoDenoiser, PnP, SparseKSVD, TVDenoiser, WaveletDenoiser
from cssat.sparse import DCT, DictionarySensing, GaussianSensing, batch_omp, sensing_dictionary

SMALL = ["target.size=16", "cs.m=200", "threads=1"]


def cfg_of(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def problem(m=150, n=16, seed=4):
    phi = GaussianSensing(m, n * n, seed=seed, dtype=torch.float64)
    g = torch.Generator().manual_seed(seed)
    coef = torch.zeros(n * n, dtype=torch.float64)
    coef[torch.randperm(n * n, generator=g)[:12]] = torch.randn(12, generator=g, dtype=torch.float64)
    x = DCT((n, n))(coef).reshape(n, n)
    return phi, x, phi(x.reshape(-1))


def test_omp_object_is_batch_omp_over_phi_psi():
    phi, x, y = problem()
    img, info = OMP(n_nonzero_coefs=30)(phi, y, (16, 16))
    gamma = batch_omp(sensing_dictionary(phi, (16, 16)), y, n_nonzero_coefs=30)
    torch.testing.assert_close(img, DCT((16, 16))(gamma).reshape(16, 16), rtol=0, atol=0)
    torch.testing.assert_close(img, x, rtol=0, atol=1e-9)  # a 12-sparse image from 150 samples: exact
    assert info["solver_n_nonzero_coefs"] == 30 and info["coefficients"].shape == (256,)
    # a sensing operator held as its dictionary ΦΨ gives the same reconstruction
    img2, _ = OMP(n_nonzero_coefs=30)(DictionarySensing(sensing_dictionary(phi, (16, 16)), (16, 16)), y, (16, 16))
    torch.testing.assert_close(img2, img, rtol=0, atol=0)


def test_dictionary_sensing_is_phi():
    phi, x, y = problem()
    op = DictionarySensing(sensing_dictionary(phi, (16, 16)), (16, 16))
    torch.testing.assert_close(op.matrix(), phi.matrix(), rtol=0, atol=1e-12)
    torch.testing.assert_close(op(x.reshape(-1)), y, rtol=0, atol=1e-12)
    v = torch.randn(150, dtype=torch.float64)
    torch.testing.assert_close(op.adjoint(v), phi.adjoint(v), rtol=0, atol=1e-12)


def test_omp_settings_follow_eq_5_and_6():
    assert OMP().settings(1444, 16384) == (75, None) and OMP().settings(13225, 16384) == (2815, None)
    assert OMP(k_ratio=0.1).settings(200, 256) == (20, None)
    assert OMP(epsilon=0.5).settings(200, 256) == (200, 0.25)  # tol is ε², K capped at m
    with pytest.raises(ValueError, match="^n_nonzero_coefs"):
        OMP(n_nonzero_coefs=300).validate(200, 256)
    with pytest.raises(ValueError, match="^k_ratio"):
        OMP(k_ratio=2)


def test_convex_solvers_fit_a_sparse_image():
    phi, x, y = problem()
    box = torch.zeros(16, 16, dtype=torch.float64)
    box[4:11, 5:13] = 1.0  # piecewise constant: TV's prior
    for solver, truth, err in ((L1(lam=1e-5, max_iter=3000, rtol=1e-9), x, 0.05),
                               (TV(lam=1e-4, max_iter=3000, rtol=1e-9), box, 0.2)):
        img, info = solver(phi, phi(truth.reshape(-1)), (16, 16))
        assert img.shape == (16, 16) and info["solver_iterations"] >= 1
        assert float((img - truth).norm() / truth.norm()) < err, solver
    with pytest.raises(ValueError, match="^rtol"):
        L1(rtol=-1)
    with pytest.raises(ValueError, match="^nonneg"):
        TV(nonneg="yes")


def test_pnp_calls_its_denoiser_on_the_sigma_schedule():
    calls = []

    class Spy:
        name = "spy"

        def __call__(self, image, sigma=None):
            calls.append(float(sigma))
            return image, {}

    phi, x, y = problem()
    img, info = PnP(Spy(), max_iter=5, sigma_start=0.1, sigma_end=0.001)(phi, y, (16, 16))
    np.testing.assert_allclose(calls, np.geomspace(0.1, 0.001, 5), rtol=1e-12)
    assert info["solver_denoiser"] == "spy" and img.shape == (16, 16)
    with pytest.raises(ValueError, match="^init"):
        PnP(Spy(), init="random")


def test_skimage_denoisers_equal_scikit_image():
    from skimage.restoration import denoise_nl_means, denoise_tv_chambolle

    rng = np.random.default_rng(0)
    img = np.clip(np.outer(np.hanning(32), np.hanning(32)) + 0.1 * rng.standard_normal((32, 32)), 0, 1)
    out, info = TVDenoiser(weight=0.07)(img)
    np.testing.assert_array_equal(out, denoise_tv_chambolle(img, weight=0.07))
    out, info = NLMDenoiser(sigma=0.1)(img)
    np.testing.assert_array_equal(out, denoise_nl_means(img, h=0.08, sigma=0.1, fast_mode=True, patch_size=5, patch_distance=6))
    assert info["denoise_sigma"] == 0.1
    t, _ = TVDenoiser(weight=0.07)(torch.as_tensor(img, dtype=torch.float32))  # tensors in, tensors out
    assert t.dtype == torch.float32 and torch.allclose(t.double(), torch.as_tensor(denoise_tv_chambolle(img, weight=0.07)), atol=1e-6)
    assert np.array_equal(NoDenoiser()(img)[0], img)
    with pytest.raises(ValueError, match="^sigma"):
        WaveletDenoiser(sigma=-1)


def test_sparse_ksvd_object_denoises_and_checks_settings():
    rng = np.random.default_rng(1)
    clean = np.outer(np.hanning(32), np.hanning(32))
    noisy = clean + 0.05 * rng.standard_normal(clean.shape)
    out, info = SparseKSVD(n_iter=3, seed=0)(noisy)
    assert np.mean((out - clean) ** 2) < 0.5 * np.mean((noisy - clean) ** 2)
    assert info["denoise_sigma_estimated"] and info["denoise_sigma"] == pytest.approx(0.05, rel=0.25)
    with pytest.raises(ValueError, match="^n_iter"):
        SparseKSVD(n_iter=0)
    with pytest.raises(ValueError, match="^dtype"):
        SparseKSVD(dtype="float16")


# --- plugging in your own: classes defined here, named by _target_ -----------------------------

class MeanSolver:
    """Every pixel the mean flux per pixel of a non-negative Φ ... here simply Φᵀy, rescaled."""

    name = "mine"

    def __init__(self, scale: float = 1.0):
        self.scale = scale

    def __call__(self, problem, y):
        x = problem.operator.adjoint(y) * self.scale
        return x.reshape(*problem.x_shape), {"solver_scale": self.scale}


class HalfDenoiser:
    name = "half"

    def __call__(self, image, sigma=None):
        return image * 0.5, {"denoise_factor": 0.5}


def test_a_solver_and_a_denoiser_of_your_own(tmp_path):
    # the README's recipe: a YAML per class in a config directory of your own, on Hydra's search path
    (tmp_path / "conf" / "solver").mkdir(parents=True)
    (tmp_path / "conf" / "denoiser").mkdir()
    (tmp_path / "conf" / "solver" / "mine.yaml").write_text(f"_target_: {__name__}.MeanSolver\nscale: 2.0\n")
    (tmp_path / "conf" / "denoiser" / "half.yaml").write_text(f"_target_: {__name__}.HalfDenoiser\n")
    cfg = cfg_of(*SMALL, f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "solver=mine", "denoiser=half")
    met = run_experiment(cfg, tmp_path / "run")
    arrays = np.load(tmp_path / "run" / "arrays.npz")
    phi = GaussianSensing(200, 256, seed=0, dtype=torch.float32)
    expected = (phi.adjoint(torch.as_tensor(arrays["y"])) * 2.0).reshape(16, 16).clamp(0, 1).double().numpy()
    np.testing.assert_allclose(arrays["reconstruction"], expected, rtol=0, atol=1e-6)
    np.testing.assert_allclose(arrays["denoised"], expected * 0.5, rtol=0, atol=1e-6)
    assert met["solver"] == "mine" and met["solver_scale"] == 2.0
    assert met["denoiser"] == "half" and met["denoise_factor"] == 0.5
    # a class whose call does not fit is refused before any work, naming the group
    (tmp_path / "conf" / "solver" / "broken.yaml").write_text(f"_target_: {__name__}.MeanSolver\nshift: 1\n")
    with pytest.raises(ValueError, match="^solver:.*shift"):
        run_experiment(cfg_of(*SMALL, f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "solver=broken"), tmp_path / "bad")
    assert not (tmp_path / "bad" / "arrays.npz").exists()
