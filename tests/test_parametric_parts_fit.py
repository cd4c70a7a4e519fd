"""The finer family's starts and fit (cssat.inversion.parametric_parts): the starts' geometry
against the mesh builder's own mirror pair and the axis formula, the albedo prior's exact
degeneracy (the same shadowed light curve), the fit on a truth in the family against the plain
box-wing's, and the errors' fields."""

import math

import numpy as np
import pytest

P9 = np.array([1.1, 1.0, 2.3, 1.9, 2.2, -0.7, 1.2, 0.45, 0.2])


def _unit(rng, n):
    x = rng.normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1)[:, None]


def _axis(tilt, azimuth):
    return np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)])


def test_a_free_pairs_start_is_the_mirror_pair_and_a_flip_reverses_each_axis():
    """The free pair's mirror start builds the mesh the family's own mirror pair builds (the
    builder mirrors through the y–z plane itself); ``flip`` reverses each dish's axis vector; the
    dish starts sit on the fitted bus's faces as documented; a split wing keeps the fitted span."""
    from cssat.inversion.parametric import box_wing_mesh, param_names
    from cssat.inversion.parametric_parts import dish_starts, part_starts

    free = dict(dishes=2, dish_pair="free", wing_panels=3, booms=True)
    mirror = dict(free, dish_pair="mirror")
    kw = dict(divisions=1, dish_rings=3, dish_segments=8)
    for (label, pf), (label_m, pm) in zip(part_starts(P9, free), part_starts(P9, mirror)):
        assert label == label_m
        vf = box_wing_mesh(pf, **kw, **free).vertices
        vm = box_wing_mesh(pm, **kw, **mirror).vertices
        np.testing.assert_allclose(np.sort(vf.round(9), axis=0), np.sort(vm.round(9), axis=0), atol=1e-9)
        q = dict(zip(param_names(**free), pf))
        assert 3 * q["length"] + 2 * q["panel_gap"] == pytest.approx(P9[3], rel=1e-12)
    names = param_names(**free)
    for (_, p), (_, pf) in zip(part_starts(P9, free)[::1], part_starts(P9, free, flip=True)[1::2]):
        q, qf = dict(zip(names, p)), dict(zip(names, pf))
        for pre in ("dish", "dish2"):
            np.testing.assert_allclose(_axis(qf[f"{pre}_tilt"], qf[f"{pre}_azimuth"]),
                                       -_axis(q[f"{pre}_tilt"], q[f"{pre}_azimuth"]), atol=1e-12)
    a, b, c = P9[:3]
    one = dict(dish_starts(P9, 1))
    for label, centre, out in (("+z face", (0, 0, c), (0, 0, 1)), ("-z face", (0, 0, -c), (0, 0, -1)),
                               ("+x face", (a, 0, 0), (1, 0, 0)), ("-x face", (-a, 0, 0), (-1, 0, 0))):
        d = one[label][9:]
        np.testing.assert_allclose(d[:3], centre, atol=1e-12)
        np.testing.assert_allclose(_axis(d[3], d[4]), out, atol=1e-12)
        assert d[5] == pytest.approx(0.6 * (a + b + c) / 3) and d[6] == pytest.approx(0.3 * d[5])


