"""Measured BRDF tables (lumos-sat's layout), ABg / binomial scatter and their least-squares fits."""

import numpy as np
import pytest
import torch

from cssat._checks import FieldError
from cssat.inversion.egi import egi_operator
from cssat.optics import CookTorrance, facet_brightness, fit_brdf, fit_brdf_file, read_brdf_table, write_brdf_table
from cssat.scene import panel


def _grid():
    """Incidence 10-60° (azimuth 180°), views -80..80° in and 25° out of the plane: lumos' layout."""
    pin, pout, tout = np.meshgrid([10.0, 30.0, 55.0], np.arange(-78.0, 79.0, 3.0), [0.0, 25.0], indexing="ij")
    return pin.ravel(), np.full(pin.size, 180.0), pout.ravel(), tout.ravel()


def _vec(phi, theta):
    p, t = np.radians(phi), np.radians(theta)
    return np.stack([np.sin(p) * np.cos(t), np.sin(p) * np.sin(t), np.cos(p)], -1)


def _abg_numpy(A, B, g, l, v):
    """Harvey's ABg, written out here: A / (B + |β − β₀|^g), β, β₀ the in-plane parts of v and of l's mirror."""
    beta = v[:, :2]
    beta0 = -l[:, :2]  # the mirror of l about +z has the opposite in-plane part
    return A / (B + np.linalg.norm(beta - beta0, axis=1) ** g)


def _noisy(f, seed=0, rel=0.03):
    return f * np.exp(rel * np.random.default_rng(seed).standard_normal(f.shape))


def test_abg_table_round_trip_and_fit(tmp_path):
    pin, tin, pout, tout = _grid()
    l, v = _vec(pin, tin), _vec(pout, tout)
    true = _abg_numpy(0.05, 2e-3, 1.6, l, v)
    path = tmp_path / "abg.txt"
    write_brdf_table(path, pin, tin, pout, tout, _noisy(true), comment="synthetic ABg\nA=0.05 B=0.002 g=1.6")
    tab = read_brdf_table(path)
    assert len(tab) == len(true) and np.allclose(tab.to_light, l) and np.allclose(tab.to_viewer, v)
    fit = fit_brdf(tab, "abg")
    assert fit.A == pytest.approx(0.05, rel=0.1) and fit.B == pytest.approx(2e-3, rel=0.1) and fit.g == pytest.approx(1.6, rel=0.05)
    n = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    got = fit.evaluate(n, torch.as_tensor(l), torch.as_tensor(v)).numpy()
    assert np.max(np.abs(np.log(got / true))) < 0.05  # within 5 % everywhere
    # the fitted BRDF in the simulation (a one-sided 2 m² plate) and in the inversion's EGI operator
    plate = panel((2, 0, 0), (0, 1, 0), (-1, -0.5, 0), two_sided=False)
    s, o = torch.as_tensor(l[:5]), torch.as_tensor(v[:5])
    b = facet_brightness(plate, s, o, irradiance=1.0, range_km=1e-3, brdf=fit).sum(1).numpy()
    assert np.allclose(b, 2.0 * got[:5] * l[:5, 2] * v[:5, 2], rtol=1e-10)
    G = egi_operator(s, o, np.array([[0.0, 0.0, 1.0]]), fit).matrix().numpy()[:, 0]
    assert np.allclose(G, got[:5] * l[:5, 2] * v[:5, 2], rtol=1e-10)


def test_cook_torrance_fit_recovers_its_parameters(tmp_path):
    pin, tin, pout, tout = _grid()
    l, v = _vec(pin, tin), _vec(pout, tout)
    truth = CookTorrance(kd=0.2, ks=0.5, roughness=0.15, f0=0.9)
    f = truth.evaluate(torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64), torch.as_tensor(l), torch.as_tensor(v)).numpy()
    path = tmp_path / "ct.txt"
    write_brdf_table(path, pin, tin, pout, tout, _noisy(f, seed=1))
    fit = fit_brdf_file(str(path), "cook_torrance", f0=0.9)
    assert fit.kd == pytest.approx(0.2, rel=0.05) and fit.ks == pytest.approx(0.5, rel=0.05)
    assert fit.roughness == pytest.approx(0.15, rel=0.05)


def _binomial_numpy(B, C, d, l1, l, v):
    """lumos-sat's binomial, written out: log10 f = Σ_k (Σ_i B_ki D^i + ½ Σ_i C_ki log10(1 + d^(i+l1) D²)) V^k."""
    rho, rho0 = v[:, :2], -l[:, :2]
    D, V = np.linalg.norm(rho - rho0, axis=1), (rho * rho0).sum(1)
    out = 0.0
    for k in range(B.shape[0]):
        t = sum(B[k, i] * D ** i for i in range(B.shape[1]))
        t = t + 0.5 * sum(C[k, i] * np.log10(1 + d ** (i + l1) * D ** 2) for i in range(C.shape[1]))
        out = out + t * V ** k
    return 10.0 ** out


def test_binomial_fit_reproduces_the_table(tmp_path):
    pin, tin, pout, tout = _grid()
    l, v = _vec(pin, tin), _vec(pout, tout)
    true = _binomial_numpy(np.array([[0.5, -1.0]]), np.array([[-1.5]]), 300.0, 1, l, v)
    path = tmp_path / "bin.txt"
    write_brdf_table(path, pin, tin, pout, tout, _noisy(true, seed=2, rel=0.01))
    fit = fit_brdf(read_brdf_table(path), "binomial", binomial=(1, 2, 1, 2))
    got = fit.evaluate(torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64), torch.as_tensor(l), torch.as_tensor(v)).numpy()
    assert np.median(np.abs(np.log(got / true))) < 0.02 and np.max(np.abs(np.log(got / true))) < 0.1
    assert fit.d == pytest.approx(300.0, rel=0.2) and fit.C[0, 0] == pytest.approx(-1.5, rel=0.1)
    assert np.allclose(fit.B, [[0.5, -1.0]], atol=0.1)


def test_a_missing_table_names_its_path(tmp_path):
    with pytest.raises(FieldError, match="^path: no such file"):
        read_brdf_table(tmp_path / "none.txt")


@pytest.mark.parametrize("text, field", [
    ("# phi_in theta_in phi_out theta_out brdf\n10 180 5 0\n", "^path: .*line 2: expected 5 columns"),
    ("phi_in theta_in phi_out theta_out brdf\n10 180 95 0 0.1\n", "^phi_out: .*within \\(-90, 90\\)"),
    ("10 180 5 0 -0.1\n", "^brdf: .*must be > 0"),
    ("10 180 5 0 0.1\n10 180 x 0 0.1\n", "^path: .*line 2: not numbers"),
])
def test_table_errors_name_the_field(tmp_path, text, field):
    bad = tmp_path / "bad.txt"
    bad.write_text(text)
    with pytest.raises(FieldError, match=field):
        read_brdf_table(bad)


def test_an_unknown_model_is_refused(tmp_path):
    good = tmp_path / "good.txt"
    good.write_text("10 180 5 0 0.1\n")
    with pytest.raises(FieldError, match="^model: expected one of"):
        fit_brdf_file(str(good), "gaussian")
