"""The photometric floor (noise.floor): a relative 1σ added in quadrature to every sample's error."""

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.physics.noise import GaussianNoise, NoNoise, PhotometricNoise, add_floor


def _stats(noise, y, n=20000, seed=0, **kw):
    g = torch.Generator().manual_seed(seed)
    draws = torch.stack([noise(y, g, **kw)[0] for _ in range(n)]).double()
    return draws.mean(0), draws.var(0)


def test_gaussian_floor_adds_in_quadrature():
    y = torch.tensor([[1.0, 4.0, 10.0]], dtype=torch.float64)
    sigma, floor = 0.1, 0.03
    noise = GaussianNoise(sigma=sigma, floor=floor)
    want = sigma**2 + (floor * y[0]) ** 2
    mean, var = _stats(noise, y)
    # the sample variance of n normal draws: relative standard error sqrt(2/(n-1)); 5 of them
    assert torch.all((var / want - 1).abs() < 5 * math.sqrt(2 / 19999))
    assert torch.all((mean - y[0]).abs() < 5 * torch.sqrt(want / 20000))
    torch.testing.assert_close(noise.variance(y)[0], want, rtol=1e-12, atol=0)


def test_photometric_floor_adds_in_quadrature():
    noise0 = PhotometricNoise(magnitude=None, systematic=1e-3, full_well_e=None)
    noise = PhotometricNoise(magnitude=None, systematic=1e-3, full_well_e=None, floor=0.02)
    y = torch.tensor([[1e-13, 3e-13]], dtype=torch.float64)  # W/m²: V ≈ 5-6, shot noise ≪ 2 %
    torch.testing.assert_close(noise.variance(y), noise0.variance(y) + (0.02 * y) ** 2, rtol=1e-12, atol=0)
    _, var = _stats(noise, y, n=6000)
    want = noise0.variance(y)[0] + (0.02 * y[0]) ** 2
    assert torch.all((var / want - 1).abs() < 5 * math.sqrt(2 / 5999))


def test_zero_floor_draws_nothing_more():
    y = torch.tensor([[1.0, 2.0, 3.0]])
    for make in (lambda **k: GaussianNoise(relative=0.01, **k), lambda **k: PhotometricNoise(magnitude=None, **k)):
        a = make()(y * 1e-12, torch.Generator().manual_seed(3))
        b = make(floor=0.0)(y * 1e-12, torch.Generator().manual_seed(3))
        assert torch.equal(a, b)
    assert NoNoise(floor=0.0)(y) is y


def test_floor_is_checked_by_name():
    for bad in (-0.01, 0.2, float("nan"), "2%", True):
        with pytest.raises(FieldError, match="floor"):
            GaussianNoise(sigma=1.0, floor=bad)
    with pytest.raises(FieldError, match=r"floor.*\[0(\.0)?, 0\.1\]"):
        PhotometricNoise(floor=0.5)
    with pytest.raises(FieldError, match="floor.*gaussian or photometric"):
        NoNoise(floor=0.02)


def test_add_floor_on_measured_values():
    y = torch.full((40000,), 5.0, dtype=torch.float64)
    noisy, sig = add_floor(y, torch.full_like(y, 0.1), 0.02, torch.Generator().manual_seed(1))
    torch.testing.assert_close(sig, torch.full_like(y, math.hypot(0.1, 0.1)), rtol=1e-12, atol=0)
    assert float(noisy.std()) == pytest.approx(0.1, rel=0.02)  # only the floor's 0.02 × 5 is drawn here
    same, s0 = add_floor(y, None, 0.0, torch.Generator())
    assert torch.equal(same, y) and torch.equal(s0, torch.zeros_like(y))
