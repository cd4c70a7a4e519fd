"""Tests at the seams between layers, where a bug passes every unit test on either side: no
held-out sample in any fit of the inversion experiment, the weights of duplicate-stamp merging,
χ²/N from the data's own scatter when no errors are given, and the band quadrature's nodes and
weights (and a passband's mean flux density) against brute-force sums written here. Each test was
checked to fail on a one-line bug injected at its seam."""

from __future__ import annotations

import csv

import numpy as np
import pytest

H_J_S, C_M_S, K_J_K = 6.62607015e-34, 299_792_458.0, 1.380649e-23


# ---------------------------------------------------------------------------------------------
# no held-out sample enters any fit of the inversion experiment


def _perturbed_copy(src, dst, seed=1):
    """``src`` (the experiment's ``lightcurve.csv``) with every sample after the first gap of
    over 6 h (the held-out night: ``nights.fit=1``) changed wildly — fluxes scaled by factors
    0.05–20 drawn at random and their 1σ by 7 — the first night's rows as they were. Returns
    the held-out mask, found here from the time stamps alone."""
    rows = list(csv.DictReader(src.open()))
    t = np.array([np.datetime64(r["time_utc"].rstrip("Z"), "ms") for r in rows])
    gap = np.flatnonzero(np.diff(t) > np.timedelta64(6, "h"))
    assert gap.size == 1, "the simulation should span two nights"
    held = np.arange(len(rows)) > gap[0]
    rng = np.random.default_rng(seed)
    for r, h in zip(rows, held):
        if h:
            r["flux_W_m2"] = repr(float(r["flux_W_m2"]) * float(np.exp(rng.uniform(-3, 3))))
            r["flux_err_W_m2"] = repr(float(r["flux_err_W_m2"]) * 7.0)
    with dst.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return held


#: the searched spin and the box-wing at a tiny size: every fit of the experiment runs
SEARCHED = ["inversion.spin=search", "inversion.n_poles=8", "inversion.n_starts=1", "inversion.n_refine=1",
            "inversion.coarse_normals=16", "inversion.coarse_samples=64", "inversion.max_samples=200",
            "inversion.search_normals=64", "inversion.min_period_s=1200", "inversion.max_period_s=6000",
            "inversion.shape=parametric", "inversion.parametric.outer=1", "inversion.parametric.inner=3",
            "inversion.parametric.divisions=1"]
READ_FLUX = ["observed.kind=flux", "observed.value_col=flux_W_m2", "observed.error_col=flux_err_W_m2"]
#: the metrics of the fits (the spin search, the EGI, the box-wing, the geometry's observability)
FITTED = ("spin_", "lc_", "egi_", "inversion_", "parametric_", "convex_fit_", "fit_", "observability_", "shape_volume")
#: what tests a fit on the held-out nights (estimate_spin's verdict) and the 1σ it withholds when unreliable
VERDICT = ("heldout", "verdict", "err_deg", "pole_interval")


