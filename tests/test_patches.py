"""Patch and cube extraction / reassembly (issue 4, item 1)."""

import numpy as np
import pytest
import torch
from sklearn.feature_extraction.image import extract_patches_2d

from cssat.sparse.patches import extract_patches, fold_patches, patch_positions


def test_patches_match_scikit_learn_for_step_one():
    rng = np.random.default_rng(0)
    img = rng.standard_normal((13, 17))
    ref = extract_patches_2d(img, (4, 5)).reshape(-1, 20)
    got = extract_patches(torch.tensor(img), (4, 5)).numpy()
    np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("shape,size,step", [((20, 23), 6, 3), ((16, 16), 8, 8), ((9, 10, 11), (3, 4, 5), 2), ((9, 12, 12), 4, (1, 3, 4))])
def test_fold_inverts_extract_and_covers_every_pixel(shape, size, step):
    x = torch.randn(*shape, dtype=torch.float64)
    p = extract_patches(x, size, step)
    torch.testing.assert_close(fold_patches(p, shape, size, step), x, rtol=0, atol=1e-14)
    pos = patch_positions(shape, size, step)
    sizes = (size,) * len(shape) if isinstance(size, int) else size
    for d, (n, s) in enumerate(zip(shape, sizes)):
        assert int(pos[d][0]) == 0 and int(pos[d][-1]) == n - s  # first and last positions


def test_fold_averages_overlaps():
    shape, size, step = (6, 6), 4, 2
    p = extract_patches(torch.zeros(shape), size, step)
    p += torch.arange(len(p), dtype=p.dtype)[:, None]  # patch k says "k" everywhere
    out = fold_patches(p, shape, size, step)
    # the top-left pixel is only in patch 0; the centre pixels are in all four patches
    assert float(out[0, 0]) == 0.0
    assert float(out[2, 2]) == pytest.approx((0 + 1 + 2 + 3) / 4)


def test_patch_errors_name_the_argument():
    with pytest.raises(ValueError, match="size: block size .* larger than the array"):
        extract_patches(torch.zeros(5, 5), 6)
    with pytest.raises(ValueError, match="x: expected a 2-D image"):
        extract_patches(torch.zeros(5), 2)
    with pytest.raises(ValueError, match="step: sizes must be >= 1"):
        extract_patches(torch.zeros(5, 5), 2, step=0)
    with pytest.raises(ValueError, match="step: .* must not exceed the block size"):
        extract_patches(torch.zeros(9, 9), 3, step=4)
    with pytest.raises(ValueError, match="patches: expected shape"):
        fold_patches(torch.zeros(3, 4), (5, 5), 2)


@pytest.mark.parametrize("shape,size,step", [((13, 17), (4, 5), 1), ((20, 23), 6, 3), ((16, 16), 8, (2, 8)),
                                             ((9, 12), (3, 4), (2, 3))])
def test_2d_patches_equal_a_brute_force_loop_at_any_step(shape, size, step):
    """The unfold path (2-D) against patches cut by hand at the positions of patch_positions."""
    x = torch.randn(*shape, dtype=torch.float32)
    py, px = patch_positions(shape, size, step)
    ph, pw = (size, size) if isinstance(size, int) else size
    ref = torch.stack([x[i:i + ph, j:j + pw].reshape(-1) for i in py.tolist() for j in px.tolist()])
    got = extract_patches(x, size, step)
    assert torch.equal(got, ref)
