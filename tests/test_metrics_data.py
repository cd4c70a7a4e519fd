import numpy as np
import pytest
import torch
from PIL import Image

from cssat.data import load_target
from cssat.metrics import psnr, ssim


def test_psnr_matches_the_formula():
    rng = np.random.default_rng(0)
    ref = rng.uniform(0, 1, (16, 16))
    x = ref + rng.normal(0, 0.05, ref.shape)
    mse = np.mean((x - ref) ** 2)
    assert psnr(ref, x, data_range=1.0) == pytest.approx(10 * np.log10(1.0 / mse), rel=1e-12)
    assert psnr(ref * 255, x * 255, data_range=255) == pytest.approx(10 * np.log10(1.0 / mse), rel=1e-12)
    # torch tensors are accepted; the default range is the span of image_true (the first argument)
    span = ref.max() - ref.min()
    assert psnr(torch.tensor(ref), torch.tensor(x)) == pytest.approx(10 * np.log10(span**2 / mse), rel=1e-12)
    assert psnr(image_test=x, image_true=ref) == pytest.approx(10 * np.log10(span**2 / mse), rel=1e-12)


def test_metrics_take_scikit_image_argument_order():
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    rng = np.random.default_rng(4)
    true = rng.uniform(0.2, 0.6, (24, 24))  # spans differ: the order decides the default range
    test = np.clip(true + rng.normal(0, 0.3, true.shape), -1, 2)
    assert psnr(true, test) == pytest.approx(peak_signal_noise_ratio(true, test, data_range=np.ptp(true)), rel=1e-12)
    assert ssim(true, test) == pytest.approx(structural_similarity(true, test, data_range=np.ptp(true)), rel=1e-12)
    assert psnr(true, test) != pytest.approx(psnr(test, true))


def test_a_batch_gives_one_value_per_image():
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    rng = np.random.default_rng(5)
    true = rng.uniform(0, 1, (3, 20, 20))
    test = true + rng.normal(0, 1, (3, 1, 1)) * 0.05 * rng.standard_normal(true.shape)
    p, s = psnr(true, test, data_range=1.0), ssim(true, test, data_range=1.0)
    assert p.shape == s.shape == (3,)
    np.testing.assert_allclose(p, [peak_signal_noise_ratio(a, b, data_range=1.0) for a, b in zip(true, test)], rtol=1e-12)
    np.testing.assert_allclose(s, [structural_similarity(a, b, data_range=1.0) for a, b in zip(true, test)], rtol=1e-12)
    # deepinv's (B, C, H, W): C = 1 as (B, H, W); C = 3 scored per image over its channels
    np.testing.assert_allclose(psnr(torch.tensor(true[:, None]), torch.tensor(test[:, None]), data_range=1.0), p, rtol=1e-12)
    rgb_t, rgb = np.stack([true] * 3, 1), np.stack([test] * 3, 1)
    np.testing.assert_allclose(psnr(rgb_t, rgb, data_range=1.0), p, rtol=1e-12)
    np.testing.assert_allclose(ssim(rgb_t, rgb, data_range=1.0), s, rtol=1e-12)
    # a volume, on request, is one value with a 3-D SSIM window
    vol_t, vol = rng.uniform(0, 1, (8, 16, 16)), rng.uniform(0, 1, (8, 16, 16))
    assert ssim(vol_t, vol, data_range=1.0, volume=True) == pytest.approx(
        structural_similarity(vol_t, vol, data_range=1.0), rel=1e-12)


def test_ssim_properties():
    rng = np.random.default_rng(1)
    ref = rng.uniform(0, 1, (32, 32))
    assert ssim(ref, ref, data_range=1.0) == pytest.approx(1.0)
    noisy = ref + rng.normal(0, 0.2, ref.shape)
    less = ref + rng.normal(0, 0.05, ref.shape)
    assert ssim(ref, noisy, data_range=1.0) < ssim(ref, less, data_range=1.0) < 1.0


def test_metric_errors():
    with pytest.raises(ValueError, match="data_range"):
        psnr(np.ones((8, 8)), np.ones((8, 8)))
    with pytest.raises(ValueError, match="image_test: shape"):
        psnr(np.ones((8, 8)), np.ones((8, 9)), data_range=1)
    with pytest.raises(ValueError, match="image_test: contains NaN"):
        ssim(np.ones((8, 8)), np.full((8, 8), np.nan), data_range=1)
    with pytest.raises(ValueError, match="image_true: expected"):
        psnr(np.ones(8), np.ones(8), data_range=1)


def test_load_builtin_and_file_images(tmp_path):
    cam = load_target("camera", 32)
    assert cam.shape == (32, 32) and cam.min() >= 0 and cam.max() <= 1
    rgb = np.zeros((40, 40, 3), np.uint8)
    rgb[10:30, 10:30] = (255, 0, 0)  # red square: luminance 0.299
    rgb[0:5, 0:5] = (255, 255, 255)
    Image.fromarray(rgb).save(tmp_path / "sq.png")
    Image.fromarray(rgb).save(tmp_path / "sq.jpg", quality=95)
    png = load_target(str(tmp_path / "sq.png"), 40)
    assert png[20, 20] == pytest.approx(0.299, abs=0.01)  # gray conversion, scaled to [0, 1]
    assert png[2, 2] == pytest.approx(1.0)
    jpg = load_target(str(tmp_path / "sq.jpg"), 20)
    assert jpg.shape == (20, 20)


def test_bad_images_are_refused_by_field(tmp_path):
    Image.fromarray(np.zeros((20, 30), np.uint8)).save(tmp_path / "wide.png")
    with pytest.raises(ValueError, match=r"target.image: image is 20×30 pixels; a square image"):
        load_target(str(tmp_path / "wide.png"), 16)
    (tmp_path / "junk.png").write_bytes(b"not an image")
    with pytest.raises(ValueError, match="target.image: cannot read"):
        load_target(str(tmp_path / "junk.png"), 16)
    with pytest.raises(ValueError, match="target.image: .*neither a readable file nor a built-in"):
        load_target(str(tmp_path / "missing.png"), 16)
    with pytest.raises(ValueError, match="target.size"):
        load_target("camera", 1)
    nan = np.ones((8, 8), np.float32)
    nan[2, 3] = np.nan
    Image.fromarray(nan, mode="F").save(tmp_path / "nan.tif")
    with pytest.raises(ValueError, match="target.image: the image contains NaN"):
        load_target(str(tmp_path / "nan.tif"), 8)