def test_no_held_out_sample_enters_any_fit(tmp_path, inversion_sim):
    """The inversion experiment fits the first ``nights.fit`` nights and predicts the others:
    a measured light curve whose held-out night is changed wildly (fluxes ×0.05–20, errors ×7)
    gives bit-identical fits — the searched spin, the EGI's normals and areas, the box-wing, the
    model on every sample (a prediction from the fit and the geometry alone) — while the
    held-out residuals and the spin's verdict on the held-out night change (the changed samples
    were read, by what tests the fit and by nothing that makes it)."""
    from cssat.experiments import run_experiment
    from conftest import cfg_of

    src = inversion_sim[1] / "lightcurve.csv"
    held = _perturbed_copy(src, tmp_path / "perturbed.csv")
    common = ["experiment=inversion", "nights.n=2", "nights.fit=1", "scenario.step_s=600", "inversion.n_normals=64",
              "threads=1", *SEARCHED, *READ_FLUX]
    a = run_experiment(cfg_of(*common, f"observations={src}"), tmp_path / "a")
    b = run_experiment(cfg_of(*common, f"observations={tmp_path / 'perturbed.csv'}"), tmp_path / "b")
    assert a["status"] == b["status"] == "ok" and a["spin"] == "search" and a["shape"] == "parametric"
    assert a["n_fit"] == b["n_fit"] == int((~held).sum()) and a["n_heldout"] == int(held.sum()) > 0
    fa, fb = np.load(tmp_path / "a" / "arrays.npz"), np.load(tmp_path / "b" / "arrays.npz")
    np.testing.assert_array_equal(fa["fit"], ~held)
    assert not np.array_equal(fa["flux"][held], fb["flux"][held])  # the perturbation was read
    np.testing.assert_array_equal(fa["flux"][~held], fb["flux"][~held])
    for key in ("normals", "areas", "sun_body", "obs_body", "model", "singular_values", "leverage"):
        np.testing.assert_array_equal(fa[key], fb[key], err_msg=key)
    # the held-out nights test the fitted spin (its verdict, and the 1σ a verdict of "unreliable"
    # withholds): those keys read them; every other key of a fit must not
    fitted = sorted(k for k in a if k.startswith(FITTED) and not any(w in k for w in VERDICT))
    assert {"spin_pole_lon_deg", "spin_pole_lat_deg", "spin_period_s", "spin_chi2", "egi_area_m2", "fit_rms",
            "parametric_a"} <= set(fitted)
    changed = {k: (a[k], b.get(k)) for k in fitted if not (a[k] == b.get(k) or a[k] != a[k] and b.get(k) != b.get(k))}
    assert not changed, changed
    assert a["heldout_rms"] != b["heldout_rms"]
    if "spin_heldout_n" in a:  # the verdict read the held-out night
        assert a["spin_heldout_n"] == int(held.sum()) and a["spin_heldout_chi2"] != b["spin_heldout_chi2"]


# ---------------------------------------------------------------------------------------------
# duplicate time stamps: the inverse-variance mean and its 1σ


def test_duplicate_stamps_merge_to_the_inverse_variance_mean_and_its_error(tmp_path):
    """Samples of one stamp (groups of 1–4, errors spread over a factor 20, one row repeated
    exactly) merge to ``Σ wᵢ yᵢ / Σ wᵢ`` with ``wᵢ = 1/σᵢ²`` and ``1σ = (Σ wᵢ)^-½``, computed
    here; without errors to the plain mean (no error invented); refused by default."""
    from cssat._checks import FieldError
    from cssat.data import read_light_curve

    rng = np.random.default_rng(11)
    t0 = np.datetime64("2021-03-01T22:00:00.000", "ms")
    rows, want = [], []
    for k, n in enumerate([1, 3, 2, 1, 4, 2, 3]):
        stamp = str(t0 + np.timedelta64(1500 * k, "ms"))
        v = rng.uniform(1.0, 5.0, n) * 1e-13
        e = rng.uniform(0.05, 1.0, n) * 1e-14
        group = list(zip(v, e))
        if k == 2:  # an exact repeat of a row: the same measurement twice, counted once
            rows.append((stamp, v[0], e[0]))
        rows += [(stamp, vi, ei) for vi, ei in group]
        w = 1.0 / e ** 2
        want.append((stamp, float((w * v).sum() / w.sum()), float(w.sum() ** -0.5), float(v.mean())))
    f = tmp_path / "dup.csv"
    f.write_text("time_utc,flux,flux_err\n" + "".join(f"{s},{float(v)!r},{float(e)!r}\n" for s, v, e in rows))
    lc = read_light_curve(f, kind="flux", value_col="flux", error_col="flux_err", duplicates="merge")
    assert len(lc) == len(want) and lc.meta.get("duplicates_dropped") == 1
    np.testing.assert_array_equal(lc.times_utc, np.array([np.datetime64(s, "us") for s, *_ in want]))
    np.testing.assert_allclose(lc.values, [w[1] for w in want], rtol=1e-12)
    np.testing.assert_allclose(lc.errors, [w[2] for w in want], rtol=1e-12)
    # the merged 1σ is below each member's: more measurements, a smaller error
    assert all(lc.errors[i] <= min(e for s, _, e in rows if s == want[i][0]) for i in range(len(want)))
    # no errors: the plain mean (the repeated row dropped first), and no 1σ made up
    g = tmp_path / "dup_noerr.csv"
    g.write_text("time_utc,flux\n" + "".join(f"{s},{float(v)!r}\n" for s, v, _ in rows))
    plain = read_light_curve(g, kind="flux", value_col="flux", duplicates="merge")
    assert plain.errors is None
    np.testing.assert_allclose(plain.values, [w[3] for w in want], rtol=1e-12)
    with pytest.raises(FieldError, match=r"duplicate time stamp") as err:
        read_light_curve(f, kind="flux", value_col="flux", error_col="flux_err")
    assert err.value.field == "observations.time_utc[row 3]"


