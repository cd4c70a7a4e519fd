"""torch Datasets: every item is a pure function of (seed, index)."""

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from cssat.data import LightCurves, ReferenceImages, item_rng
from cssat.scene import astra_like, make_scenario, tess_like


@pytest.fixture(scope="module")
def refs():
    return ReferenceImages(tess_like(), size=16, length=12, seed=5, noise=0.05)


def test_reference_items_do_not_depend_on_order_batch_or_workers(refs):
    single = torch.stack([refs[i] for i in range(len(refs))])
    assert single.shape == (12, 16, 16)
    torch.testing.assert_close(refs.batch(0, 12), single, rtol=0, atol=0)
    torch.testing.assert_close(torch.stack([refs[i] for i in reversed(range(12))]).flip(0), single, rtol=0, atol=0)
    for workers in (0, 2):
        loaded = torch.cat(list(DataLoader(refs, batch_size=5, num_workers=workers)))
        torch.testing.assert_close(loaded, single, rtol=0, atol=0)
    other = ReferenceImages(tess_like(), size=16, length=12, seed=6, noise=0.05)
    assert not torch.equal(other[0], single[0])


def test_reference_images_are_normalised_renders_plus_noise():
    clean = ReferenceImages(tess_like(), size=16, length=4, seed=1)
    noisy = ReferenceImages(tess_like(), size=16, length=4, seed=1, noise=0.1)
    c, n = clean.batch(0, 4), noisy.batch(0, 4)
    peaks = c.amax((1, 2))
    lit = peaks > 0
    assert bool(lit.any())  # at least one view sees the lit satellite
    torch.testing.assert_close(peaks[lit], torch.ones(int(lit.sum())))  # each lit image is normalised
    assert bool((c[~lit] == 0).all())  # an unlit view is black, not noise
    resid = (n - c).flatten()
    assert 0.07 < float(resid.std()) < 0.13
    with pytest.raises(IndexError):
        clean[4]
    with pytest.raises(ValueError, match="reference.size"):
        ReferenceImages(tess_like(), size=0, length=1)


def test_light_curve_items():
    sc = make_scenario(n_steps=20, step_s=300.0)
    from cssat.physics import GaussianAtmosphere

    ds = LightCurves(astra_like(), sc, length=3, seed=0, atmosphere=GaussianAtmosphere(emitters="pixels"),
                     images=True, size=16)
    a, b = ds[0], ds[1]
    assert a["curve"].shape == (20,) and a["images"].shape == (20, 16, 16)
    torch.testing.assert_close(a["images"].sum((1, 2)), a["clean"], rtol=1e-10, atol=0)
    assert not torch.equal(a["curve"], b["curve"])
    torch.testing.assert_close(ds[0]["curve"], a["curve"], rtol=0, atol=0)
    np.testing.assert_allclose(a["times"][:3].numpy(), [0, 300, 600])
    # Eq. 12 by hand: the item's curve is Σ_p Φ[t, p] x_t[p] with Φ drawn from the item's seed
    seed = int(item_rng(0, 1, 2).integers(0, 2**62))
    w = GaussianAtmosphere().weights(20, 256, seed=seed, dtype=torch.float64)
    torch.testing.assert_close(b["curve"], (w * a["images"].reshape(20, -1)).sum(1), rtol=1e-12, atol=0)
    facet = LightCurves(astra_like(), sc, length=1, seed=0)  # the default: Eq. 11 over the facets
    assert facet[0]["curve"].shape == (20,) and not torch.equal(facet[0]["curve"], a["curve"])
    assert torch.equal(LightCurves(astra_like(), sc, length=1, atmosphere=None)[0]["curve"], a["clean"])
    with pytest.raises(TypeError, match="atmosphere"):
        LightCurves(astra_like(), sc, length=1, atmosphere="fog")