def test_the_albedo_prior_rescale_keeps_the_shadowed_light_curve():
    """``with_albedo_prior``: every length times s and every albedo over s² gives the same light
    curve at the same visibility, and Embree casts the same visibility at both scales (the
    family's exact size–albedo degeneracy), with the bus albedo at the prior; the free pair's
    paired starts hold every combination of the generic placements, the diagonal the mirror starts."""
    import torch

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility, param_names
    from cssat.inversion.parametric_parts import part_starts, with_albedo_prior

    parts = dict(dishes=2, dish_pair="free", wing_panels=3, booms=True, deck=True)
    names = param_names(**parts)
    p = part_starts(P9, parts)[0][1]
    q = with_albedo_prior(p, names, cd_bus=0.3)
    s = math.sqrt(0.45 / 0.3)
    assert dict(zip(names, q))["cd_bus"] == pytest.approx(0.3, rel=1e-12)
    assert dict(zip(names, q))["a"] == pytest.approx(1.1 * s, rel=1e-12)
    rng = np.random.default_rng(0)
    S, V = _unit(rng, 60), _unit(rng, 60)
    kw = dict(divisions=2, dish_rings=4, dish_segments=16, **parts)
    vis = [box_wing_visibility(x, S, V, **kw) for x in (p, q)]
    # the cast agrees but where a cell's centroid lies on another part's face (the deck on the bus): Embree's
    # ray offset is absolute, so there the grazing ray's verdict depends on the scale
    assert float((vis[0] == vis[1]).double().mean()) > 0.999
    y = [box_wing_light_curve(torch.as_tensor(x), S, V, vis[0], range_km=1e-3, irradiance=1.0, **kw).numpy()
         for x in (p, q)]
    np.testing.assert_allclose(y[1], y[0], rtol=1e-10)
    paired = part_starts(P9, parts, pairs=True)
    plain = part_starts(P9, parts)
    assert len(paired) == 9 and len(plain) == 3
    for k in range(3):
        np.testing.assert_array_equal(paired[4 * k][1], plain[k][1])
    assert len({tuple(x) for _, x in paired}) == 9


def test_fit_parts_finds_a_dish_the_plain_box_wing_cannot_hold():
    """A truth in the family (a box-wing with one dish on its +z face, cast shadows, 2 % noise,
    Sun and observer anywhere): the plain box-wing fitted from the truth's own bus and wings misses
    it by 4σ; ``fit_parts`` from that fit picks the +z start by its brief loss, reaches 1.3σ (the
    truth's own ≈ 0.94σ), and reports every start's brief loss, lowest first."""
    import torch

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility
    from cssat.inversion.parametric_fit import fit_box_wing
    from cssat.inversion.parametric_parts import fit_parts

    truth = np.r_[1.0, 0.9, 1.2, 4.0, 1.5, math.radians(25.0), 0.6, 0.3, 0.2, 0.0, 0.0, 1.2, 0.0, 0.0, 0.8, 0.25, 0.6]
    kw = dict(panels=2, divisions=1, dish_rings=3, dish_segments=10)
    rng = np.random.default_rng(1)
    S, V = _unit(rng, 120), _unit(rng, 120)
    vis = box_wing_visibility(truth, S, V, dishes=1, **kw)
    clean = box_wing_light_curve(torch.as_tensor(truth), S, V, vis, range_km=1e-3, irradiance=1.0, dishes=1,
                                 **kw).numpy()
    sigma = 0.02 * clean + 0.002 * float(np.median(clean))
    y = clean + sigma * rng.normal(size=len(clean))
    p9, plain = fit_box_wing(y, S, V, truth[:9], sigma=sigma, outer=2, inner=40, **kw)
    p, info = fit_parts(y, S, V, p9, dict(dishes=1), sigma=sigma, brief=dict(outer=1, inner=15), outer=2, inner=60,
                        albedos="profile", **kw)
    assert plain["rms_over_noise"] > 3.5
    assert info["rms_over_noise"] < 2.0
    assert info["params"]["dish_z"] > 1.0 and info["start"] == "+z face"
    losses = [loss for _, loss in info["briefs"]]
    assert [lab for lab, _ in info["briefs"]][0] == info["start"] and losses == sorted(losses) and len(losses) == 4
    assert info["loss"] <= losses[0]
    assert info["fulls"] == [(info["start"], info["loss"])]  # keep=1: the best brief, fitted in full
    np.testing.assert_array_equal(p, np.array(list(info["params"].values())))


