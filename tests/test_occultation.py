"""The Fresnel shadow of an occulter (issue 25, points 1–2), against independent physics."""

from __future__ import annotations

import math

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


def test_the_photon_budget_of_the_issue():
    """0.5 m, 0.2 ms, throughput 0.5: ≈ 700 / 110 / 18 photons from V = 6 / 8 / 10 (issue 25)."""
    from cssat.occultation.record import photons

    for V, n in ((6, 700), (8, 110), (10, 18)):
        assert photons(V, 0.5, 2e-4) == pytest.approx(n, rel=0.06)


def test_a_finite_star_is_a_sum_of_point_stars():
    """The limb-darkened star's smoothing against a brute-force sum of the point-star pattern
    shifted to 800 points drawn over the disk with the limb-darkening weight."""
    from cssat.occultation import shadow
    from cssat.occultation.record import pattern_kernel, smooth

    N, px, F = 40, 0.1, 0.9
    z = F * F / LAM
    mask = np.zeros((N, N))
    mask[12:28, 10:30] = 1
    I = shadow(torch.tensor(mask), px, LAM, z)
    D, u = 0.6, 0.6  # the star's projected diameter (m), limb darkening
    got = smooth(I, pattern_kernel(px, star_diameter_m=D, limb_darkening=u, supersample=16)).numpy()
    rng = np.random.default_rng(0)
    pts = []
    while len(pts) < 800:  # rejection sampling of I(μ) = 1 − u(1 − μ) on the disk
        x, y = rng.uniform(-1, 1, 2)
        r2 = x * x + y * y
        if r2 <= 1 and rng.uniform() <= 1 - u * (1 - np.sqrt(1 - r2)):
            pts.append((x * D / 2, y * D / 2))
    ref = np.zeros((N, N))
    for dx, dy in pts:  # each point star shifts the pattern: the shifted mask's shadow, exact
        shifted = np.zeros((N, N))
        fine = np.kron(mask, np.ones((10, 10)))
        sy, sx = int(round(dy / px * 10)), int(round(dx / px * 10))
        fine = np.roll(np.roll(fine, sy, 0), sx, 1)
        shifted = fine.reshape(N, 10, N, 10).mean((1, 3))
        ref += shadow(torch.tensor(shifted), px, LAM, z).numpy()
    ref /= len(pts)
    inner = slice(8, 32)
    assert np.abs(got[inner, inner] - ref[inner, inner]).max() < 0.03
    assert np.abs(got - I.numpy()).max() > 0.1  # the star's size matters here


def test_record_samples_the_moving_pattern():
    """At pixel centres the bilinear record returns the pattern's values; outside the grid the
    unocculted star (1); the track moves against the velocity."""
    from cssat.occultation.record import record

    rng = np.random.default_rng(1)
    I = torch.tensor(rng.uniform(0, 2, (16, 20)))
    px = 0.1
    # pixel (r, c)'s centre is at east (c + 0.5 − W/2) px, north (r + 0.5 − H/2) px
    r, c = 5, 13
    p = [(c + 0.5 - 10) * px, (r + 0.5 - 8) * px]
    out = record(I, px, [p], [1000.0, 0.0], [0.0, -3 * px / 1000.0, 1.0])
    assert out[0, 0].item() == pytest.approx(I[r, c].item(), abs=1e-12)
    assert out[0, 1].item() == pytest.approx(I[r, c + 3].item(), abs=1e-12)  # the pattern moved west: we see east
    assert out[0, 2].item() == pytest.approx(1.0, abs=1e-12)