def test_channels_sharing_a_stamp_are_kept_and_each_channel_merges_its_own(tmp_path):
    """An MMT track (no errors): channel 2 and channel 3 at one stamp are both kept; two samples
    of channel 2 at one stamp merge to their mean, in channel 2."""
    from cssat.data import read_light_curve

    head = ("# satellite: 48243 ONEWEB-0208 / UK\n# catalogue: 1 NORAD\n# variability: 0 Not variable\n"
            "# variability_period: None\n# type: 0 U/SAT Uncertain Satellite\n# npoints: 6\n#\n"
            "# Date Time StdMag Mag Filter Penumbra Distance Phase Channel Track\n")
    data = [("23:25:50.100", 7.9, 2), ("23:25:50.100", 8.3, 3), ("23:25:50.200", 7.5, 2), ("23:25:50.200", 7.8, 2),
            ("23:25:50.300", 7.0, 3), ("23:25:50.300", 7.4, 3)]
    f = tmp_path / "track.txt"
    f.write_text(head + "".join(f"2021-06-11 {t} {m + 0.4:.3f} {m:.3f} Clear 0 860.0 85.4 {c} 19284160\n"
                                for t, m, c in data))
    lc = read_light_curve(f, value_col="StdMag", duplicates="merge")
    got = sorted(zip(lc.times_utc.astype(str), lc.channels.astype(str), np.round(lc.values, 9)))
    want = sorted([("2021-06-11T23:25:50.100000", "2", 8.3), ("2021-06-11T23:25:50.100000", "3", 8.7),
                   ("2021-06-11T23:25:50.200000", "2", round((7.9 + 8.2) / 2, 9)),
                   ("2021-06-11T23:25:50.300000", "3", round((7.4 + 7.8) / 2, 9))])
    assert got == want


# ---------------------------------------------------------------------------------------------
# χ²/N without given errors: the data's own white-noise scatter