def test_the_parts_errors_name_their_field():
    from cssat.inversion.parametric import param_names
    from cssat.inversion.parametric_parts import dish_starts, fit_parts, part_starts, with_albedo_prior

    with pytest.raises(ValueError, match="flip"):
        part_starts(P9, dict(dishes=2, dish_pair="free"), flip=True, pairs=True)
    with pytest.raises(ValueError, match="p9"):
        part_starts(P9[:8], dict(dishes=1))
    with pytest.raises(ValueError, match="dishes"):
        dish_starts(P9, 3)
    with pytest.raises(ValueError, match="dish_pair"):
        part_starts(P9, dict(dishes=2, dish_pair="sideways"))
    with pytest.raises(ValueError, match="cd_bus"):
        with_albedo_prior(P9, param_names(), cd_bus=0.0)
    with pytest.raises(ValueError, match="names"):
        with_albedo_prior(P9, param_names()[:5])
    with pytest.raises(ValueError, match="starts"):
        fit_parts(np.ones(5), np.ones((5, 3)), np.ones((5, 3)), P9, dict(dishes=1), starts=[])
    with pytest.raises(ValueError, match="keep"):
        fit_parts(np.ones(5), np.ones((5, 3)), np.ones((5, 3)), P9, dict(dishes=1), keep=0)


def test_the_experiments_stage_fits_the_finer_family_when_asked(caplog):
    """``inversion.parametric.dishes`` (and the other parts) reach the stage: with ``dishes=1`` its
    metrics hold the dish's parameters, its mesh a dish part, and its prediction is the family's
    light curve at those parameters recomputed here with the asked cells (a stage that dropped the
    parts anywhere would predict another curve); without, the plain box-wing's nine; where the
    finer family's fit ends above the plain one's loss (a local minimum: it holds the plain one),
    the plain one is kept, said in ``parametric_family`` and a warning; bad settings are refused
    by their key. (Whether the finer family fits better is the benchmarks' question:
    BENCHMARKS.md, "A finer family".)"""
    from types import SimpleNamespace

    import torch

    from cssat._checks import FieldError
    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility, param_names
    from cssat.models.egi.config import ParametricConfig

    for bad, key in ((dict(dishes=3), "dishes"), (dict(dishes=1, dish_pair="free"), "dish_pair"),
                     (dict(dish_pair="left"), "dish_pair"), (dict(wing_panels=0), "wing_panels"),
                     (dict(booms="yes"), "booms"), (dict(dish_rings=0), "dish_rings"), (dict(parts_keep=0), "parts_keep"),
                     (dict(parts_pairs=True), "parts_pairs"), (dict(dishes=2, parts_pairs=True), "parts_pairs"),
                     (dict(dishes=2, dish_pair="free", parts_pairs="yes"), "parts_pairs"),
                     (dict(parts_from="sideways"), "parts_from")):
        with pytest.raises(FieldError, match=rf"inversion\.parametric\.{key}"):
            ParametricConfig(**bad)
    assert ParametricConfig().parts() == {} and ParametricConfig().family() == dict(panels=2, divisions=4)
    assert ParametricConfig(dishes=2, dish_pair="free", deck=True).parts() == dict(dishes=2, dish_pair="free", deck=True)
    truth = np.r_[1.0, 0.9, 1.2, 4.0, 1.5, math.radians(25.0), 0.6, 0.3, 0.2, 0.0, 0.0, 1.2, 0.0, 0.0, 0.8, 0.25, 0.6]
    kw = dict(panels=2, divisions=1, dish_rings=3, dish_segments=10, dishes=1)
    N, A = egi(box_wing_mesh(truth, **kw))
    fit = np.arange(160) < 110
    for seed, dishes, family in ((1, 0, "plain"), (1, 1, "parts"), (2, 1, "plain")):
        rng = np.random.default_rng(seed)
        S, V = _unit(rng, 160), _unit(rng, 160)
        clean = box_wing_light_curve(torch.as_tensor(truth), S, V, box_wing_visibility(truth, S, V, **kw),
                                     range_km=1e-3, irradiance=1.0, **kw).numpy()
        sigma = 0.02 * clean + 0.002 * float(np.median(clean))
        y = clean + sigma * rng.normal(size=len(clean))
        m = SimpleNamespace(fit=fit, held=~fit, sigma=sigma, y=y, night=(~fit).astype(int))
        a = SimpleNamespace(sun_b=S, obs_b=V, metrics={"spin": "known"})
        sol = SimpleNamespace(res=SimpleNamespace(normals=N, areas=A), model_unit=np.zeros(160), metrics={})
        caplog.clear()
        solve_parametric(ParametricConfig(divisions=1, outer=2, inner=40, dishes=dishes, dish_rings=3, dish_segments=10),
                         m, a, sol)
        assert sol.metrics["parametric_family"] == family
        assert sol.metrics["parametric_parts_start"] == ("+z face" if family == "parts" else None)
        assert ("ended above the plain box-wing's loss" in caplog.text) == (dishes and family == "plain")
        parts = family != "plain"
        names = param_names(1 if parts else 0)
        assert sol.metrics["parametric_start_aspect"] == pytest.approx(3.75)  # the one default start's
        assert {k for k in sol.metrics if k.startswith("parametric_")} - {"parametric_yaw_deg", "parametric_family",
                                                                              "parametric_parts_start",
                                                                              "parametric_parts_base",
                                                                              "parametric_shadow_resolution_m",
                                                                              "parametric_start_aspect"} == \
            {f"parametric_{k}" for k in names}
        assert ("dish" in sol.param_mesh.part_names) == parts
        p = np.array([sol.metrics[f"parametric_{k}"] for k in names])
        fam = dict(panels=2, divisions=1, **(dict(dishes=1, dish_rings=3, dish_segments=10) if parts else {}))
        again = box_wing_light_curve(torch.as_tensor(p), S, V, box_wing_visibility(p, S, V, **fam), range_km=1e-3,
                                     irradiance=1.0, **fam).numpy()
        np.testing.assert_allclose(sol.model_unit, again, rtol=1e-12)
        rms = math.sqrt(float(np.mean((y[fit] - again[fit]) ** 2)))
        assert sol.metrics["fit_rms"] == pytest.approx(rms, rel=1e-9)