def test_the_silhouette_comes_back_from_the_recorded_shadow():
    """A small box-wing silhouette (6 × 6.5 m on 0.25 m pixels) at GEO's range, 550 nm (√(λz)
    = 4.4 m: its shadow is a diffraction pattern), recorded by 12 telescopes of 0.5 m across the
    track, noiseless: the non-linear inversion through autograd gives the mask back (IoU ≥ 0.85;
    the empty mask scores 0, the shadow's own dark region thresholded far less)."""
    from cssat.occultation import shadow
    from cssat.occultation.invert import invert_silhouette, iou
    from cssat.occultation.record import pattern_kernel, record, smooth

    lam, px, z, N = 550e-9, 0.25, 3.5786e7, 24
    truth = np.zeros((N, N))
    truth[9:15, 8:16] = 1
    truth[11:13, 2:22] = 1
    v = np.array([2600.0, 0.0])
    pos = np.stack([np.zeros(12), (np.arange(12) - 5.5) * 2 * px], 1)
    times = np.arange(-N / 2, N / 2) * px / 2600.0
    k = pattern_kernel(px, aperture_m=0.5, smear_m=px, smear_dir=(1, 0))
    with torch.no_grad():
        I = smooth(shadow(torch.tensor(truth), px, lam, z), k)
        y = record(I, px, pos, v, times)
    m, info = invert_silhouette(y, 0.01, (N, N), px, lam, z, pos, v, times, kernel=k, iters=400)
    assert iou(m, truth) >= 0.85, info
    assert iou(1 - I.numpy(), truth) < 0.5  # the shadow itself is no silhouette


def test_a_geo_satellite_s_shadow_sweeps_at_the_sidereal_rate():
    """The synthetic Astra 1KR seen from 51.2° N with a star near it: the shadow crosses the
    fundamental plane at ω⊕ × the satellite's distance along the line of sight × cos δ⋆ (the
    star drifts at the sidereal rate, the satellite stays put) — ≈ 2.6 km/s, to 2 %."""
    from cssat.occultation import shadow_track, star_direction
    from cssat.scene import ASTRA_1KR_SYNTHETIC_TLE, make_scenario

    sc = make_scenario(tle=ASTRA_1KR_SYNTHETIC_TLE, start_utc="2020-04-01T22:00:00", n_steps=3, step_s=1.0,
                       lat_deg=51.17, lon_deg=10.45, alt_m=0.0)
    rel = sc.r_sat[1] - sc.r_obs[1]
    d = rel / np.linalg.norm(rel)  # a star exactly behind the satellite
    dec = np.arcsin(d[2])
    ra = np.arctan2(d[1], d[0])
    tr = shadow_track(sc, star_direction(np.degrees(ra), np.degrees(dec)))
    omega = 7.2921159e-5
    expect = omega * tr["distance_km"][1] * np.cos(dec)
    assert tr["miss_km"][1] < 1e-6 and tr["speed_km_s"][1] == pytest.approx(expect, rel=0.02)
    assert 2.4 < tr["speed_km_s"][1] < 2.8


def test_the_silhouette_of_a_box_is_its_projected_area():
    """A 2 × 3 × 1 m box seen along z covers 6 m², along a body diagonal |A·v| summed over faces
    (the projected area of a convex body: ½ Σ A_f |n_f·v|)."""
    from cssat.occultation import silhouette
    from cssat.scene import box

    b = box((2.0, 3.0, 1.0))
    assert silhouette(b, [0, 0, 1.0], 0.05, 80, supersample=4).sum() * 0.05 ** 2 == pytest.approx(6.0, rel=1e-3)
    v = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    proj = 0.5 * (2 * 3 * 2 * abs(v[2]) + 2 * 1 * 2 * abs(v[1]) + 3 * 1 * 2 * abs(v[0]))
    assert silhouette(b, v, 0.05, 100, supersample=8).sum() * 0.05 ** 2 == pytest.approx(proj, rel=5e-3)


