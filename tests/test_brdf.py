"""Issue 23: BRDF families against physics (reciprocity, energy, the Lambert sphere's phase law)
and against scalar implementations written here from the papers' formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from cssat._checks import FieldError


def _models():
    from cssat.optics.brdf import AshikhminShirley, BlinnPhong, CookTorrance, Lambert, Phong

    return [Lambert(0.7), Phong(0.4, 0.5, 30.0), BlinnPhong(0.3, 0.6, 80.0), CookTorrance(0.2, 0.8, 0.25, 0.95),
            AshikhminShirley(0.5, 0.2, 60.0)]


def _unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("model", _models(), ids=lambda m: m.name)
def test_helmholtz_reciprocity(model):
    rng = np.random.default_rng(0)
    n, l, v = _unit(rng, 500), _unit(rng, 500), _unit(rng, 500)
    a, b = model.evaluate(n, l, v), model.evaluate(n, v, l)
    assert torch.allclose(a, b, rtol=1e-12, atol=1e-15)
    assert (a >= 0).all() and (a > 0).any()


def _hemisphere(nt=600, nphi=1200):
    th = (np.arange(nt) + 0.5) * (math.pi / 2) / nt
    ph = (np.arange(nphi) + 0.5) * 2 * math.pi / nphi
    T, P = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    dw = (np.sin(T) * (math.pi / 2 / nt) * (2 * math.pi / nphi)).reshape(-1)
    return v, dw


@pytest.mark.parametrize("model", _models(), ids=lambda m: m.name)
def test_energy_conservation_by_quadrature(model):
    """The directional albedo ∫ f (n·v) dω_v ≤ 1 at every incidence (a 600 × 1200 midpoint rule
    on the hemisphere)."""
    v, dw = _hemisphere()
    n = np.array([0.0, 0.0, 1.0])
    for deg in (0, 30, 60, 80):
        l = np.array([math.sin(math.radians(deg)), 0.0, math.cos(math.radians(deg))])
        f = model.evaluate(n, l, v).numpy()
        albedo = float((f * v[:, 2] * dw).sum())
        assert 0 < albedo <= 1.0 + 2e-3, (model.name, deg, albedo)


def test_white_furnace_lambert():
    from cssat.optics.brdf import Lambert

    v, dw = _hemisphere(300, 600)
    f = Lambert(1.0).evaluate([0, 0, 1.0], [0.3, 0.0, math.sqrt(1 - 0.09)], v).numpy()
    assert float((f * v[:, 2] * dw).sum()) == pytest.approx(1.0, abs=2e-5)


def test_the_lambert_sphere_phase_law():
    """A Lambert sphere's flux against the phase angle α: (sin α + (π − α) cos α)/π of full
    phase (Russell 1916), summed over 200,000 equal-area patches."""
    from cssat.optics.brdf import Lambert

    N = 200_000
    k = np.arange(N) + 0.5
    z = 1 - 2 * k / N
    phi = math.pi * (1 + 5 ** 0.5) * k
    r = np.sqrt(1 - z * z)
    normals = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
    dA = 4 * math.pi / N
    l = np.array([0.0, 0.0, 1.0])
    vals = []
    for a in np.radians([0.0, 30.0, 60.0, 90.0, 120.0, 150.0]):
        v = np.array([math.sin(a), 0.0, math.cos(a)])
        f = Lambert(1.0).evaluate(normals, l, v).numpy()
        vals.append(float((f * (normals @ l).clip(0) * (normals @ v).clip(0)).sum() * dA))
    vals = np.array(vals) / vals[0]
    a = np.radians([0.0, 30.0, 60.0, 90.0, 120.0, 150.0])
    assert np.allclose(vals, (np.sin(a) + (math.pi - a) * np.cos(a)) / math.pi, atol=2e-3)


def _scalar(model, n, l, v):
    """The models' formulas, one triple at a time, in plain Python."""
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))  # noqa: E731
    nl, nv = dot(n, l), dot(n, v)
    if nl <= 0 or nv <= 0:
        return 0.0
    hv = [a + b for a, b in zip(l, v)]
    hn = math.sqrt(dot(hv, hv))
    h = [x / hn for x in hv]
    nh = max(dot(n, h), 0.0)
    name = model.name
    if name == "lambert":
        return model.albedo / math.pi
    if name == "phong":
        r = [2 * nl * a - b for a, b in zip(n, l)]
        return model.kd / math.pi + model.ks * (model.shininess + 2) / (2 * math.pi) * max(dot(r, v), 0) ** model.shininess
    if name == "blinn_phong":
        return model.kd / math.pi + model.ks * (model.shininess + 8) / (8 * math.pi) * nh ** model.shininess
    if name == "cook_torrance":
        a2 = model.roughness ** 2
        D = a2 / (math.pi * (nh ** 2 * (a2 - 1) + 1) ** 2)
        G = (2 * nl / (nl + math.sqrt(a2 + (1 - a2) * nl ** 2))) * (2 * nv / (nv + math.sqrt(a2 + (1 - a2) * nv ** 2)))
        F = model.f0 + (1 - model.f0) * (1 - dot(v, h)) ** 5
        return model.kd / math.pi + model.ks * D * G * F / (4 * nl * nv)
    if name == "ashikhmin_shirley":
        hl = dot(h, l)
        F = model.rs + (1 - model.rs) * (1 - hl) ** 5
        spec = (model.n + 1) / (8 * math.pi) * nh ** model.n / (hl * max(nl, nv)) * F
        diff = 28 * model.rd / (23 * math.pi) * (1 - model.rs) * (1 - (1 - nl / 2) ** 5) * (1 - (1 - nv / 2) ** 5)
        return diff + spec
    raise AssertionError(name)