def test_the_log_line_says_which_family_was_kept():
    from cssat.experiments.forward.egi import EGILightCurve

    base = dict(n_samples=676, n_nights_observed=3, egi_n_normals=33, heldout_rms_over_noise=1.32)
    lines = {fam: EGILightCurve.headline(None, dict(base, **({"parametric_family": fam} if fam else {})), None)
             for fam in ("parts", "plain", None)}
    assert "EGI 33 normals, the box-wing with its parts, held-out rms 1.32× noise" in lines["parts"]
    assert "EGI 33 normals, the box-wing, held-out rms" in lines["plain"]
    assert "EGI 33 normals, held-out rms" in lines[None]


def test_the_experiments_stage_polishes_and_predicts_with_resolved_shadows():
    """``inversion.parametric.shadow_resolution_m``: the stage's prediction is the fitted box-wing's
    light curve with each sub-facet's lit fraction from rays that far apart (recomputed here), not
    the one-ray-a-cell curve; the truth here is resolved too, and the resolved polish fits it no
    worse than the unresolved stage; a bad value is refused by its key."""
    from types import SimpleNamespace

    import torch

    from cssat._checks import FieldError
    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility, param_names
    from cssat.models.egi.config import ParametricConfig

    for bad in (0, -1.0, "fine"):
        with pytest.raises(FieldError, match=r"inversion\.parametric\.shadow_resolution_m"):
            ParametricConfig(shadow_resolution_m=bad)
    truth = np.r_[1.0, 0.9, 1.2, 4.0, 1.5, math.radians(25.0), 0.6, 0.3, 0.2]
    N, A = egi(box_wing_mesh(truth, divisions=1))
    fit = np.arange(160) < 110
    rng = np.random.default_rng(3)
    S, V = _unit(rng, 160), _unit(rng, 160)
    clean = box_wing_light_curve(torch.as_tensor(truth), S, V, box_wing_visibility(truth, S, V, resolution_m=0.25),
                                 range_km=1e-3, irradiance=1.0).numpy()
    sigma = 0.02 * clean + 0.002 * float(np.median(clean))
    y = clean + sigma * rng.normal(size=len(clean))
    out = {}
    for res in (None, 0.25):
        m = SimpleNamespace(fit=fit, held=~fit, sigma=sigma, y=y, night=(~fit).astype(int))
        a = SimpleNamespace(sun_b=S, obs_b=V, metrics={"spin": "known"})
        sol = SimpleNamespace(res=SimpleNamespace(normals=N, areas=A), model_unit=np.zeros(160), metrics={})
        solve_parametric(ParametricConfig(divisions=1, outer=2, inner=40, shadow_resolution_m=res, resolved_outer=2),
                         m, a, sol)
        p = np.array([sol.metrics[f"parametric_{k}"] for k in param_names()])
        again = box_wing_light_curve(torch.as_tensor(p), S, V,
                                     box_wing_visibility(p, S, V, divisions=1, resolution_m=res),
                                     range_km=1e-3, irradiance=1.0, divisions=1).numpy()
        np.testing.assert_allclose(sol.model_unit, again, rtol=1e-12)
        assert sol.metrics["parametric_shadow_resolution_m"] == res
        out[res] = sol.metrics["fit_rms"]
        if res is not None:
            cells = box_wing_light_curve(torch.as_tensor(p), S, V, box_wing_visibility(p, S, V, divisions=1),
                                         range_km=1e-3, irradiance=1.0, divisions=1).numpy()
            assert np.abs(sol.model_unit - cells).max() > 0.01 * clean.max()  # the resolution made a difference
    assert out[0.25] <= out[None]


