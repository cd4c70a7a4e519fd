"""The measurement layer: atmosphere models as sensing operators, noise models, Measurement."""

import math

import pytest
import torch

from conftest import dot_test
from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement, NoNoise
from cssat.sparse import GaussianSensing


def test_default_atmosphere_is_the_papers_gaussian_sensing_bit_for_bit():
    """The default Φ follows its documented draw, rebuilt here from the rule alone: row ``i`` is
    ``N(0, 1/n)`` from a generator seeded by the splitmix64 finaliser of ``seed · φ₆₄ + i + 1`` (low 63 bits)
    (so the first rows do not depend on ``m``)."""
    def splitmix(seed, i):
        mask = (1 << 64) - 1
        z = (seed * 0x9E3779B97F4A7C15 + i + 1) & mask
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return (z ^ (z >> 31)) & ((1 << 63) - 1)  # 63 bits: a valid torch seed

    op = GaussianAtmosphere().operator(50, 64, seed=3, dtype=torch.float32)
    rows = [torch.empty(64, dtype=torch.float32).normal_(0.0, 1 / 8, generator=torch.Generator().manual_seed(splitmix(3, i)))
            for i in range(50)]
    assert torch.equal(op.matrix(), torch.stack(rows))
    assert torch.equal(GaussianAtmosphere().operator(20, 64, seed=3, dtype=torch.float32).matrix(), op.matrix()[:20])


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


def test_photometric_noise_is_poisson_plus_read_noise_in_electrons():
    from cssat.physics import PhotometricNoise

    pn = PhotometricNoise(magnitude=14.0, diameter_m=0.5, exposure_s=0.5, read_noise_e=8.0, sky_mag_arcsec2=19.0)
    S = pn.electrons(14.0)
    bg = pn.n_pix * (pn.sky_e_per_pixel + pn.dark_e_per_pixel)
    y = torch.full((1, 200000), 3.0, dtype=torch.float64)  # a constant light curve whose scene flux is 3
    out = pn(y, torch.Generator().manual_seed(0), flux=torch.tensor([3.0]))
    e = out * (S / 3.0)  # back to electrons, background subtracted
    var = S + bg + pn.n_pix * 8.0 ** 2
    assert float(e.mean()) == pytest.approx(S, abs=4 * math.sqrt(var / 2e5))  # unbiased: noise in flux
    assert float(e.var()) == pytest.approx(var, rel=0.02)
    # the CCD equation: SNR = S / √(S + n_pix (B + D + R²))
    assert pn.snr() == pytest.approx(S / math.sqrt(var), rel=1e-12)
    assert float(e.mean() / e.std()) == pytest.approx(pn.snr(), rel=0.02)
    # same seed, same noise
    assert torch.equal(out, pn(y, torch.Generator().manual_seed(0), flux=torch.tensor([3.0])))


def test_magnitudes_and_electrons_round_trip_and_the_v_zero_point():
    from cssat.physics import PhotometricNoise
    from cssat.physics.photometry import V_ZERO_POINT_PHOTONS, magnitude_to_photon_rate, photon_rate_to_magnitude

    pn = PhotometricNoise(diameter_m=1.0, throughput=0.4, exposure_s=2.0)
    for mag in (-2.0, 5.5, 12.0, 19.3):
        assert pn.magnitude_of(pn.electrons(mag)) == pytest.approx(mag, abs=1e-12)
        assert photon_rate_to_magnitude(magnitude_to_photon_rate(mag)) == pytest.approx(mag, abs=1e-12)
    # five magnitudes are a factor 100 in flux (Pogson)
    assert pn.electrons(10.0) / pn.electrons(15.0) == pytest.approx(100.0, rel=1e-12)
    # V = 0 is about 1000 photons s⁻¹ cm⁻² Å⁻¹ over the 880 Å V band (Bessell 1979's rule of thumb)
    assert V_ZERO_POINT_PHOTONS == pytest.approx(1000 * 1e4 * 880, rel=0.05)
    # electrons = photons × area × throughput × time
    assert pn.electrons(0.0) == pytest.approx(V_ZERO_POINT_PHOTONS * math.pi / 4 * 0.4 * 2.0, rel=1e-12)
    with pytest.raises(ValueError, match="^throughput"):
        PhotometricNoise(throughput=1.5)


def test_photometric_noise_on_a_light_curve_in_watts():
    from cssat.optics import SOLAR_IRRADIANCE_W_M2, apparent_magnitude
    from cssat.physics import PhotometricNoise

    pn = PhotometricNoise(magnitude=None, read_noise_e=0.0, dark_e_per_s=0.0, sky_mag_arcsec2=40.0, systematic=0.0)
    flux = SOLAR_IRRADIANCE_W_M2 * 10 ** (-0.4 * (10.0 + 26.74))  # a V ≈ 10 satellite, W/m²
    y = torch.full((100000,), flux, dtype=torch.float64)
    out = pn(y, torch.Generator().manual_seed(1))
    mag = float(apparent_magnitude(torch.tensor(flux)))
    S = pn.electrons(mag)
    assert float(out.mean()) == pytest.approx(flux, rel=4 / math.sqrt(S * 1e5))
    assert float(out.std() / out.mean()) == pytest.approx(1 / math.sqrt(S), rel=0.02)  # shot noise only
