"""The occultation's superellipses as a multi-start chosen by held-out telescopes
(:func:`cssat.occultation.choose_prior`): the starts against brute-force moments, the choice on a
silhouette of known parts, and the same answer at one and two threads and after a 1e-9 change."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

LAM, PX, N, Z = 550e-9, 0.4, 32, 3.8e7


def _panels(n=N, px=PX):
    """Two separate 5.2 × 2.0 m panels east and west of the centre (a two-part silhouette)."""
    truth = np.zeros((n, n))
    truth[13:18, 2:15] = 1.0
    truth[13:18, 18:31] = 1.0
    return truth


def _record(truth, seed=0, n_tel=10, sig=0.02, distance=Z):
    """``truth``'s monochromatic shadow recorded by ``n_tel`` telescopes 0.8 m apart across an
    eastward track, noise ``sig`` a sample."""
    from cssat.occultation import pattern_kernel, record, shadow, smooth

    v = np.array([2800.0, 0.0])
    pos = np.stack([np.zeros(n_tel), (np.arange(n_tel) - (n_tel - 1) / 2) * 0.8], 1)
    times = (np.arange(-N, N) + 0.5) * (PX / 2) / 2800.0
    k = pattern_kernel(PX, aperture_m=0.5, smear_m=PX / 2, smear_dir=(1, 0))
    with torch.no_grad():
        clean = record(smooth(shadow(torch.tensor(truth), PX, LAM, distance, ground=1.25), k), PX, pos, v, times).numpy()
    y = clean + sig * np.random.default_rng(seed).standard_normal(clean.shape)
    return (y, sig, (N, N), PX, LAM, distance, pos, v, times), k


def _choose(truth, distance=Z):
    from cssat.occultation import choose_prior, invert_silhouette

    geo, k = _record(truth, distance=distance)
    kw = {"kernel": k, "ground": 1.25}
    mp, _ = invert_silhouette(*geo, tv=0.3, iters=40, **kw)
    return choose_prior(*geo, init_mask=mp, prior="auto", tv=0.3, iters=30, shape_iters=20, components=(1, 2),
                        n_starts=2, **kw)


def test_shape_starts_are_the_clusters_moments():
    """Two separate rectangles: the two-shape start has each rectangle's centroid and the half-axes
    of its equivalent ellipse (2√λ of its pixel-centre covariance plus a pixel's px²/12, computed
    here by brute force), the long axis east (angle π/2); the one-shape start the union's; every
    start continuous in the mask (a 1e-9 change moves it by < 1e-6)."""
    from cssat.occultation import shape_starts

    truth = _panels()
    (two,) = shape_starts(truth, PX, 2, n_starts=1, seed=3)
    rr, cc = np.nonzero(truth)
    x, y = (cc + 0.5 - N / 2) * PX, (rr + 0.5 - N / 2) * PX
    for side in (x < 0, x > 0):
        row = two[np.argmin(np.abs(two[:, 0] - x[side].mean()))]
        assert row[0] == pytest.approx(x[side].mean(), abs=1e-12) and row[1] == pytest.approx(y[side].mean(), abs=1e-12)
        a = 2 * math.sqrt(x[side].var() + PX * PX / 12)
        b = 2 * math.sqrt(y[side].var() + PX * PX / 12)
        assert math.exp(row[2]) == pytest.approx(a, rel=1e-9) and math.exp(row[3]) == pytest.approx(b, rel=1e-9)
        assert abs(math.sin(row[4])) == pytest.approx(1.0, abs=1e-9)
    (one,) = shape_starts(truth, PX, 1, seed=3)
    assert one[0, 0] == pytest.approx(x.mean(), abs=1e-12) and math.exp(one[0, 2]) == pytest.approx(2 * math.sqrt(x.var() + PX * PX / 12))
    soft = np.clip(truth * 0.9 + 0.05 + 0.02 * np.random.default_rng(0).standard_normal(truth.shape), 0, 1)
    for k in (1, 2, 3):
        a = shape_starts(soft, PX, k, n_starts=3, seed=1)
        b = shape_starts(soft + 1e-9, PX, k, n_starts=3, seed=1)
        assert all(np.abs(p - q).max() < 1e-6 for p, q in zip(a, b))


def test_the_multistart_keeps_the_two_panels_at_one_and_two_threads_and_after_a_1e_9_change():
    """Two separate panels: held-out telescopes keep the superellipses (lower held-out χ² than the
    pixels) with two shapes (one shape misses the gap: its held-out χ² is higher), the kept mask's
    IoU ≥ 0.85; the spread's near-best candidates include
    the kept one. At two threads and after the distance changed by 1e-9 (relative) the same number of
    shapes, start and prior, and the IoU against the truth equal to 1e-9."""
    from cssat.occultation import iou

    truth = _panels()
    old = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        m1, c1 = _choose(truth)
        torch.set_num_threads(2)
        m2, c2 = _choose(truth)
        torch.set_num_threads(1)
        m3, c3 = _choose(truth, distance=Z * (1 + 1e-9))
    finally:
        torch.set_num_threads(old)
    assert c1.used == "shapes" and c1["heldout_chi2_shapes"] < c1["heldout_chi2_pixels"], c1.metrics()
    assert c1["n_shapes"] == 2, c1.metrics()
    held = {c["n_shapes"]: c["heldout_chi2"] for c in c1["candidates"]}
    assert held[1] > held[2] + 1.0
    assert iou(m1, truth) >= 0.85
    assert c1["kept_candidate"] in c1["near_best"]
    lo, hi = c1["spread"]["area_m2"]
    assert lo <= c1["candidates"][c1["kept_candidate"]]["area_m2"] <= hi
    for c in (c2, c3):
        assert (c.used, c["n_shapes"], c["start"]) == (c1.used, c1["n_shapes"], c1["start"])
    assert abs(iou(m2, truth) - iou(m1, truth)) <= 1e-9 and abs(iou(m3, truth) - iou(m1, truth)) <= 1e-9


def test_choose_prior_names_its_bad_choices():
    from cssat._checks import FieldError
    from cssat.occultation import choose_prior

    geo, k = _record(_panels())
    with pytest.raises(FieldError, match="invert.prior"):
        choose_prior(*geo, init_mask=_panels(), prior="splines", kernel=k)
    with pytest.raises(FieldError, match="components"):
        choose_prior(*geo, init_mask=_panels(), prior="shapes", kernel=k, components=())
    with pytest.raises(FieldError, match="init_mask"):  # nothing to start the shapes from
        choose_prior(*geo, init_mask=np.zeros((N, N)), prior="shapes", kernel=k)
    m, c = choose_prior(*geo, init_mask=np.zeros((N, N)), prior="auto", kernel=k)  # auto keeps the pixels
    assert c.used == "pixels" and not m.any()