def test_the_stage_hands_its_parts_multi_start_to_fit_parts(monkeypatch):
    """``inversion.parametric.parts_pairs`` and ``parts_keep``: a free pair's dishes started at
    every pairing of the generic placements (3 × 3 starts, each labelled by both) and the best
    ``parts_keep`` briefs fitted in full — the stage passes both to ``fit_parts`` (recorded here)
    and keeps a paired start's fit; without them, the three mirror-image starts and one full fit."""
    from types import SimpleNamespace

    import torch

    import cssat.inversion.parametric_parts as pp
    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility
    from cssat.models.egi.config import ParametricConfig

    truth = np.r_[1.0, 0.9, 1.2, 4.0, 1.5, math.radians(25.0), 0.6, 0.3, 0.2]
    N, A = egi(box_wing_mesh(truth, divisions=1))
    rng = np.random.default_rng(4)
    S, V = _unit(rng, 120), _unit(rng, 120)
    clean = box_wing_light_curve(torch.as_tensor(truth), S, V, box_wing_visibility(truth, S, V, divisions=1),
                                 range_km=1e-3, irradiance=1.0, divisions=1).numpy()
    sigma = 0.02 * clean + 0.002 * float(np.median(clean))
    y = clean + sigma * rng.normal(size=len(clean))
    fit = np.arange(120) < 80
    calls = []
    original = pp.fit_parts

    def recorded(*args, **kw):
        out = original(*args, **kw)
        calls.append((kw["keep"], kw["starts"], out[1]))
        return out

    monkeypatch.setattr(pp, "fit_parts", recorded)
    for pairs, keep in ((True, 2), (False, 1)):
        m = SimpleNamespace(fit=fit, held=~fit, sigma=sigma, y=y, night=(~fit).astype(int))
        a = SimpleNamespace(sun_b=S, obs_b=V, metrics={"spin": "known"})
        sol = SimpleNamespace(res=SimpleNamespace(normals=N, areas=A), model_unit=np.zeros(120), metrics={})
        solve_parametric(ParametricConfig(divisions=1, outer=1, inner=10, dishes=2, dish_pair="free", dish_rings=2,
                                          dish_segments=6, parts_pairs=pairs, parts_keep=keep), m, a, sol)
        got_keep, starts, info = calls[-1]
        assert got_keep == keep
        # the full fits: the best `keep` briefs, in their order; the lowest of them kept
        assert [lab for lab, _ in info["fulls"]] == [lab for lab, _ in info["briefs"][:keep]]
        assert min(info["fulls"], key=lambda f: f[1]) == (info["start"], info["loss"])
        if pairs:
            assert len(starts) == 9 and len(info["briefs"]) == 9 and all("; " in label for label, _ in starts)
            assert len({label for label, _ in starts}) == 9 and "; " in info["start"]
        else:
            assert starts is None and len(info["briefs"]) == 3 and "; " not in info["start"]


