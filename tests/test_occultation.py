"""The Fresnel shadow of an occulter (issue 25, points 1–2), against independent physics."""

from __future__ import annotations

import numpy as np
import pytest
import torch

LAM = 5e-7


def _fresnel_k(lo, hi, x, s):
    """∫_lo^hi exp(iπ s² (x' − x)²/2) dx' × s: the 1-D Fresnel integral by scipy."""
    from scipy.special import fresnel

    Sa, Ca = fresnel(s * (lo - x))
    Sb, Cb = fresnel(s * (hi - x))
    return (Cb - Ca) + 1j * (Sb - Sa)


def test_a_rectangle_s_shadow_is_the_product_of_fresnel_integrals():
    """An opaque rectangle (straight edges) at GEO's range, 550 nm, 0.1 m pixels: |1 − U_x U_y/2i|²
    with U from scipy.special.fresnel at every pixel centre, to round-off."""
    from cssat.occultation import shadow

    lam, z, px, N = 550e-9, 3.5786e7, 0.1, 96
    r0, r1, c0, c1 = 20, 61, 33, 80
    mask = np.zeros((N, N))
    mask[r0:r1, c0:c1] = 1
    I = shadow(torch.tensor(mask), px, lam, z).numpy()
    s = np.sqrt(2 / (lam * z))
    c = (np.arange(N) + 0.5) * px
    U = 1 - np.outer(_fresnel_k(r0 * px, r1 * px, c, s), _fresnel_k(c0 * px, c1 * px, c, s)) / 2j
    assert np.abs(I - np.abs(U) ** 2).max() < 1e-12
    assert I.min() < 0.2 and I.max() > 1.2  # a diffraction pattern, not a silhouette (√(λz) = 4.4 m)


def test_poissons_spot_on_the_axis_of_a_disk():
    """Behind an opaque disk the axis is bright (I = 1 in the Fresnel approximation) and the spot
    is J0²(2π R r/(λz)) near it; the geometric shadow would be 0. A disk of radius 6 pixels,
    antialiased, √(λz) = 12 pixels."""
    from scipy.special import j0

    from cssat.occultation import shadow

    N, F, R, ss = 101, 12.0, 6.0, 9
    z = F * F / LAM
    yy, xx = (np.mgrid[:N * ss, :N * ss] + 0.5) / ss - N / 2
    mask = (np.hypot(yy, xx) <= R).astype(float).reshape(N, ss, N, ss).mean((1, 3))
    I = shadow(torch.tensor(mask), 1.0, LAM, z).numpy()
    c = N // 2
    assert I[c, c] > 0.97
    r = np.arange(4)
    assert np.abs(I[c, c:c + 4] - j0(2 * np.pi * R * r / (LAM * z)) ** 2).max() < 0.03


def test_the_fraunhofer_limit_and_parseval():
    """A small square aperture (Fresnel number 1/16): the field is the Fourier transform,
    I = (a²/λz)² sinc²(a x/λz) sinc²(a y/λz), to 1e-3; the energy within the grid is at most the
    aperture's and most of it."""
    from cssat.occultation import aperture_field

    N, F, a = 44, 8.0, 2
    z = F * F / LAM
    mask = np.zeros((N, N))
    mask[N // 2 - 1:N // 2 + 1, N // 2 - 1:N // 2 + 1] = 1  # pixel centres at ±0.5 around x = N/2
    U = aperture_field(torch.tensor(mask), 1.0, LAM, z).numpy()
    x = np.arange(N) + 0.5 - N / 2
    ref = (a * a / (LAM * z)) ** 2 * np.outer(np.sinc(a * x / (LAM * z)), np.sinc(a * x / (LAM * z))) ** 2
    assert np.abs(np.abs(U) ** 2 - ref).max() < 1e-3 * ref.max()
    energy = (np.abs(U) ** 2).sum()
    assert 0.7 * mask.sum() < energy <= mask.sum() * (1 + 1e-9)


def test_the_geometric_shadow_at_a_small_fresnel_scale():
    """√(λz) = 2 pixels under a 40-pixel square (the values at pixel centres are exact; the
    fringe-sampling check is off): dark deep inside, the unocculted star far outside."""
    from cssat.occultation import shadow

    N, F = 64, 2.0
    mask = np.zeros((N, N))
    mask[12:52, 12:52] = 1
    I = shadow(torch.tensor(mask), 1.0, LAM, F * F / LAM, check_sampling=False).numpy()
    assert I[22:42, 22:42].mean() < 0.01
    ring = np.ones((N, N), bool)
    ring[2:62, 2:62] = False
    assert abs(I[ring].mean() - 1) < 0.05
    # the light the square removes from the grid is its geometric area, within the fringes' spill
    assert abs((1 - I).sum() - 40 * 40) < 0.05 * 40 * 40


def test_the_shadow_is_batched_differentiable_and_follows_dtype():
    from cssat.occultation import shadow

    rng = np.random.default_rng(0)
    m = torch.tensor(rng.uniform(0, 1, (3, 12, 12)), requires_grad=True)
    I = shadow(m, 1.0, LAM, 36.0 / LAM)
    assert I.shape == (3, 12, 12) and I.dtype == torch.float64
    for b in range(3):
        assert torch.allclose(I[b], shadow(m[b].detach(), 1.0, LAM, 36.0 / LAM), atol=1e-12)
    assert shadow(m.detach().float(), 1.0, LAM, 36.0 / LAM).dtype == torch.float32
    small = torch.tensor(rng.uniform(0, 1, (5, 5)), requires_grad=True)
    assert torch.autograd.gradcheck(lambda x: shadow(x, 1.0, LAM, 9.0 / LAM).sum(), (small,))


def test_the_sampling_condition_is_named():
    from cssat._checks import FieldError
    from cssat.occultation import shadow

    with pytest.raises(FieldError, match="pixel_m"):
        shadow(torch.ones(200, 200), 1.0, LAM, 16.0 / LAM)  # half-diagonal 141 px > λz/(2 px) = 8 px
    with pytest.raises(FieldError, match="mask"):
        shadow(torch.ones(5), 1.0, LAM, 1.0)
    with pytest.raises(FieldError, match="wavelength_m"):
        shadow(torch.ones(4, 4), 1.0, -1.0, 1.0)
