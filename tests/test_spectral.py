"""Spectral albedos: colour indices out of the passbands (cssat.optics.passbands.band_coefficients)."""

import math
from pathlib import Path

import numpy as np
import pytest
import torch

import cssat.optics
from cssat._checks import FieldError
from cssat.optics import facet_brightness
from cssat.optics import passbands as pb
from cssat.scene import Mesh, get_model
from cssat.scene.materials import MATERIALS, SPECTRA, SPECTRA_NM, paint

DATA = Path(cssat.optics.__file__).parent / "data"
C = 299_792_458.0


def _plate(material):
    m = Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), 0.5, 0.1)
    return paint(m, material)


def _band(name):
    d = np.loadtxt(DATA / f"band_{name}.txt")
    return d[:, 0], d[:, 1], name in ("g", "r", "i")  # SDSS curves are photon-counting, Bessell's energy


def _brute_ab(name, reflectance=None):
    """AB magnitude of the Sun's light (times a reflectance table) through a band: a 0.1 nm
    trapezoid of its own, ⟨f_ν⟩ = ∫ F T λ^k dλ / ∫ T λ^k c/λ² dλ."""
    wl, sp = np.loadtxt(DATA / "sun_astm_g173_etr_5nm.txt", unpack=True)
    bw, bt, photon = _band(name)
    lam = np.arange(bw[0], bw[-1] + 1e-9, 0.1)
    F = np.interp(lam, wl, sp) * 1e9
    if reflectance is not None:
        F = F * np.interp(lam, SPECTRA_NM, reflectance)
    T = np.interp(lam, bw, bt)
    L = lam * 1e-9
    w = L if photon else np.ones_like(L)
    fnu = np.trapezoid(F * T * w, L) / np.trapezoid(T * w * C / L**2, L)
    return -2.5 * math.log10(fnu / 3631e-26)


def _colour(mesh, b1, b2, system="AB"):
    sun, obs = [[0.0, 0.3, 0.954]], [[0.2, -0.1, 0.975]]
    sun = np.array(sun) / np.linalg.norm(sun)
    obs = np.array(obs) / np.linalg.norm(obs)
    m = []
    for b in (b1, b2):
        f = facet_brightness(mesh, sun, obs, range_km=36000.0, band=b, spectral=True).sum()
        m.append(float(pb.magnitude(f, b, system)))
    return m[0] - m[1]


@pytest.mark.parametrize("material", ["black_paint", "panel_back", "uniform"])
@pytest.mark.parametrize("b1,b2", [("B", "V"), ("V", "R"), ("g", "r"), ("r", "i")])
def test_a_grey_material_has_the_suns_colour(material, b1, b2):
    bands = {"B": pb.bessell_b()}
    got = _colour(_plate(material), bands.get(b1, b1), bands.get(b2, b2))
    assert got == pytest.approx(_brute_ab(b1) - _brute_ab(b2), abs=2e-3)


@pytest.mark.parametrize("material", ["mli", "mli_gold", "solar_cell", "white_paint"])
@pytest.mark.parametrize("b1,b2", [("B", "V"), ("V", "R"), ("g", "r")])
def test_a_coloured_material_differs_from_the_sun_by_its_reflectance_through_the_bands(material, b1, b2):
    """Its colour minus the Sun's is −2.5 log10 of the ratio of its band-averaged reflectances."""
    bands = {"B": pb.bessell_b()}
    R = SPECTRA[material][0]
    want = (_brute_ab(b1, R) - _brute_ab(b2, R)) - (_brute_ab(b1) - _brute_ab(b2))
    got = _colour(_plate(material), bands.get(b1, b1), bands.get(b2, b2)) - (_brute_ab(b1) - _brute_ab(b2))
    assert got == pytest.approx(want, abs=3e-3)


def test_gold_kapton_is_redder_than_the_sun():
    b = pb.bessell_b()
    sun_bv = pb.sun_magnitude(b, "Vega") - pb.sun_magnitude("V", "Vega")
    assert sun_bv == pytest.approx(0.653, abs=0.015)  # the Sun's B−V, Ramírez et al. 2012, ApJ 752, 5
    R = SPECTRA["mli"][0]
    excess = (_brute_ab("B", R) - _brute_ab("V", R)) - (_brute_ab("B") - _brute_ab("V"))
    assert excess > 0.3
    assert _colour(_plate("mli"), b, "V", "Vega") == pytest.approx(sun_bv + excess, abs=3e-3)


def test_grey_by_default_and_the_level_kept():
    mesh = get_model("astra_like")
    sun, obs = [[0.6, 0.0, 0.8]], [[0.5, 0.1, 0.86]]
    obs = np.array(obs) / np.linalg.norm(obs)
    plain = facet_brightness(mesh, sun, obs)
    assert torch.equal(facet_brightness(mesh, sun, obs, band="V"), plain)  # spectral off: the band changes nothing
    assert torch.equal(facet_brightness(mesh, sun, obs, band="V", spectral=False), plain)
    assert not torch.equal(facet_brightness(mesh, sun, obs, band="V", spectral=True), plain)
    # the broadband level: each table's Sun-weighted mean over 300-1100 nm is the factor 1 point
    wl, sp = np.loadtxt(DATA / "sun_astm_g173_etr_5nm.txt", unpack=True)
    for name, (R, _) in SPECTRA.items():
        assert len(R) == len(SPECTRA_NM) and name in MATERIALS
        r = np.interp(wl, SPECTRA_NM, R)
        assert 0 < np.trapezoid(sp * r, wl) / np.trapezoid(sp, wl) <= 1
    with pytest.raises(FieldError, match="spectral"):
        facet_brightness(mesh, sun, obs, band="V", spectral="yes")
