"""The shadow-aware parametric fit's benchmark (benchmarks/bench_shadow_fit.py) at a tiny size, on
a truth that IS in the family: the noise it simulates has the χ² a Gaussian's must; the family
at the true geometry recovers the truth's albedos and its own volume; the fit from the true
geometry stays there at the noise; the fit from the EGI measures what the light curve holds (a
wing's area × albedo) but not, today, the split of the two (a known failure, marked)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

P = np.array([1.0, 0.8, 1.3, 5.0, 1.6, math.radians(35), 0.5, 0.35, 0.15])  # a box-wing, hinge 35°


@pytest.fixture(scope="module")
def rows():
    import bench_shadow_fit as bench

    from cssat.inversion.parametric import box_wing_mesh

    geo = bench.geometry(step_s=600.0)
    assert geo.night.max() == 2 and np.all(np.diff(geo.night) >= 0)  # three nights, in order
    truth = bench.Truth(box_wing_mesh(P, divisions=2), 0, True, P, "in the family")
    res = bench.fit_truth("box_wing", geo, seed=3, floor=0.02, mesh=truth, n_points=20_000,
                          fit_settings=dict(divisions=2, outer=3, inner=30))
    return {r["family"]: r for r in res["rows"]}


def test_the_true_mesh_reaches_the_noise(rows):
    r = rows["no dishes"]
    n = r["n_heldout"]
    assert n >= 30
    # the clean truth against its own noisy data: χ²/n of n unit Gaussians, mean 1, sd sqrt(2/n)
    assert abs(r["true_heldout_chi2"] - 1.0) < 4 * math.sqrt(2 / n)


def test_albedos_at_the_true_geometry(rows):
    r = rows["true geometry, albedos fitted"]
    assert r["iou"] == 1.0  # the same closed box on both sides: every point in one is in the other
    assert r["params"]["cd_bus"] == pytest.approx(P[7], rel=0.03)
    assert r["params"]["cd_panel"] == pytest.approx(P[8], rel=0.03)
    assert r["ratio"] < 1.3


def test_fit_from_the_true_geometry_stays_at_the_noise(rows):
    r = rows["all fitted from the true geometry"]
    assert r["ratio"] < 1.3
    assert abs(r["params"]["hinge"] - P[5]) < math.radians(1)
    assert r["iou"] > 0.9


def test_fit_from_the_egi_measures_area_times_albedo(rows):
    q = rows["no dishes"]["params"]
    # a Lambertian light curve measures a flat wing's area × albedo; sizes and albedos apart only through shadows
    assert q["length"] * q["width"] * q["cd_panel"] == pytest.approx(P[3] * P[4] * P[8], rel=0.1)
    assert set(rows) == {"no dishes", "no dishes, true albedos given", "true geometry, albedos fitted",
                         "all fitted from the true geometry"}


@pytest.mark.xfail(strict=True, reason="known: from the EGI start the fit keeps the start's wing aspect and gap (with the "
                                       "visibility held fixed their gradient is zero) and the size-albedo split of cd0")
def test_fit_from_the_egi_reaches_the_noise(rows):
    assert rows["no dishes"]["ratio"] < 1.5  # in the family: the held-out residual should be the noise's


@pytest.mark.parametrize("name", ["b702_like", "spacebus_like"])
def test_the_platform_truths_closed_volume_is_their_closed_parts(name):
    """The two platforms' closed volume (the IoU's denominator) is the analytic sum of their
    closed parts — the bus, two booms, the deck module or tower and the cylinder (an n-gon prism:
    ``n r² sin(2π/n) / 2 × length``) — and nothing of the zero-thickness wings and dishes; their
    ``nominal`` is a family member of 17 parameters with two dishes."""
    import _platforms
    import bench_shadow_fit as bench

    from cssat.inversion.parametric import param_names

    def prism(r, length, n):
        return n * r**2 * math.sin(2 * math.pi / n) / 2 * length

    expected = {"b702_like": 3.2 * 3.0 * 4.2 + 2 * 0.1 * 1.8 * 0.1 + 1.0 * 1.0 * 0.8 + prism(0.35, 0.6, 16),
                "spacebus_like": 2.2 * 2.0 * 4.6 + 2 * 0.1 * 1.2 * 0.1 + 0.8 * 0.6 * 0.4 + prism(0.05, 1.0, 8)}[name]
    t = bench.truth(name, "materials")
    assert bench.closed_volume(t.mesh) == pytest.approx(expected, rel=1e-9)
    assert t.dishes == 2 and len(t.nominal) == len(param_names(2))
    mesh, _ = getattr(_platforms, name)()
    assert set(np.unique(mesh.cd)) == {_platforms.BUS, _platforms.WING, _platforms.DISH}
    assert np.all(bench.truth(name, "uniform").mesh.cd == 0.3)


@pytest.mark.parametrize("name", ["b702_like", "spacebus_like", "astra_defunct"])
def test_the_finer_familys_truth_parameters_are_the_meshes_parts(name):
    """``Truth.fine``: the finer family at the truth's parameters has the truth's wing area (from
    the meshes' docstrings; on the platforms also their cells' facets) and its closed volume less the parts the family
    leaves out (b702: the engine; spacebus: the omni mast; astra: nothing closed), to round-off;
    and the fine starts keep the fitted wing's span (n panels and n − 1 gaps)."""
    import bench_shadow_fit as bench

    from cssat.inversion.parametric import box_wing_mesh, param_names
    from cssat.inversion.parametric_parts import part_starts

    def prism(r, length, n):
        return n * r**2 * math.sin(2 * math.pi / n) / 2 * length

    t = bench.truth(name, "materials")
    parts, par = t.fine
    fam = box_wing_mesh(np.array(list(par.values())), divisions=2, dish_rings=4, dish_segments=16, **parts)
    left_out = {"b702_like": prism(0.35, 0.6, 16), "spacebus_like": prism(0.05, 1.0, 8), "astra_defunct": 0.0}[name]
    assert bench.closed_volume(fam) == pytest.approx(bench.closed_volume(t.mesh) - left_out, rel=1e-9)
    # two wings of n panels, two-sided: astra 4 of 2.2 x 2.4 m, b702 3 of 2.6 x 3.0, spacebus 4 of 1.9 x 2.2 (docstrings)
    true_wing = {"b702_like": 3 * 2.6 * 3.0, "spacebus_like": 4 * 1.9 * 2.2, "astra_defunct": 4 * 2.2 * 2.4}[name] * 4
    assert fam.areas[fam.part == 1].sum() == pytest.approx(true_wing, rel=1e-9)
    if name != "astra_defunct":  # the platforms' wings are the facets of the cells' albedo
        assert t.mesh.areas[t.mesh.cd == 0.1].sum() == pytest.approx(true_wing, rel=1e-9)
    p9 = np.array([1.0, 1.0, 1.5, 8.0, 2.0, 0.3, 1.0, 0.3, 0.3])
    for _, p in part_starts(p9, parts):
        q = dict(zip(param_names(**parts), p))
        n = parts["wing_panels"]
        assert n * q["length"] + (n - 1) * q["panel_gap"] == pytest.approx(8.0, rel=1e-12)
