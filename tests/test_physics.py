"""The measurement layer: atmosphere models as sensing operators, noise models, Measurement."""

import math

import pytest
import torch

from conftest import dot_test
from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement, NoNoise
from cssat.sparse import GaussianSensing


def test_default_atmosphere_is_the_papers_gaussian_sensing_bit_for_bit():
    op = GaussianAtmosphere().operator(50, 64, seed=3, dtype=torch.float32)
    assert torch.equal(op.matrix(), GaussianSensing(50, 64, seed=3, dtype=torch.float32).matrix())


def test_gaussian_atmosphere_moments():
    w = GaussianAtmosphere().weights(400, 900, seed=1, dtype=torch.float64)
    assert abs(float(w.mean())) < 4 / math.sqrt(w.numel()) / 30  # mean 0 within 4 standard errors (std 1/30)
    assert float(w.std()) == pytest.approx(1 / 30, rel=0.01)
    w = GaussianAtmosphere(mean=1.0, std=0.01).weights(400, 900, seed=1, dtype=torch.float64)
    assert float(w.mean()) == pytest.approx(1.0, abs=4 * 0.01 / 600) and float(w.std()) == pytest.approx(0.01, rel=0.01)
    with pytest.raises(ValueError, match="^emitters"):
        GaussianAtmosphere(emitters="voxels")
    with pytest.raises(ValueError, match="^std"):
        GaussianAtmosphere(std=-1.0)


def test_measurement_is_linear_physics():
    op = GaussianAtmosphere().operator(30, 36, seed=2, dtype=torch.float64)
    meas = Measurement(op)
    assert dot_test(meas.operator) < 1e-12
    x = torch.rand(4, 6, 6, dtype=torch.float64)
    # images (B, H, W) and flattened rows give the same light curves: y = Φ x
    torch.testing.assert_close(meas.A(x), x.reshape(4, 36) @ op.matrix().T, rtol=1e-12, atol=0)
    torch.testing.assert_close(meas(x), meas.A(x), rtol=0, atol=0)  # no noise: forward = A
    torch.testing.assert_close(meas.A_adjoint(meas.A(x)), meas.A(x) @ op.matrix(), rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="^x:"):
        meas.A(torch.rand(5, 5))


def test_measurement_frames_is_eq_11_12():
    meas = Measurement(GaussianAtmosphere().operator(7, 10, seed=0, dtype=torch.float64))
    frames = torch.rand(7, 10, dtype=torch.float64)
    w = meas.matrix()
    expected = torch.tensor([sum(float(w[t, j] * frames[t, j]) for j in range(10)) for t in range(7)], dtype=torch.float64)
    torch.testing.assert_close(meas.frames(frames), expected, rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="frames"):
        meas.frames(torch.rand(6, 10, dtype=torch.float64))


def test_gaussian_noise_is_seeded_and_has_its_variance():
    op = GaussianAtmosphere().operator(20000, 16, seed=0, dtype=torch.float64)
    x = torch.rand(16, dtype=torch.float64)
    clean = Measurement(op).A(x)
    rms = float(clean.pow(2).mean().sqrt())
    noisy = Measurement(op, GaussianNoise(relative=0.1), seed=5)
    a, b = noisy(x), noisy(x)
    assert torch.equal(a, b)  # same seed, same noise on every call
    assert not torch.equal(a, Measurement(op, GaussianNoise(relative=0.1), seed=6)(x))
    assert float((a - clean).std()) == pytest.approx(0.1 * rms, rel=0.02)
    assert float((a - clean).mean()) == pytest.approx(0.0, abs=4 * 0.1 * rms / math.sqrt(20000))
    absolute = Measurement(op, GaussianNoise(sigma=0.5), seed=5)(x)
    assert float((absolute - clean).std()) == pytest.approx(0.5, rel=0.02)
    assert torch.equal(Measurement(op, NoNoise())(x), clean)
    with pytest.raises(ValueError, match="^sigma"):
        GaussianNoise(relative=0.1, sigma=0.2)
    with pytest.raises(ValueError, match="^relative"):
        GaussianNoise(relative=-0.1)


def test_noise_matches_the_pre_measurement_layer_formula():
    # cs.noise of cssat 0.1: y + noise · rms(y) · randn(m) from a CPU generator seeded with seed + 1
    phi = GaussianSensing(300, 64, seed=4, dtype=torch.float32)
    x = torch.rand(64)
    y = phi(x)
    old = y + 0.05 * y.pow(2).mean().sqrt() * torch.randn(300, generator=torch.Generator().manual_seed(5))
    assert torch.equal(Measurement(phi, GaussianNoise(relative=0.05), seed=5)(x), old)
