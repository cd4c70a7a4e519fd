"""Passbands and magnitude systems against published solar magnitudes, a quadrature written here and
closed forms (cssat.optics.passbands)."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.optics import passbands as pb

DIST_MOD_1AU = 5 * math.log10(149_597_870.7 / 3.0856775814913673e14)  # 1 AU in units of 10 pc


@pytest.mark.parametrize("band, system, published", [
    # Willmer (2018, ApJS 236, 47): M_V = 4.81 (Vega) and 4.80 (AB) in its abstract; apparent AB
    # magnitudes of Tables 3-4 (Johnson V -26.77, Cousins R -26.97, SDSS g -26.47, r -26.93, i -27.05)
    ("V", "Vega", 4.81 + DIST_MOD_1AU), ("V", "AB", 4.80 + DIST_MOD_1AU), ("V", "AB", -26.77), ("R", "AB", -26.97),
    ("g", "AB", -26.47), ("r", "AB", -26.93), ("i", "AB", -27.05)])
def test_the_suns_magnitude_matches_willmer_2018(band, system, published):
    assert pb.sun_magnitude(band, system) == pytest.approx(published, abs=0.03)


def test_vega_minus_ab_in_v_is_willmers():
    # the same Sun in V: Vega 4.81, AB 4.80 (Willmer 2018), so m_AB(Vega) in V is about -0.01
    assert pb.passband("V").vega_ab == pytest.approx(-0.01, abs=0.01)
    assert pb.sun_magnitude("V", "Vega") - pb.sun_magnitude("V", "AB") == pytest.approx(0.01, abs=0.01)


def test_a_grey_object_is_the_sun_dimmed_and_the_inverse_round_trips():
    m = pb.magnitude(torch.tensor([1361e-10, 1361e-12, 0.0], dtype=torch.float64), "g", "AB")
    m_sun = pb.sun_magnitude("g", "AB")
    assert m[0].item() == pytest.approx(m_sun + 25.0, abs=1e-12) and m[1].item() == pytest.approx(m_sun + 30.0, abs=1e-12)
    assert math.isinf(m[2].item())
    back = pb.flux_from_magnitude(m[:2], "g", "AB")
    assert torch.allclose(back, torch.tensor([1361e-10, 1361e-12], dtype=torch.float64), rtol=1e-12)


def test_ab_at_a_wavelength_is_a_narrow_band_through_the_sun():
    for lam in (450.0, 532.0, 800.0):
        top_hat = pb.Passband("narrow", np.array([lam - 1.0, lam - 0.99, lam + 0.99, lam + 1.0]), np.array([0, 1, 1, 0.0]))
        assert pb.ab_magnitude_at(1361.0, lam).item() == pytest.approx(pb.sun_magnitude(top_hat, "AB"), abs=0.005)
    # lumos-sat's convention: the whole flux as nu f_nu at 532 nm, f_nu = F lambda / c
    F = 1360.0
    assert pb.ab_magnitude_at(F, 532.0, "bolometric").item() == pytest.approx(
        -2.5 * math.log10(F * 532e-9 / 299_792_458.0 / 3631e-26), abs=1e-12)


def test_a_measured_filter_file_is_used(tmp_path):
    wl, t = pb.passband("V").wavelength_nm, pb.passband("V").throughput
    f = tmp_path / "my_V.csv"
    f.write_text("# lambda_nm, percent\n" + "\n".join(f"{a}, {100 * b}" for a, b in zip(wl, t)))
    mine = pb.Passband.from_file(f, photon=False, vega_ab=pb.passband("V").vega_ab)
    assert mine.name == "my_V"
    assert pb.sun_magnitude(mine, "Vega") == pytest.approx(pb.sun_magnitude("V", "Vega"), abs=1e-12)
    red = tmp_path / "red.txt"  # a different curve gives a different (redder: brighter for the Sun) magnitude
    red.write_text("\n".join(f"{a + 100} {b}" for a, b in zip(wl, t)))
    assert pb.sun_magnitude(pb.Passband.from_file(red, photon=False), "AB") < pb.sun_magnitude("V", "AB") - 0.1
    with pytest.raises(FieldError, match="system.*no Vega zero point"):
        pb.sun_magnitude(pb.Passband.from_file(red), "Vega")
    tail = tmp_path / "qe.txt"  # a QE curve to 1200 nm: its faint tail past the solar table is cut, a big one refused
    tail.write_text("400 0.5\n700 0.9\n1090 0.2\n1200 0.001\n")
    assert pb.Passband.from_file(tail).throughput[-1] == 0.0
    tail.write_text("400 0.5\n700 0.9\n1100 0.8\n1300 0.8\n")
    with pytest.raises(FieldError, match="passband: qe: .* outside the solar spectrum"):
        pb.Passband.from_file(tail)
    bad = tmp_path / "bad.txt"
    bad.write_text("500 1\n490 x\n")
    with pytest.raises(FieldError, match="passband"):
        pb.Passband.from_file(bad)


def test_bad_band_and_system_are_refused_by_name():
    with pytest.raises(FieldError, match=r"band: expected one of \['V', 'R', 'g', 'r', 'i', 'clear'\]"):
        pb.magnitude(1.0, "B")
    with pytest.raises(FieldError, match="system: expected one of"):
        pb.magnitude(1.0, "V", "ST")
    with pytest.raises(FieldError, match="wavelength_nm"):
        pb.ab_magnitude_at(1.0, 2000.0)


def test_lambert_sphere_phase_function_against_a_quadrature_over_the_sphere():
    # flux from a Lambertian sphere: the integral of (n.s)+ (n.v)+ over the sphere, by midpoint
    # quadrature in (theta, phi) written here, normalised at full phase
    th = (np.arange(400) + 0.5) * np.pi / 400
    ph = (np.arange(800) + 0.5) * 2 * np.pi / 800
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    dA = np.sin(T)

    def flux(alpha):
        s, v = np.array([0, 0, 1.0]), np.array([np.sin(alpha), 0, np.cos(alpha)])
        return np.sum(np.clip(n @ s, 0, None) * np.clip(n @ v, 0, None) * dA)

    for a in (30.0, 90.0, 150.0):
        assert pb.lambert_sphere_phase(a).item() == pytest.approx(flux(math.radians(a)) / flux(0.0), abs=2e-4)


def test_std_magnitude_removes_range_and_lambert_phase():
    m = torch.tensor([8.0, 8.0])
    out = pb.std_magnitude(m, torch.tensor([2000.0, 1000.0]), torch.tensor([90.0, 0.0]))
    assert out[0].item() == pytest.approx(8.0 - 5 * math.log10(2.0), abs=1e-12)
    assert out[1].item() == pytest.approx(8.0 + 2.5 * math.log10(math.pi), abs=1e-12)  # full phase is pi x brighter
    assert pb.std_magnitude(m, 500.0, phase_function="none")[0].item() == pytest.approx(8.0 + 5 * math.log10(2.0))
    with pytest.raises(FieldError, match="phase_deg"):
        pb.std_magnitude(m, 1000.0)
    with pytest.raises(FieldError, match="range_km"):
        pb.std_magnitude(m, 0.0, 90.0)


def test_the_tables_ship_in_the_wheel():
    root = Path(__file__).resolve().parents[1]
    spec = re.search(r'"cssat\.optics\.data" = \[(.*?)\]', (root / "pyproject.toml").read_text()).group(1)
    for f in (root / "cssat/optics/data").iterdir():
        if f.suffix in (".txt", ".md"):
            assert f'"*{f.suffix}"' in spec, f.name
    assert (root / "cssat/optics/data/__init__.py").is_file()


def test_a_light_curves_band_converts_its_magnitudes(tmp_path):
    from cssat.data import read_light_curve

    f = tmp_path / "lc.csv"
    f.write_text("time_utc,magnitude,filter\n2020-04-01T21:00:00Z,10.0,r\n2020-04-01T21:00:30Z,11.0,r\n")
    legacy = read_light_curve(f).fluxes()  # no band: V with the Sun at -26.74, as before
    assert np.allclose(legacy, 1361.0 * 10 ** (-0.4 * (np.array([10.0, 11.0]) + 26.74)), rtol=1e-12)
    own = read_light_curve(f, band="file", band_system="AB")  # the file's filter column: SDSS r
    assert own.band[0].name == "r"
    expect = 1361.0 * 10 ** (-0.4 * (np.array([10.0, 11.0]) - pb.sun_magnitude("r", "AB")))
    assert np.allclose(own.fluxes(), expect, rtol=1e-12)
    assert np.allclose(own.rows([1]).fluxes(), expect[1:], rtol=1e-12)  # kept by a subset
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("time_utc,magnitude,filter\n2020-04-01T21:00:00Z,10.0,V\n2020-04-01T21:00:30Z,11.0,R\n")
    with pytest.raises(FieldError, match=r"observations.band: band 'file' needs one filter.*\['R', 'V'\]"):
        read_light_curve(mixed, band="file")
    with pytest.raises(FieldError, match="observations.band: expected one of"):  # before the (missing) file is read
        read_light_curve(tmp_path / "absent.csv", band="B")
    with pytest.raises(FieldError, match="observations.band: band 'clear' has no Vega zero point"):
        read_light_curve(f, band="clear")


def test_earthshine_in_the_simulated_light_curve_is_the_earthshine_term():
    from cssat.optics import simulate_light_curve
    from cssat.scene import make_scenario
    from cssat.optics.earthshine import earthshine_brightness
    from cssat.scene.attitude import nadir_pointing_frame

    from cssat.scene.mesh import Mesh

    sc = make_scenario(start_utc="2020-04-01T21:00:00", n_steps=2, step_s=600.0)
    box = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])  # a cube, outward faces
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4],
             [1, 5, 7], [1, 7, 3]]
    mesh = Mesh(box, np.array(faces), np.full(12, 0.5), np.full(12, 0.2))
    assert bool(((mesh.centroids * mesh.normals).sum(1) > 0).all())
    plain = simulate_light_curve(mesh, sc, shadows=False)
    lit = simulate_light_curve(mesh, sc, shadows=False, earthshine=True, earth_albedo=0.3)
    es = earthshine_brightness(mesh, sc.r_sat, sc.r_sun, sc.r_obs, rotation=nadir_pointing_frame(sc.r_sat, sc.v_sat))
    es = es * torch.as_tensor(sc.elevation_deg > 0, dtype=es.dtype)[:, None]
    assert float(es.sum()) > 0 and torch.allclose(lit.facets - plain.facets, es, rtol=1e-9, atol=0)