def test_the_stage_starts_the_parts_on_the_plain_fit_its_start_or_both(monkeypatch):
    """``inversion.parametric.parts_from``: ``fit_parts`` is handed the plain box-wing's fit
    (``fit``), its unfitted start from the EGI (``start``: :func:`box_wing_start` of the EGI at the
    one default aspect, to the bit), or both in that order (``both``), and the stage keeps the run
    of lower loss, named in ``parametric_parts_base``, its parameters the metrics'."""
    from types import SimpleNamespace

    import torch

    import cssat.inversion.parametric_parts as pp
    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility, param_names
    from cssat.inversion.parametric_fit import box_wing_start
    from cssat.models.egi.config import ParametricConfig

    truth = np.r_[1.0, 0.9, 1.2, 4.0, 1.5, math.radians(25.0), 0.6, 0.3, 0.2, 0.0, 0.0, 1.2, 0.0, 0.0, 0.8, 0.25, 0.6]
    kw = dict(panels=2, divisions=1, dish_rings=2, dish_segments=6, dishes=1)
    N, A = egi(box_wing_mesh(truth, **kw))
    rng = np.random.default_rng(5)
    S, V = _unit(rng, 100), _unit(rng, 100)
    clean = box_wing_light_curve(torch.as_tensor(truth), S, V, box_wing_visibility(truth, S, V, **kw),
                                 range_km=1e-3, irradiance=1.0, **kw).numpy()
    sigma = 0.02 * clean + 0.002 * float(np.median(clean))
    y = clean + sigma * rng.normal(size=len(clean))
    fit = np.arange(100) < 70
    start = box_wing_start(N, A, panels=2, cd0=0.3, aspect=3.75)
    calls = []
    original = pp.fit_parts

    def recorded(*args, **kw):
        out = original(*args, **kw)
        calls.append((np.array(args[3]), *out))
        return out

    monkeypatch.setattr(pp, "fit_parts", recorded)
    names = param_names(1)
    for how in ("fit", "start", "both"):
        calls.clear()
        m = SimpleNamespace(fit=fit, held=~fit, sigma=sigma, y=y, night=(~fit).astype(int))
        a = SimpleNamespace(sun_b=S, obs_b=V, metrics={"spin": "known"})
        sol = SimpleNamespace(res=SimpleNamespace(normals=N, areas=A), model_unit=np.zeros(100), metrics={})
        solve_parametric(ParametricConfig(divisions=1, outer=1, inner=10, dishes=1, dish_rings=2, dish_segments=6,
                                          parts_from=how), m, a, sol)
        bases = [c[0] for c in calls]
        assert len(bases) == (2 if how == "both" else 1)
        is_start = [bool(np.array_equal(b, start)) for b in bases]
        assert is_start == {"fit": [False], "start": [True], "both": [False, True]}[how]
        if how != "start":  # the plain fit moved away from its start
            assert np.abs(bases[0] - start).max() > 1e-3
        if sol.metrics["parametric_family"] == "parts":
            labels = ["plain fit", "plain start"] if how == "both" else ["plain " + how]
            best = min(range(len(calls)), key=lambda i: calls[i][2]["loss"])
            assert sol.metrics["parametric_parts_base"] == labels[best]
            np.testing.assert_allclose([sol.metrics[f"parametric_{k}"] for k in names], calls[best][1], rtol=1e-12)
        else:
            assert sol.metrics["parametric_parts_base"] is None