def test_the_occultation_experiment_runs_and_writes_its_results(tmp_path):
    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=occultation", "silhouette.size=24", "silhouette.pixel_m=0.5",
                                                       "invert.iters=5", "invert.shape_iters=5", "threads=1"])
    met = run_experiment(cfg, tmp_path / "run")
    assert met["status"] == "ok" and 2.5 < met["shadow_speed_km_s"] < 3.0 and 0 <= met["iou"] <= 1
    # the V band's photon-weighted wavelength for a K giant (B − V 1.1: 4515 K) sets the Fresnel scale
    assert 545e-9 < met["effective_wavelength_m"] < 565e-9 and met["star_teff_k"] == pytest.approx(4514.8, abs=1)
    assert met["fresnel_scale_m"] == pytest.approx(np.sqrt(met["effective_wavelength_m"] * met["distance_km"] * 1e3))
    # the telescopes stand on the ground: a horizontal line shrinks by between sin(altitude) and 1 in the plane
    alt = np.radians(met["star_altitude_deg"])
    assert np.sin(alt) - 1e-9 <= met["ground_projection"] <= 1 + 1e-9
    assert met["array_plane_spacing_m"] == pytest.approx(met["array_ground_spacing_m"] * met["ground_projection"])
    assert met["airmass"] == pytest.approx(1 / np.sin(alt)) and met["row"] == "realistic" and met["n_wavelengths"] == 8
    for k in ("time_offset_s", "time_offset_sigma_s", "path_offset_m", "path_offset_sigma_m", "star_diameter_mas",
              "path_capture_probability", "iou_placed", "scintillation_frozen_sigma"):
        assert np.isfinite(met[k]), k
    for f in ("arrays.npz", "figures/occultation_shadow.png", "figures/occultation_series.png",
              "figures/occultation_silhouette.png"):
        assert (tmp_path / "run" / f).is_file()


def _linear_case(N=32, px=0.25):
    from cssat.occultation.record import pattern_kernel

    v = np.array([2600.0, 0.0])
    pos = np.stack([np.zeros(10), (np.arange(10) - 4.5) * 3 * px], 1)
    times = np.arange(-N / 2, N / 2) * px / 2600.0
    k = pattern_kernel(px, aperture_m=0.5, smear_m=px, smear_dir=(1, 0))
    return dict(pixel_m=px, wavelength_m=550e-9, distance_m=3.5786e7, positions_m=pos, velocity_m_s=v, times_s=times,
                kernel=k)


def _faint_plate():
    """A 10 %-opaque 2 × 1.5 m plate on 32² pixels of 0.25 m, its linearised series with 0.1 % noise."""
    from cssat.occultation import ShadowOperator

    c = _linear_case()
    truth = np.zeros((32, 32))
    truth[12:18, 10:18] = 0.1
    op = ShadowOperator((32, 32), **c)
    rng = np.random.default_rng(2)
    y = 1 + op(torch.tensor(truth).reshape(1, -1))[0].numpy().reshape(10, -1) + 1e-3 * rng.standard_normal((10, 32))
    return c, truth, y


def test_the_linearised_shadow_is_a_linear_operator_with_its_adjoint():
    """<A x, y> = <x, Aᵀ y> (the adjoint by autograd), and A's columns are the brute-force
    linear term −2 Re(h ∗ e_ij) recorded: one pixel's column from the exact shadow of a faint
    pixel, (I(ε e) − 1)/ε → −2 Re(h ∗ e) as ε → 0."""
    from cssat.occultation import ShadowOperator, shadow
    from cssat.occultation.record import record, smooth

    c = _linear_case()
    op = ShadowOperator((32, 32), **c)
    g = torch.Generator().manual_seed(0)
    x = torch.randn(2, 32 * 32, generator=g, dtype=torch.float64)
    y = torch.randn(2, op.n_out, generator=g, dtype=torch.float64)
    assert float((op(x) * y).sum()) == pytest.approx(float((x * op.adjoint(y)).sum()), rel=1e-10)
    e = torch.zeros(32, 32, dtype=torch.float64)
    e[14, 17] = 1.0
    eps = 1e-6
    geo = {k: c[k] for k in ("positions_m", "velocity_m_s", "times_s")}
    exact = (record(smooth(shadow(eps * e, c["pixel_m"], c["wavelength_m"], c["distance_m"]), c["kernel"]), c["pixel_m"],
                    **geo) - 1) / eps
    assert torch.allclose(op(e.reshape(1, -1))[0], exact.reshape(-1), atol=1e-6 * float(exact.abs().max()))
    with pytest.raises(Exception, match="sigma"):
        ShadowOperator((32, 32), **c, sigma=0.0)


