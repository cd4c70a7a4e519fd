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


def test_a_dataloader_fetches_a_batch_in_one_render(refs, monkeypatch):
    calls = []
    render_many = ReferenceImages.images
    monkeypatch.setattr(ReferenceImages, "images", lambda self, idx: calls.append(list(idx)) or render_many(self, idx))
    order = torch.Generator().manual_seed(3)
    loader = DataLoader(refs, batch_size=5, shuffle=True, generator=order)
    batches = list(loader)
    assert [len(c) for c in calls] == [5, 5, 2]  # __getitems__: one vectorised render per batch
    seen = [i for c in calls for i in c]
    assert sorted(seen) == list(range(12))  # shuffled
    calls.clear()
    single = torch.stack([refs[i] for i in seen])  # item by item: the same values
    torch.testing.assert_close(torch.cat(batches), single, rtol=0, atol=0)


def test_channel_axis_and_training_pairs():
    from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement, NoNoise

    phi = GaussianAtmosphere().operator(40, 256, seed=2, dtype=torch.float32)
    chan = ReferenceImages(tess_like(), size=16, length=6, seed=5, channel_axis=True)
    plain = ReferenceImages(tess_like(), size=16, length=6, seed=5)
    assert chan[0].shape == (1, 16, 16) and chan.batch(0, 6).shape == (6, 1, 16, 16)
    torch.testing.assert_close(chan.batch(0, 6)[:, 0], plain.batch(0, 6), rtol=0, atol=0)
    clean = ReferenceImages(tess_like(), size=16, length=6, seed=5, channel_axis=True,
                            measurement=Measurement(phi, NoNoise()))
    x, y = clean[2]
    assert x.shape == (1, 16, 16) and y.shape == (40,)
    torch.testing.assert_close(y, phi.matrix() @ x.reshape(-1))  # y = Φx, against the dense matrix
    noisy = ReferenceImages(tess_like(), size=16, length=6, seed=5,
                            measurement=Measurement(phi, GaussianNoise(relative=0.1)))
    xb, yb = noisy.batch(0, 6)
    assert xb.shape == (6, 16, 16) and yb.shape == (6, 40)
    for i in (0, 3, 5):  # each pair is the same alone, in a batch (Φx to float32 rounding: BLAS
        torch.testing.assert_close(noisy[i][0], xb[i], rtol=0, atol=0)  # blocks a batch differently)
        torch.testing.assert_close(noisy[i][1], yb[i], rtol=1e-5, atol=1e-6)
    xs, ys = next(iter(DataLoader(noisy, batch_size=6)))
    torch.testing.assert_close(ys, yb, rtol=0, atol=0)
    lit = [i for i in range(6) if float(xb[i].sum()) > 0]
    noise = yb - xb.reshape(6, -1) @ phi.matrix().T
    assert len(lit) >= 2 and not torch.allclose(noise[lit[0]], noise[lit[1]])  # independent noise per item
    with pytest.raises(ValueError, match="measurement: its operator takes 256 pixels, the images have 8²"):
        ReferenceImages(tess_like(), size=8, length=2, measurement=Measurement(phi))


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
