"""The GPU path (``device=cuda``): the same results as the CPU path, on the device. These tests
run where CUDA is present (``pytest -m cuda``) and are skipped elsewhere, CI included."""

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_module

pytestmark = pytest.mark.cuda


def test_operators_and_measurement_follow_the_device():
    from cssat.physics import GaussianNoise, Measurement
    from cssat.sparse import DCT, GaussianSensing, sensing_dictionary

    cpu = GaussianSensing(300, 1024, seed=3, dtype=torch.float64)
    gpu = GaussianSensing(300, 1024, seed=3, dtype=torch.float64, device="cuda")
    assert gpu.weight.device.type == "cuda"
    torch.testing.assert_close(gpu.weight.cpu(), cpu.weight, rtol=0, atol=0)  # the same draws
    x = torch.rand(4, 32, 32, dtype=torch.float64)
    torch.testing.assert_close(gpu(x.cuda()).cpu(), cpu(x))
    torch.testing.assert_close(sensing_dictionary(gpu, (32, 32)).cpu(), sensing_dictionary(cpu, (32, 32)))
    torch.testing.assert_close(DCT((32, 32)).adjoint(x.cuda()).cpu(), DCT((32, 32)).adjoint(x))
    y = Measurement(gpu, GaussianNoise(relative=0.01), seed=1)(x.cuda())
    assert y.device.type == "cuda" and y.shape == (4, 300)


@pytest.mark.parametrize("precompute", [True, False])
def test_batch_omp_on_the_gpu_equals_the_cpu_kernels(precompute):
    from cssat.sparse import batch_omp

    g = torch.Generator().manual_seed(0)
    D = torch.randn(128, 256, generator=g, dtype=torch.float64)
    Y = torch.randn(500, 128, generator=g, dtype=torch.float64)
    ref, rinfo = batch_omp(D, Y, n_nonzero_coefs=20, precompute=precompute, return_info=True)
    got, info = batch_omp(D.cuda(), Y.cuda(), n_nonzero_coefs=20, precompute=precompute, return_info=True)
    assert got.device.type == "cuda"
    assert torch.equal((got.cpu() != 0), (ref != 0))  # the same supports
    torch.testing.assert_close(got.cpu(), ref, rtol=1e-8, atol=1e-10)
    assert torch.equal(info.n_iter.cpu(), rinfo.n_iter)


def test_render_and_denoise_on_the_gpu():
    from cssat.metrics import psnr
    from cssat.optics import render
    from cssat.scene import tess_like
    from cssat.sparse import ksvd_denoise

    mesh = tess_like()
    dirs = torch.nn.functional.normalize(torch.randn(6, 3, generator=torch.Generator().manual_seed(1), dtype=torch.float64), dim=1)
    cpu = render(mesh, dirs, dirs.flip(0), 32, dtype=torch.float64)
    gpu = render(mesh, dirs.cuda(), dirs.flip(0).cuda(), 32, dtype=torch.float64)
    assert gpu.device.type == "cuda"
    torch.testing.assert_close(gpu.sum((1, 2)).cpu(), cpu.sum((1, 2)), rtol=1e-6, atol=1e-12)  # the light curve
    assert float((gpu.cpu() - cpu).abs().max()) <= 1e-6 * float(cpu.abs().max())
    rng = np.random.default_rng(0)
    clean = (cpu[0] / cpu[0].max()).float()
    noisy = clean + torch.from_numpy(rng.normal(0, 0.05, clean.shape)).float()
    out = ksvd_denoise(noisy.cuda(), 0.05, n_iter=3, n_train=2000)
    assert out.device.type == "cuda"
    assert psnr(clean, out.cpu(), data_range=1.0) > psnr(clean, noisy, data_range=1.0) + 3


@pytest.mark.parametrize("experiment", ["sim1", "sim2", "sim3", "solvers", "lightcurve"])
def test_every_experiment_runs_on_the_gpu(tmp_path, experiment):
    from cssat.experiments import run_experiment

    small = {
        "sim1": ["target.size=32"],
        "sim2": ["target.size=16", "cs.m=200", "cache_dir=null"],
        "sim3": ["target.size=16", "cs.m=200", "reference.pool=300", "reference.n=200", "reference.repeats=2",
                 "cache_dir=null"],
        "solvers": ["target.size=16", "grid.axes.0.values=[0.4]"],
        "lightcurve": ["scenario.n_steps=60", "render.size=32"],
    }[experiment]
    over = [f"experiment={experiment}", "threads=1", *small]
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        gpu_cfg = compose(config_name="config", overrides=[*over, "device=cuda"])
        cpu_cfg = compose(config_name="config", overrides=over)
    gpu = run_experiment(gpu_cfg, tmp_path / "gpu")
    cpu = run_experiment(cpu_cfg, tmp_path / "cpu")
    assert gpu["status"] == "ok" and gpu.get("device", "cuda").startswith("cuda")
    if isinstance(cpu.get("psnr"), float):
        assert abs(gpu["psnr"] - cpu["psnr"]) < 1.0  # float32 on another device: the same result to rounding


def test_refine_spin_on_the_gpu_follows_the_cpu():
    """The shadowed box-wing's spin refined with its light curves and gradients on the GPU: the same
    pole, period and 1σ as on the CPU (float64; the reductions' order differs, so not to the bit)."""
    import math

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility
    from cssat.inversion.parametric_spin import refine_spin
    from cssat.scene.attitude import spin_frame, to_body

    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 8 * 3600.0, 120)
    sun = np.tile([1.0, 0.0, 0.0], (120, 1))
    a = 0.3 + 0.8 * t / t[-1]
    obs = np.stack([np.cos(a), np.sin(a) * math.cos(0.35), np.sin(a) * math.sin(0.35)], 1)
    p = np.array([1.2, 1.0, 1.8, 6.0, 2.0, 0.5, 1.0, 0.3, 0.2])
    R = spin_frame(t, 60.0, 35.0, 600.0, 10.0, "ecliptic")
    S, V = to_body(R, sun), to_body(R, obs)
    y = box_wing_light_curve(torch.as_tensor(p), S, V, box_wing_visibility(p, S, V), range_km=1e-3, irradiance=1.0).numpy()
    sigma = 0.01 * y + 0.001 * float(np.median(y))
    y = y + sigma * rng.normal(size=len(y))
    kw = dict(sigma=sigma, fixed=("cd_bus",), shape=True, maxiter=10)
    cpu = refine_spin(t, y, sun, obs, p, 61.0, 34.0, 600.0, 12.0, **kw)
    gpu = refine_spin(t, y, sun, obs, p, 61.0, 34.0, 600.0, 12.0, device="cuda", **kw)
    for k in ("pole_lon_deg", "pole_lat_deg", "period_s", "formal_pole_err_deg", "rms_over_noise"):
        assert gpu[k] == pytest.approx(cpu[k], rel=1e-5, abs=1e-6), k
    np.testing.assert_allclose(gpu["params"], cpu["params"], rtol=1e-5)
