"""Real satellite materials (cssat.scene.materials) on the procedural models (issue 36)."""

import math

import numpy as np
import pytest

from cssat._checks import FieldError
from cssat.optics import facet_brightness
from cssat.scene import astra_like, box, get_model, merge, tess_like
from cssat.scene.materials import MATERIALS, paint

#: solar absorptance α, Fortescue, Swinerd & Stark, Spacecraft Systems Engineering 4th ed. (2011), Table 11.3
TABLE_11_3 = {"solar_cell": 0.88, "mli": 0.40, "mli_gold": 0.25, "osr": 0.07, "white_paint": 0.12,
              "aluminium": 0.24, "black_paint": 0.95}


def test_materials_reflect_what_they_do_not_absorb():
    for name, alpha in TABLE_11_3.items():  # an opaque surface reflects 1 - α of the sunlight
        m = MATERIALS[name]
        assert m.cd + m.cs == pytest.approx(1 - alpha, abs=1e-9), name
        assert m.alpha == alpha
    for m in MATERIALS.values():
        assert 0 <= m.cd and 0 <= m.cs and m.cd + m.cs <= 1 and 0 < m.roughness <= 1
    assert 0.04 <= MATERIALS["solar_cell"].cs <= 0.125  # DOE/ER-0081 (1980): cells' specular reflectance


def test_astra_like_wears_its_materials():
    a = astra_like(array_angle_deg=90.0)
    uni = astra_like(material="uniform", array_angle_deg=90.0)
    assert np.array_equal(a.vertices, uni.vertices) and np.array_equal(a.faces, uni.faces)
    names = np.array(a.part_names)[a.part]
    for n in set(names):
        assert np.all(a.cd[names == n] == MATERIALS[n].cd) and np.all(a.cs[names == n] == MATERIALS[n].cs)
    bus = np.arange(len(a)) < 6 * 4 * 4 * 2  # the bus is built first: 6 faces of 4 x 4 cells, 2 triangles each
    side = np.abs(a.normals[:, 1]) > 0.9
    assert set(names[bus & side]) == {"osr"} and set(names[bus & ~side]) == {"mli"}
    # at a 90° array angle the cells face +z (the Earth, where the Sun is at local midnight)
    cells = names == "solar_cell"
    assert np.allclose(a.normals[cells], [0, 0, 1], atol=1e-9)
    assert a.areas[cells].sum() == pytest.approx(2 * 4 * 2.4 * 2.2)
    back = (names == "panel_back") & (a.normals[:, 2] < -1 + 1e-9)  # the wings' backs face -z (dishes' backs do not)
    assert a.areas[back].sum() == pytest.approx(2 * 4 * 2.4 * 2.2)


def test_diffuse_flux_follows_the_materials():
    # away from any glint, Eq. 8 is Σ A cd (s·n)(v·n)/(π r²) over the lit, seen facets: brute force here
    m = tess_like()
    s = np.array([0.6, 0.3, 0.74])
    s /= np.linalg.norm(s)
    v = np.array([0.5, -0.6, 0.62])
    v /= np.linalg.norm(v)
    got = facet_brightness(m, s[None], v[None], irradiance=1.0).numpy()[0]
    sn, vn = m.normals @ s, m.normals @ v
    want = np.where((sn > 0) & (vn > 0), m.areas * m.cd * sn * vn / math.pi, 0.0) / 1e6  # range 1 km = 1e3 m
    assert np.allclose(got, want, rtol=1e-12, atol=1e-300)
    uni = get_model("tess_like", material="uniform")
    ratio = facet_brightness(uni, s[None], v[None], irradiance=1.0).sum() / got.sum()
    assert float(ratio) > 3  # the paper's cd = 0.8 everywhere is far brighter than the real surfaces


def test_parts_survive_merge_and_scale():
    painted = paint(box((1, 1, 1)), "osr")
    both = merge([painted, box((1, 1, 1), center=(3, 0, 0))])
    assert both.part_names == ("osr", "default") and list(np.bincount(both.part)) == [12, 12]
    assert merge([box((1, 1, 1))]).part is None  # no parts in: none out (the old meshes, unchanged)
    big = get_model("astra_like", scale=2.0)
    assert big.part_names == astra_like().part_names and np.array_equal(big.part, astra_like().part)


def test_material_errors():
    with pytest.raises(FieldError, match="^material: expected one of"):
        get_model("astra_like", material="shiny")
    with pytest.raises(FieldError, match="^cd: a uniform cd"):
        get_model("astra_like", material="satellite", cd=0.5)
    with pytest.raises(FieldError, match="^material: expected one of"):
        paint(box((1, 1, 1)), "chrome")
    assert np.all(get_model("tess_like", cd=0.5).cd == 0.5)  # cd alone: the old uniform model


def test_a_brdf_per_material():
    from cssat.optics import Lambert

    m = tess_like()
    s, v = np.array([0.6, 0.0, 0.8]), np.array([0.0, 0.6, 0.8])
    got = facet_brightness(m, s[None], v[None], irradiance=1.0, brdf={"mli": Lambert(0.2), "default": Lambert(0.5)}).numpy()[0]
    albedo = np.where(np.array(m.part_names)[m.part] == "mli", 0.2, 0.5)
    sn, vn = m.normals @ s, m.normals @ v
    want = np.where((sn > 0) & (vn > 0), m.areas * albedo / math.pi * sn * vn, 0.0) / 1e6
    assert np.allclose(got, want, rtol=1e-12, atol=1e-300)