@pytest.mark.parametrize("model", _models(), ids=lambda m: m.name)
def test_each_model_against_its_formula_written_out(model):
    rng = np.random.default_rng(7)
    n, l, v = _unit(rng, 200), _unit(rng, 200), _unit(rng, 200)
    got = model.evaluate(n, l, v).numpy()
    want = np.array([_scalar(model, *map(list, t)) for t in zip(n, l, v)])
    assert np.allclose(got, want, rtol=1e-10, atol=1e-14)


def test_the_papers_brdf_gives_the_papers_facet_brightness():
    """E A f (n·l)(n·v)/r² with PaperBRDF equals facet_brightness (Eq. 8–9, its own code)."""
    from cssat.optics import facet_brightness
    from cssat.optics.brdf import PaperBRDF
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
    from cssat.scene import box

    mesh = box((2.0, 1.0, 0.5), cd=0.6, cs=0.3)
    rng = np.random.default_rng(1)
    sun, obs = _unit(rng, 300), _unit(rng, 300)
    obs[:3] = 2 * (sun[:3] @ np.array([0, 0, 1.0]))[:, None] * np.array([0, 0, 1.0]) - sun[:3]  # exact glints off +z
    ref = facet_brightness(mesh, sun, obs, range_km=1000.0).numpy()
    N = mesh.normals
    f = PaperBRDF(0.6, 0.3).evaluate(N[None], sun[:, None], obs[:, None]).numpy()
    mine = SOLAR_IRRADIANCE_W_M2 * mesh.areas * f * (sun @ N.T).clip(0) * (obs @ N.T).clip(0) / 1e12
    assert np.allclose(mine, ref, rtol=1e-6, atol=0)  # the mesh stores float32 normals and areas
    assert (ref[:3].max(1) > 1e3 * np.median(ref[ref > 0])).all()  # the glints are in


def test_device_and_dtype_follow_the_input():
    from cssat.optics.brdf import CookTorrance

    n = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float32)
    out = CookTorrance().evaluate(n, torch.tensor([0.0, 0.6, 0.8]), torch.tensor([0.6, 0.0, 0.8]))
    assert out.dtype == torch.float32 and out.shape == ()


@pytest.mark.parametrize("make, field", [
    (lambda B: B.Lambert(1.5), "albedo"), (lambda B: B.Phong(0.7, 0.5), "ks"),
    (lambda B: B.CookTorrance(roughness=0.0), "roughness"), (lambda B: B.BlinnPhong(shininess=-1), "shininess"),
])
def test_bad_parameters_name_their_field(make, field):
    import cssat.optics.brdf as B

    with pytest.raises(FieldError) as err:
        make(B)
    assert err.value.field == field