def test_a_faint_occulter_comes_back_through_the_linear_solvers():
    """A semi-transparent (10 %) 2 × 1.5 m plate — a weak occulter, where the linearised model
    holds — recorded by 10 telescopes with 0.1 % noise: TV on the linearised operator recovers
    its support (IoU of the support ≥ 0.7 where the empty estimate scores 0) and its opacity
    (the recovered mean over the plate within 25 % of 0.1)."""
    from cssat.occultation import invert_linear

    c, truth, y = _faint_plate()
    from cssat.recon import TV

    m, info = invert_linear(y, 1e-3, (32, 32), **c, solver=TV(lam=3e-3, method="pdhg", max_iter=800))
    sup = truth > 0
    assert (((m > 0.05) & sup).sum() / ((m > 0.05) | sup).sum()) >= 0.7, info
    assert m[sup].mean() == pytest.approx(0.1, rel=0.25)
    assert info["chi2_per_sample"] < 2.0


def test_the_occultation_rate_against_a_monte_carlo_sky():
    """Stars thrown at the assumed density on a band of sky; the satellite fixed in hour angle;
    a star counts when its separation from the satellite comes within the half-width during the
    night (vectors, not the rate's formula): the count matches per_night to Poisson's 4σ."""
    from cssat.occultation import occultation_rate, stars_brighter_than

    dec0, width_deg, hours = np.radians(-7.0), 0.5, 8.0
    z = 3.85e7
    width_m = np.radians(width_deg) * z
    expect = occultation_rate(12.0, width_m, z, dec_deg=-7.0, night_hours=hours)["per_night"]
    rng = np.random.default_rng(0)
    band = np.radians(1.0)  # stars within ±1° of dec0, all right ascensions
    area = 2 * np.pi * (np.sin(dec0 + band) - np.sin(dec0 - band)) * (180 / np.pi) ** 2
    n = rng.poisson(stars_brighter_than(12.0) * area)
    ra = rng.uniform(0, 2 * np.pi, n)
    dec = np.arcsin(rng.uniform(np.sin(dec0 - band), np.sin(dec0 + band), n))
    # the satellite at hour angle 0: the star's hour angle runs over the night from −hours/2 to +hours/2
    ha_span = np.radians(15.041 * hours)
    ha = (ra + np.pi) % (2 * np.pi) - np.pi  # the star's hour angle at midnight = −(its RA − the LST)
    crosses = np.abs(ha) <= ha_span / 2  # it crosses the satellite's meridian during the night
    sat = np.array([np.cos(dec0), 0.0, np.sin(dec0)])
    star_at_crossing = np.stack([np.cos(dec), np.zeros(n), np.sin(dec)], 1)  # its closest approach, on the meridian
    sep = np.degrees(np.arccos(np.clip(star_at_crossing @ sat, -1, 1)))
    count = int((crosses & (sep <= width_deg / 2)).sum())
    assert abs(count - expect) < 4 * np.sqrt(expect) + 1, (count, expect)
    with pytest.raises(Exception, match="magnitude"):
        stars_brighter_than(20.0)


def test_the_recorded_noise_has_the_stated_variance():
    """A flat series at half the star's light: the sample variance of the noisy series is the
    Poisson + read + scintillation variance (N I + r² + (σ_I N I)²)/N² to 3 %, its mean is I, and
    the assigned 1σ (from the measured counts) has that median to 3 %."""
    from cssat.occultation import noisy, photons
    from cssat.physics.turbulence import scintillation_index

    N = photons(8.0, 0.5, 2e-4)
    s_i2 = scintillation_index(0.5, 1.0, 2e-4)
    I = torch.full((200, 200), 0.5, dtype=torch.float64)
    y, sig = noisy(I, 8.0, 0.5, 2e-4, read_noise_e=3.0, generator=torch.Generator().manual_seed(3))
    var = (N * 0.5 + 9.0 + s_i2 * (N * 0.5) ** 2) / N ** 2
    assert float(y.mean()) == pytest.approx(0.5, abs=4 * math.sqrt(var / y.numel()))
    assert float(y.var()) == pytest.approx(var, rel=0.03)
    assert float(sig.median()) ** 2 == pytest.approx(var, rel=0.03)


