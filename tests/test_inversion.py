"""Issue 24: the EGI sensing operator against the light curve computed facet by facet."""

from __future__ import annotations

import numpy as np
import pytest
import torch


def _views(T=300, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, T, 3))
    return v / np.linalg.norm(v, axis=2, keepdims=True)


@pytest.mark.parametrize("model", ["astra_like", "tess_like", "box"])
def test_a_meshs_shadowless_light_curve_is_the_egi_operator_times_its_egi(model):
    """facet_brightness (Eq. 8–9, cs = 0, no shadows) per unit irradiance and range, summed over
    facets, equals G @ a for the mesh's EGI — to round-off."""
    from dataclasses import replace

    from cssat.inversion import egi, egi_operator
    from cssat.optics import facet_brightness
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
    from cssat.scene import box, get_model

    mesh = box((1.5, 1.0, 0.7), divisions=2) if model == "box" else get_model(model)
    mesh = replace(mesh, cs=np.zeros(len(mesh)), _cache={})  # the Lambertian part: linear in the EGI
    s, o = _views()
    y = facet_brightness(mesh, s, o, range_km=1e-3).sum(1).numpy() / SOLAR_IRRADIANCE_W_M2  # r = 1 m
    normals, areas = egi(mesh)
    G = egi_operator(s, o, normals)
    assert np.allclose(G(torch.as_tensor(areas)[None])[0].numpy(), y, rtol=1e-9, atol=1e-15)
    assert areas.sum() == pytest.approx(float((mesh.areas * mesh.cd).sum()), rel=1e-12)


def test_the_operator_is_linear_batched_and_has_its_adjoint():
    from cssat.inversion import egi_operator, fibonacci_sphere

    s, o = _views(50, 1)
    N = fibonacci_sphere(200)
    G = egi_operator(s, o, N)
    a = torch.rand(3, 200, dtype=torch.float64)
    y = torch.rand(3, 50, dtype=torch.float64)
    assert torch.allclose((G(a) * y).sum(1), (a * G.adjoint(y)).sum(1), rtol=1e-12)  # ⟨Ga, y⟩ = ⟨a, Gᵀy⟩
    assert G.matrix().shape == (50, 200) and (G.matrix() >= 0).all()


def test_the_fibonacci_sphere_is_uniform():
    from cssat.inversion import fibonacci_sphere

    N = fibonacci_sphere(4000).numpy()
    assert np.allclose(np.linalg.norm(N, axis=1), 1.0)
    assert np.abs(N.mean(0)).max() < 1e-3  # no preferred direction
    # equal area: the fraction of points in a polar cap equals the cap's area fraction (1 − cos θ)/2
    for deg in (10, 45, 90):
        frac = (N[:, 2] > np.cos(np.radians(deg))).mean()
        assert frac == pytest.approx((1 - np.cos(np.radians(deg))) / 2, abs=1e-3)