def _white(sigma, seed, n=3000, step=5.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * step + rng.uniform(-0.5, 0.5, n)
    return t, rng.normal(0.0, sigma, n)


@pytest.mark.parametrize("sigma", [0.003, 0.05])
def test_light_curve_scatter_is_the_white_noise_sigma_under_a_smooth_signal(sigma):
    """``light_curve_scatter`` on white noise of known σ: σ within 6 % (3000 samples: the MAD's
    own 1σ is ~2 %); under a smooth signal 100× larger (a 600 s sinusoid at a jittered 5 s
    cadence: its slope leaks a few % into the second differences) and glints on 1 % of the
    samples, within 15 % — while the plain standard deviation is 70× off."""
    from cssat.inversion.period import light_curve_scatter

    t, e = _white(sigma, seed=int(sigma * 1e4))
    assert light_curve_scatter(t, e) == pytest.approx(sigma, rel=0.06)
    y = 100 * sigma * np.sin(2 * np.pi * t / 600.0) + e
    y[::97] += 50 * sigma  # glints: 1 % of the samples
    assert light_curve_scatter(t, y) == pytest.approx(sigma, rel=0.15)
    assert np.std(y) > 30 * sigma


def test_chi2_per_sample_without_errors_is_one_for_the_right_model_and_large_for_a_wrong_one():
    """``estimate_period`` with no ``sigma``: χ² is the residual in units of the data's own
    white-noise scatter (``noise_sigma``). A 3-harmonic curve in noise of known σ: χ²/N within
    10 % of 1 and ``noise_sigma`` within 8 % of σ; the residual's χ² computed here with the true
    σ agrees. The same curve fitted with one harmonic (a wrong model): χ²/N ≫ 1 — a χ² scaled by
    the residual's own spread would say 1 for any model, one scaled by the data's standard
    deviation ≪ 1; with the true σ given, the same χ²/N within the scatter's own error."""
    from cssat.inversion import estimate_period

    sigma, P = 0.01, 437.0
    t, e = _white(sigma, seed=5)
    ph = 2 * np.pi * t / P
    y = 1.0 + 0.3 * np.cos(ph) + 0.15 * np.sin(2 * ph + 0.4) + 0.1 * np.cos(3 * ph + 1.0) + e
    r = estimate_period(t, y, min_period_s=100, max_period_s=2000, n_surrogates=4)
    assert r["period_s"] == pytest.approx(P, rel=1e-3) and r["n_harmonics"] >= 3
    assert r["noise_sigma"] == pytest.approx(sigma, rel=0.08)
    assert r["chi2_per_sample"] == pytest.approx(1.0, abs=0.1)
    nu = len(t) - 2 * r["n_harmonics"] - r["n_nuisance"]
    assert r["chi2_per_sample"] == pytest.approx(r["rss"] / sigma ** 2 / nu, rel=0.13)  # the true σ's χ²/ν
    wrong = estimate_period(t, y, min_period_s=100, max_period_s=2000, max_harmonics=1, n_surrogates=4)
    assert wrong["noise_sigma"] == pytest.approx(sigma, rel=0.08)
    # at most two harmonics of P (one of P/2 — the BIC takes the half period's first): the third
    # (amplitude 0.1) is left, 0.1²/2 of variance: χ²/N ≈ 1 + 0.005/σ² = 51
    assert 35 < wrong["chi2_per_sample"] < 70
    given = estimate_period(t, y, sigma=sigma, min_period_s=100, max_period_s=2000, max_harmonics=1, n_surrogates=4)
    assert wrong["chi2_per_sample"] == pytest.approx(given["chi2_per_sample"], rel=0.13)


# ---------------------------------------------------------------------------------------------
# the band quadrature's nodes and weights, and a passband's mean flux density, by brute force


def _photons(band, teff_k, step_nm):
    """Eq. S1's photon spectrum written here: the band's table interpolated linearly × Planck ×
    λ, on a ``step_nm`` grid over the table."""
    from cssat.optics.passbands import passband

    pb = passband(band)
    lo, hi = float(pb.wavelength_nm[0]), float(pb.wavelength_nm[-1])
    lam = np.linspace(lo, hi, int(round((hi - lo) / step_nm)) + 1)
    L = lam * 1e-9
    return lam, np.interp(lam, pb.wavelength_nm, pb.throughput) * L / (L ** 5 * np.expm1(H_J_S * C_M_S / (L * K_J_K * teff_k)))


@pytest.mark.parametrize("band, teff_k", [("V", 5800.0), ("r", 3500.0), ("clear", 10000.0), ("i", 5800.0)])
def test_band_nodes_and_weights_against_a_brute_force_sum(band, teff_k):
    """``band_wavelengths``: on the support where the photons pass 0.1 % of their peak (the
    documented rule, applied here on the 0.5 nm table), cut into n equal bins, each node is its
    bin's photon centroid and each weight its bin's photon share, both summed here every 0.01 nm;
    one node is the band's photon centroid; the nodes reproduce the photon-mean wavelength, and
    their quadrature of a smooth function of λ (1/λ², a diffraction pattern's cos(2πa/λ)) improves
    from 1 node to 8 towards the brute-force value."""
    from cssat.occultation.spectrum import band_wavelengths

    coarse, Nc = _photons(band, teff_k, 0.5)
    on = Nc >= 1e-3 * Nc.max()
    lo, hi = coarse[on][0], coarse[on][-1]
    lam, N = _photons(band, teff_k, 0.01)
    sel = (lam >= lo - 1e-9) & (lam <= hi + 1e-9)
    x, y = lam[sel], N[sel]
    total = np.trapezoid(y, x)

    def mean(f):
        return float(np.trapezoid(f(x) * y, x) / total)

    fns = {"lambda": lambda v: v, "1/lambda^2": lambda v: 1.0 / v ** 2, "fresnel": lambda v: np.cos(2 * np.pi * 1500.0 / v)}
    errors = {}
    for n in (1, 2, 4, 8):
        nodes, w = band_wavelengths(band, teff_k, n)
        nodes = nodes * 1e9  # m -> nm
        assert nodes.shape == w.shape == (n,) and abs(w.sum() - 1) < 1e-12 and (w > 0).all()
        edges = np.linspace(lo, hi, n + 1)
        for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            inside = (x >= a) & (x <= b)
            share = np.trapezoid(y[inside], x[inside]) / total
            centroid = np.trapezoid(y[inside] * x[inside], x[inside]) / np.trapezoid(y[inside], x[inside])
            assert a <= nodes[i] <= b, (n, i, nodes[i], a, b)
            assert abs(nodes[i] - centroid) < 0.3, (n, i, nodes[i], centroid)  # nm: the 0.5 nm table's resolution
            assert abs(w[i] - share) < 2e-3, (n, i, w[i], share)
        assert float(w @ nodes) == pytest.approx(mean(fns["lambda"]), rel=2e-4)
        if n == 1:
            assert nodes[0] == pytest.approx(mean(fns["lambda"]), rel=1e-6)
        errors[n] = {k: abs(float(w @ f(nodes)) - mean(f)) for k, f in fns.items()}
    for k in fns:
        if k != "lambda":
            assert errors[8][k] < 0.2 * errors[1][k] + 1e-12, (k, errors)


@pytest.mark.parametrize("band", ["V", "g", "clear"])
def test_mean_flux_density_against_a_brute_force_integral(band):
    """Eq. P2 for three spectra (the Sun, a 3,500 K blackbody, a power law F_λ ∝ λ⁻⁴) through a
    photon band (g, clear) and an energy band (V), against the integral summed here every 0.01 nm;
    and a flat f_ν spectrum gives back its own f_ν whatever the band."""
    from cssat.optics.passbands import passband, sun_spectrum

    pb = passband(band)
    lam = np.arange(pb.wavelength_nm[0], pb.wavelength_nm[-1] + 1e-9, 0.01)
    T = np.interp(lam, pb.wavelength_nm, pb.throughput)
    L = lam * 1e-9
    k = L if pb.photon else np.ones_like(L)
    sun_l, sun_f = sun_spectrum()
    grid = np.arange(300.0, 1100.5, 1.0)
    G = grid * 1e-9
    spectra = {"sun": (sun_l, sun_f), "3500 K": (grid, 1e-30 / (G ** 5 * np.expm1(H_J_S * C_M_S / (G * K_J_K * 3500.0)))),
               "lambda^-4": (grid, 2.0 * (G / 550e-9) ** -4)}
    for name, (sl, sf) in spectra.items():
        F = np.interp(lam, sl, sf) * 1e9  # W m⁻² nm⁻¹ -> per m
        want = np.trapezoid(F * T * k, L) / np.trapezoid(T * k * C_M_S / L ** 2, L)
        assert pb.mean_flux_density(sl, sf) == pytest.approx(want, rel=2e-4, abs=0), name
    fnu = 3.0e-26  # W m⁻² Hz⁻¹ (3 Jy): f_λ = f_ν c / λ², per nm
    fine = np.arange(290.0, 1110.0, 0.05)
    assert pb.mean_flux_density(fine, fnu * C_M_S / (fine * 1e-9) ** 2 * 1e-9) == pytest.approx(fnu, rel=1e-4, abs=0)