def test_edge_width_and_feature_contrast_against_blurred_targets():
    """A square blurred by a Gaussian of σ has the 10–90 % edge width 2 · 1.2816 σ (the normal
    quantiles); a bar target's 0.5 m bars and gaps score contrast 1 in the truth and lose it
    when blurred by σ = 0.3 m (the MTF at their 1 m period: exp(−2π² σ²/1 m²) = 0.17)."""
    from scipy.ndimage import gaussian_filter

    from cssat.occultation import bar_target, edge_width, feature_contrast

    t = np.zeros((128, 128))
    t[30:98, 30:98] = 1
    for sig in (2.0, 4.0):
        assert edge_width(gaussian_filter(t, sig), t, 0.1) == pytest.approx(2 * 1.2816 * sig * 0.1, rel=0.05)
    bars = bar_target(128, 0.1, 0.5)
    assert bars.sum() * 0.01 == pytest.approx(4.0 + 2 * 4 * 0.5 * 4.0, rel=1e-9)  # the bus and 8 bars of 0.5 × 4 m
    perfect = feature_contrast((bars >= 0.5).astype(float), bars, 0.1, 0.5)  # (the target's edges fall mid-pixel)
    assert perfect["gap_contrast"] == 1.0 and perfect["gap_pixels"] > 0
    blurred = feature_contrast(gaussian_filter(bars, 3.0), bars, 0.1, 0.5)
    assert blurred["gap_contrast"] < 0.3
    assert feature_contrast(bars, bars, 0.1, 0.2)["gap_pixels"] == 0  # no gap is as narrow as 0.2 m


def test_a_superellipse_has_its_analytic_area():
    """The area of |u/a|^p + |w/b|^p ≤ 1 is 4ab Γ(1 + 1/p)² / Γ(1 + 2/p): an ellipse (p → 2) πab,
    a near-rectangle (p = 2 + e⁴) almost 4ab; the rendered soft mask's sum matches to 0.5 %, at any angle."""
    from scipy.special import gamma

    from cssat.occultation import render_shapes

    a, b = 2.0, 0.7
    for q in (-4.0, 0.0, 4.0):
        p = 2 + np.exp(q)
        exact = 4 * a * b * gamma(1 + 1 / p) ** 2 / gamma(1 + 2 / p)
        for ang in (0.0, 0.4):
            m = render_shapes([[0.3, -0.2, np.log(a), np.log(b), ang, q]], (120, 120), 0.05)
            assert float(m.sum()) * 0.05 ** 2 == pytest.approx(exact, rel=5e-3)
    two = render_shapes([[-1.0, 0, 0, 0, 0, 0], [1.0, 0, 0, 0, 0, 0]], (100, 100), 0.05)  # two unit discs touching: the union
    assert float(two.max()) == pytest.approx(1.0, abs=1e-6) and float(two.min()) >= 0.0