def test_facet_brightness_with_a_brdf_and_materials():
    """E A f (S·N)(V·N)/r² per facet; two materials split by face index; the paper's default
    path unchanged."""
    from cssat.optics import facet_brightness
    from cssat.optics.brdf import Lambert, Phong
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
    from cssat.scene import box

    mesh = box((2.0, 1.0, 0.5), cd=0.6, cs=0.0)
    rng = np.random.default_rng(4)
    sun, obs = _unit(rng, 50), _unit(rng, 50)
    N, A = mesh.normals.astype(np.float64), mesh.areas.astype(np.float64)
    sn, vn = (sun @ N.T).clip(0), (obs @ N.T).clip(0)
    lam = facet_brightness(mesh, sun, obs, range_km=1.0, brdf=Lambert(0.6)).numpy()
    assert np.allclose(lam, SOLAR_IRRADIANCE_W_M2 * A * 0.6 / math.pi * sn * vn / 1e6, rtol=1e-6)
    paper = facet_brightness(mesh, sun, obs, range_km=1.0).numpy()  # cs = 0: the paper's is Lambert too
    assert np.allclose(lam, paper, rtol=1e-6)
    mat = np.arange(len(mesh)) % 2
    mixed = facet_brightness(mesh, sun, obs, range_km=1.0, brdf=[Lambert(0.6), Phong(0.2, 0.7, 10.0)], materials=mat).numpy()
    phong = facet_brightness(mesh, sun, obs, range_km=1.0, brdf=Phong(0.2, 0.7, 10.0)).numpy()
    assert np.allclose(mixed[:, mat == 0], lam[:, mat == 0]) and np.allclose(mixed[:, mat == 1], phong[:, mat == 1])
    with pytest.raises(FieldError) as err:
        facet_brightness(mesh, sun, obs, brdf=[Lambert(), Lambert()], materials=[0, 1])
    assert err.value.field == "materials"


@pytest.mark.parametrize("option", ["mesh", "paper", "lambert", "phong", "blinn_phong", "cook_torrance", "ashikhmin_shirley"])
def test_every_brdf_option_runs_the_light_curve_experiment(tmp_path, option):
    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=lightcurve", f"brdf={option}", "attitude=spin",
                                                       "scenario.n_steps=6", "scenario.step_s=600", "render.size=8",
                                                       "threads=1"])
    met = run_experiment(cfg, tmp_path)
    assert met["status"] == "ok" and met["brdf"] == option and met["magnitude_min"] is not None


def _two_body_scene():
    import trimesh

    a = trimesh.creation.box((2.0, 1.0, 1.0))
    a.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(name="bus"))
    b = trimesh.creation.box((4.0, 0.05, 1.0))
    b.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(name="array"))
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="bus_node")
    scene.add_geometry(b, node_name="array_node", transform=trimesh.transformations.translation_matrix([0, 3.0, 0]))
    return scene, a, b


def test_a_trimesh_scene_and_a_glb_load_with_their_bodies(tmp_path):
    from cssat.scene import as_mesh, load_mesh

    scene, a, b = _two_body_scene()
    mesh = as_mesh(scene)
    assert len(mesh) == len(a.faces) + len(b.faces) and set(mesh.part_names) == {"bus", "array"}
    arr = mesh.part == mesh.part_names.index("array")
    assert np.allclose(mesh.centroids[arr].mean(0), [0, 3.0, 0])  # the node's transform applied
    assert mesh.areas.sum() == pytest.approx(a.area + b.area)
    (tmp_path / "sat.glb").write_bytes(scene.export(file_type="glb"))
    glb = load_mesh(tmp_path / "sat.glb", center=False)
    assert len(glb) == len(mesh) and set(glb.part_names) == {"bus", "array"}
    assert glb.areas.sum() == pytest.approx(mesh.areas.sum())


def test_a_brdf_per_part_name():
    from cssat.optics import facet_brightness
    from cssat.optics.brdf import CookTorrance, Lambert
    from cssat.scene import as_mesh

    mesh = as_mesh(_two_body_scene()[0])
    rng = np.random.default_rng(9)
    sun, obs = _unit(rng, 40), _unit(rng, 40)
    by_name = facet_brightness(mesh, sun, obs, brdf={"bus": Lambert(0.5), "array": CookTorrance()}).numpy()
    arr = mesh.part == mesh.part_names.index("array")
    assert np.allclose(by_name[:, ~arr], facet_brightness(mesh, sun, obs, brdf=Lambert(0.5)).numpy()[:, ~arr])
    assert np.allclose(by_name[:, arr], facet_brightness(mesh, sun, obs, brdf=CookTorrance()).numpy()[:, arr])
    with pytest.raises(FieldError, match="missing"):
        facet_brightness(mesh, sun, obs, brdf={"bus": Lambert(0.5)})