def test_fit_shapes_recovers_a_box_wing_from_its_shadow():
    """A bus (a 2 × 2 m square) and a wing (6 × 1 m) on 0.25 m pixels at GEO's range, recorded
    by 12 telescopes with 1 % noise; started from a crude mask (the truth dilated by a pixel:
    IoU < 0.85), the superellipses' fit returns IoU ≥ 0.9, the wing's length to 10 %, both
    centres to 0.1 m (0.4 pixel)."""
    from scipy.ndimage import binary_dilation

    from cssat.occultation import fit_shapes, iou, render_shapes, shadow
    from cssat.occultation.record import pattern_kernel, record, smooth

    lam, px, z, N = 550e-9, 0.25, 3.5786e7, 48
    truth = render_shapes([[0.0, 1.5, 0.0, 0.0, 0.0, 4.0], [0.0, -1.5, np.log(3.0), np.log(0.5), np.pi / 2, 4.0]], (N, N), px,
                          softness=0.05).numpy()
    v = np.array([2600.0, 0.0])
    pos = np.stack([np.zeros(12), (np.arange(12) - 5.5) * 0.9], 1)
    times = np.arange(-N / 2, N / 2) * px / 2600.0
    k = pattern_kernel(px, aperture_m=0.5, smear_m=px, smear_dir=(1, 0))
    with torch.no_grad():
        y = record(smooth(shadow(torch.tensor(truth), px, lam, z), k), px, pos, v, times)
    y = y + 0.01 * torch.randn(y.shape, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    crude = binary_dilation(truth >= 0.5, iterations=1).astype(float)
    assert iou(crude, truth) < 0.85
    m, params, info = fit_shapes(y, 0.01, (N, N), px, lam, z, pos, v, times, init_mask=crude, kernel=k)
    assert iou(m, truth) >= 0.9, (info, params)
    wing, bus = (params[0], params[1]) if params[0, 1] < 0 else (params[1], params[0])
    assert max(np.exp(wing[2]), np.exp(wing[3])) == pytest.approx(3.0, rel=0.1)  # the wing's half-length
    assert np.hypot(bus[0], bus[1] - 1.5) < 0.1 and np.hypot(wing[0], wing[1] + 1.5) < 0.1


@pytest.mark.parametrize("name", ["l1", "omp", "landweber"])
def test_the_linear_route_runs_every_solver(name):
    """ℓ1 and OMP in the DCT and Landweber on the same faint plate: each estimate correlates with
    the truth (> 0.7; a blank or random estimate scores ~0) and fits to within 1.6× the noise."""
    from cssat.occultation import invert_linear
    from cssat.recon import L1, OMP, Landweber

    c, truth, y = _faint_plate()
    m, info = invert_linear(y, 1e-3, (32, 32), **c, solver={"l1": L1, "omp": OMP, "landweber": Landweber}[name]())
    assert np.corrcoef(m.ravel(), truth.ravel())[0, 1] > 0.7 and info["chi2_per_sample"] < 1.6
    with pytest.raises(Exception, match="solver: expected a solver object"):
        invert_linear(y, 1e-3, (32, 32), **c, solver="cg")


def test_the_occultation_experiment_names_its_bad_choices_before_any_work(tmp_path):
    from hydra import compose, initialize_config_module

    from cssat._checks import FieldError
    from cssat.experiments import run_experiment

    for bad in ("invert.prior=foo", "silhouette.target=foo", "invert.init=foo", "array.fill=0"):
        with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
            cfg = compose(config_name="config", overrides=["experiment=occultation", bad, "threads=1"])
        field = bad.split("=")[0]
        with pytest.raises(FieldError, match=field.replace(".", r"\.")):
            run_experiment(cfg, tmp_path / field)


def test_registered_iou_finds_a_known_shift_on_a_finer_grid():
    """``registered_iou``: a reconstruction that is the true silhouette (a bus and a tilted panel,
    drawn analytically) displaced by a known (0.73, −1.31) m and drawn on a grid twice as coarse
    scores, on the truth's 0.05 m grid, the shift back to within a quarter of a coarse pixel and an
    IoU near 1 (only the coarse pixels' staircase differs), while unregistered it scores far
    less; a shapeless mask scores 0; bad arguments are refused by name."""
    from cssat._checks import FieldError
    from cssat.occultation import registered_iou

    def draw(n, px, dy, dx):
        c = (np.arange(n) + 0.5 - n / 2) * px
        y, x = np.meshgrid(c - dy, c - dx, indexing="ij")
        bus = (np.abs(x) < 1.2) & (np.abs(y) < 1.6)
        u, v = x * np.cos(0.3) + y * np.sin(0.3), -x * np.sin(0.3) + y * np.cos(0.3)
        panel = (np.abs(u) < 6.0) & (np.abs(v) < 0.9)
        return (bus | panel).astype(float)

    truth = draw(400, 0.05, 0.0, 0.0)  # 20 m across
    rec = draw(200, 0.10, 0.73, -1.31)
    out = registered_iou(rec, truth, pixel_m=0.10, truth_pixel_m=0.05)
    assert abs(out["shift_north_m"] + 0.73) <= 0.025 + 1e-9 and abs(out["shift_east_m"] - 1.31) <= 0.025 + 1e-9, out
    assert out["iou"] > 0.95 and out["iou_unregistered"] < 0.6, out
    assert registered_iou(np.zeros((200, 200)), truth, pixel_m=0.1, truth_pixel_m=0.05)["iou"] == 0.0
    with pytest.raises(FieldError, match="truth_pixel_m"):
        registered_iou(rec, truth, pixel_m=0.1, truth_pixel_m=0.0)
    with pytest.raises(FieldError, match="mask"):
        registered_iou(rec[0], truth, pixel_m=0.1, truth_pixel_m=0.05)


def test_the_polychromatic_shadow_against_a_brute_force_sum_over_wavelengths():
    """Eq. S1: the shadow of a 3 × 1.2 m plate on a 5,800 K star through the V band, on 8
    photon-centroid nodes (``band_wavelengths``), against a brute-force sum over the photon
    spectrum every 0.5 nm, built here from Planck's law and the band's table: agree to 1 % of the
    pattern's contrast, twenty times better than the single wavelength at the band's photon centroid;
    and the Sun's B − V (0.65) gives its 5,772 K within 1 % (Ballesteros 2012)."""
    from cssat.occultation import shadow
    from cssat.occultation.spectrum import band_wavelengths, teff_from_bv
    from cssat.optics.passbands import passband

    assert abs(teff_from_bv(0.65) / 5772.0 - 1) < 0.01
    n, px, z = 96, 0.25, 3.6e7
    c = (np.arange(n) + 0.5 - n / 2) * px
    y, x = np.meshgrid(c, c, indexing="ij")
    mask = torch.as_tensor(((np.abs(x) < 1.5) & (np.abs(y) < 0.6)).astype(np.float64))
    pb = passband("V")
    lam = np.arange(pb.wavelength_nm[0], pb.wavelength_nm[-1] + 0.25, 0.5)
    L = lam * 1e-9
    photons = np.interp(lam, pb.wavelength_nm, pb.throughput) * L / (L ** 5 * np.expm1(6.62607015e-34 * 299792458.0
                                                                                         / (L * 1.380649e-23 * 5800.0)))
    keep = photons > 1e-4 * photons.max()
    brute = shadow(mask, px, L[keep], z, weights=photons[keep], check_sampling=False).numpy()
    nodes, w = band_wavelengths("V", 5800.0, 8)
    poly = shadow(mask, px, nodes, z, weights=w, check_sampling=False).numpy()
    mono = shadow(mask, px, band_wavelengths("V", 5800.0, 1)[0], z, check_sampling=False).numpy()
    contrast = brute.max() - brute.min()
    assert np.abs(poly - brute).max() < 0.01 * contrast
    assert np.abs(mono - brute).max() > 20 * np.abs(poly - brute).max()


def test_ground_and_plane_positions_against_the_projection_by_hand():
    """The fundamental plane seen from the ground (issue 37, point 5): for a star at 31° altitude
    (azimuth 120°), a ground offset towards the star's azimuth is sin 31° = 0.515 as long in the
    plane, one across it unchanged; 25 m along the plane's up-sky axis is 25/sin 31° = 48.5 m on
    the ground; a random layout goes to the plane and back; the up-sky axis is the zenith's
    projection; bad input is refused by name."""
    from cssat._checks import FieldError
    from cssat.occultation import ground_to_plane, plane_to_ground

    alt, az = 31.0, 120.0
    a = np.radians(az)
    towards = np.array([[np.sin(a), np.cos(a)]])
    across = np.array([[np.cos(a), -np.sin(a)]])
    assert np.isclose(np.linalg.norm(ground_to_plane(towards, alt, az)), np.sin(np.radians(alt)))
    assert np.allclose(np.abs(ground_to_plane(across, alt, az)), [[1.0, 0.0]])
    assert np.isclose(np.linalg.norm(plane_to_ground([[0.0, 25.0]], alt, az)), 25.0 / np.sin(np.radians(alt)))
    g = np.random.default_rng(0).normal(size=(7, 2)) * 30
    assert np.allclose(plane_to_ground(ground_to_plane(g, alt, az), alt, az), g)
    up = ground_to_plane([[0.0, 0.0, 1.0]], alt, az)  # a point 1 m up projects up the sky by cos(alt)
    assert np.allclose(up, [[0.0, np.cos(np.radians(alt))]])
    with pytest.raises(FieldError, match="star_alt_deg"):
        ground_to_plane(g, 0.0, az)
    with pytest.raises(FieldError, match="enu_m"):
        ground_to_plane(g[0], alt, az)
