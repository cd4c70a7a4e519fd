"""Issue 35, point 1: one pipeline for every forward model. Every experiment is a YAML overlay whose
``forward`` group is a forward model of the one protocol (or an image model of the image stages),
no module of ``cssat/experiments`` has an experiment's own ``run()``, and the ``solver`` group
works on the EGI and on the silhouette."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from conftest import cfg_of


def test_every_experiment_is_an_overlay_over_the_one_pipeline():
    from hydra.utils import get_class

    from cssat.experiments import experiment_names
    from cssat.experiments.forward.base import ForwardModel

    kinds = {}
    for name in experiment_names():
        cfg = cfg_of(f"experiment={name}")
        assert cfg.get("experiment_module") is None, name
        cls = get_class(cfg.forward._target_)
        assert issubclass(cls, ForwardModel), (name, cls)  # the image models too: one protocol, one runner
        kinds[name] = cls.__name__
    assert kinds["inversion"] == kinds["inversion_tumbling"] == "EGILightCurve"
    assert kinds["occultation"] == "Shadow" and kinds["lightcurve"] == "SceneLightCurve"
    assert kinds["sim1"] == kinds["solvers"] == kinds["realism"] == "PixelSensing"  # a grid is a list of configs of one model
    # realism's moving-scene column (a cell's forward): a forward model of the same protocol
    assert issubclass(get_class(cfg_of("experiment=realism").grid_options.moving._target_), ForwardModel)


def test_the_experiments_package_has_no_experiment_specific_run():
    """Only the task function is a ``run``: a grid is run by the image model's stages, and the task
    dispatches on no kind of model (no ``isinstance``): every model goes to the one runner."""
    import cssat.experiments

    root = Path(cssat.experiments.__file__).parent
    found = sorted(str(f.relative_to(root)) for f in root.rglob("*.py")
                   if any(isinstance(n, ast.FunctionDef) and n.name == "run" for n in ast.parse(f.read_text()).body))
    assert found == ["task.py"]
    task = ast.parse((root / "task.py").read_text())
    calls = {n.func.id for n in ast.walk(task) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert "isinstance" not in calls and "run_model" in calls
    assert not any(isinstance(n, ast.Attribute) and n.attr == "run" for n in ast.walk(task))  # no grid.run bypass


def _recording(cls, calls):
    """``cls`` with every stage replaced by one that records its name (its ``needs`` kept)."""

    def stage(name):
        def method(self, *args):
            calls.append(name)
            return {"x": 1} if name == "score" else None
        return method

    body = {name: stage(name) for name in ("plan", "measure", "estimate", "solve", "score", "write")}
    body["headline"] = lambda self, metrics, run: None
    return type(f"Recording{cls.__name__}", (cls,), body)


def _models():
    from cssat.experiments.forward.base import ForwardModel
    from cssat.experiments.forward.egi import EGILightCurve
    from cssat.experiments.forward.observed import Observed
    from cssat.experiments.forward.scene import SceneLightCurve
    from cssat.experiments.forward import PixelSensing
    from cssat.experiments.forward.shadow import Shadow
    from cssat.experiments.motion import MovingScene

    return [ForwardModel, EGILightCurve, SceneLightCurve, Shadow, Observed, PixelSensing, MovingScene]


def _meets(order, needs):
    """Whether every stage of ``order`` comes after every stage it needs (brute force, by position)."""
    pos = {s: i for i, s in enumerate(order)}
    return all(pos[d] < pos[s] for s, deps in needs.items() for d in deps)


@pytest.mark.parametrize("cls", _models(), ids=lambda c: c.__name__)
def test_the_runner_meets_every_models_declared_stage_needs(tmp_path, cls):
    """The runner's order against what each model declares it needs (not against STAGES itself):
    every stage runs once, after every stage it reads from, and is timed."""
    from cssat.experiments.context import Run
    from cssat.experiments.forward.base import STAGES, run_model

    calls = []
    run = Run.from_config({}, tmp_path)
    m = run_model(_recording(cls, calls)(), {}, run)
    assert sorted(calls) == sorted(STAGES) and len(set(calls)) == 6 and run.stages_done == calls
    declared = {s: tuple(d) for s, d in dict(cls.needs).items()}
    assert declared and _meets(calls, declared), (cls.__name__, calls, declared)
    assert m["x"] == 1 and {"seconds_setup", "seconds_score", "seconds_write"} <= set(m)


def test_every_order_of_the_stages_that_breaks_a_declared_need_is_refused(tmp_path, monkeypatch):
    """All 720 orders of the six stages through the runner, for each model: an order is run to
    the end exactly when it meets the model's declared needs (checked by position here); any
    other is refused before the first stage that would run too early — also when the order is the
    module's STAGES, permuted."""
    import itertools

    from cssat.experiments.context import Run
    from cssat.experiments.forward import base

    for cls in _models():
        needs = {s: tuple(d) for s, d in dict(cls.needs).items()}
        ran_any = refused_any = False
        for order in itertools.permutations(base.STAGES):
            calls = []
            ok = _meets(order, needs)
            if ok:
                base.run_model(_recording(cls, calls)(), {}, Run.from_config({}, tmp_path), stages=order)
                assert calls == list(order)
                ran_any = True
            else:
                with pytest.raises(base.StageOrderError, match=r"would run before"):
                    base.run_model(_recording(cls, calls)(), {}, Run.from_config({}, tmp_path), stages=order)
                first_bad = next(i for i, s in enumerate(order) if any(d not in order[:i] for d in needs.get(s, ())))
                assert calls == list(order[:first_bad])  # nothing ran out of order
                refused_any = True
        assert ran_any and refused_any, cls.__name__
    # the module's own order, permuted: estimate after solve breaks the EGI's declared needs
    from cssat.experiments.forward.egi import EGILightCurve

    monkeypatch.setattr(base, "STAGES", ("plan", "measure", "solve", "estimate", "score", "write"))
    calls = []
    with pytest.raises(base.StageOrderError, match=r"egi: stage 'solve' would run before \['estimate'\]"):
        base.run_model(_recording(EGILightCurve, calls)(), {}, Run.from_config({}, tmp_path))
    assert calls == ["plan", "measure"]


def test_a_model_whose_declared_needs_the_order_violates_is_refused(tmp_path):
    from cssat.experiments.context import Run
    from cssat.experiments.forward.base import ForwardModel, StageOrderError, run_model

    calls = []
    Late = _recording(type("Late", (ForwardModel,), {"needs": {"estimate": ("solve",)}}), calls)
    with pytest.raises(StageOrderError, match=r"stage 'estimate' would run before \['solve'\]"):
        run_model(Late(), {}, Run.from_config({}, tmp_path))
    assert calls == ["plan", "measure"]
    Typo = _recording(type("Typo", (ForwardModel,), {"needs": {"solve": ("estmate",)}}), calls)
    with pytest.raises(StageOrderError, match=r"not stages: \['estmate'\]"):
        run_model(Typo(), {}, Run.from_config({}, tmp_path))


def test_a_stage_reads_only_the_results_its_model_declares(tmp_path):
    """``run.result(stage)`` gives a stage what an earlier stage returned, and refuses a stage its
    model's needs do not declare (the result is there, but reading it is not declared)."""
    from cssat.experiments.context import Run, StageOrderError
    from cssat.experiments.forward.base import ForwardModel, run_model

    seen = {}

    class Typed(ForwardModel):
        needs = {"measure": ("plan",), "solve": ("measure",), "score": ("solve",), "write": ("score",)}

        def plan(self, cfg, run):
            pass

        def measure(self, run):
            return [1.0, 2.0]

        def solve(self, run):
            return sum(run.result("measure"))

        def score(self, run):
            seen["solve"] = run.result("solve")
            return {"x": seen["solve"]}

        def write(self, run, metrics):
            run.result("measure")  # not declared by write: refused

    with pytest.raises(StageOrderError, match=r"stage 'write' reads the result of 'measure', which its model's needs do not"):
        run_model(Typed(), {}, Run.from_config({}, tmp_path))
    assert seen == {"solve": 3.0}


def test_the_scene_model_hands_on_a_typed_measurement(tmp_path):
    """The light curve's measure stage returns a SceneMeasured that score and write read: the
    arrays written are its fields, the magnitudes those of its flux (Pogson, against the Sun's V)."""
    from cssat.experiments.context import Run
    from cssat.experiments.forward.base import run_model
    from cssat.experiments.forward.scene import SceneLightCurve, SceneMeasured

    cfg = cfg_of("experiment=lightcurve", "scenario.n_steps=3", "render.size=8", "threads=1")
    run = Run.from_config(cfg, tmp_path)
    metrics = run_model(SceneLightCurve(), cfg, run)
    m = run.results["measure"]
    assert isinstance(m, SceneMeasured) and run.results["score"] is metrics
    a = np.load(tmp_path / "arrays.npz")
    np.testing.assert_array_equal(a["flux"], m.flux.numpy())
    np.testing.assert_array_equal(a["flux_pixelwise"], m.pixelwise.numpy())
    assert m.images.shape == (3, 8, 8) and metrics["n_steps"] == 3
    lit = m.flux.numpy() > 0
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2

    sun_v = -26.74  # the Sun's V magnitude, at SOLAR_IRRADIANCE_W_M2
    np.testing.assert_allclose(m.magnitude[lit], sun_v - 2.5 * np.log10(m.flux.numpy()[lit] / SOLAR_IRRADIANCE_W_M2), rtol=1e-9)


def tiny(name: str) -> list[str]:
    """The experiment at the smoke run's tiny size (``cssat.smoke.TINY``), one thread."""
    from cssat.smoke import TINY

    return [f"experiment={name}", *TINY[name], "threads=1"]


EGI_TINY = tiny("inversion")
OCC_TINY = tiny("occultation")


def test_the_solver_group_solves_the_egi(tmp_path):
    """``solver=nnls`` (the default) gives the EGI of ``recover_egi(method="nnls")`` on the same
    operator, with the experiment's closure; ``solver=nntv`` solves the TV on the sphere: its EGI
    is non-negative and its weighted misfit on the fitted samples is the χ² it reports."""
    from cssat.experiments import run_experiment
    from cssat.inversion import egi_operator, fibonacci_sphere, recover_egi

    m = run_experiment(cfg_of(*EGI_TINY), tmp_path / "nnls")
    a = np.load(tmp_path / "nnls" / "arrays.npz")
    fit = a["fit"]
    G = egi_operator(a["sun_body"][fit], a["obs_body"][fit], fibonacci_sphere(64))
    ref, info = recover_egi(G, a["flux"][fit], sigma=a["sigma"][fit], method="nnls", closure=1.0)
    assert m["inversion_method"] == "nnls" and m["inversion_grid_chi2"] == pytest.approx(info["chi2"], rel=1e-12)  # before refine_egi
    t = run_experiment(cfg_of(*EGI_TINY, "solver=nntv", "solver.lam=1e-2"), tmp_path / "nntv")
    b = np.load(tmp_path / "nntv" / "arrays.npz")
    assert t["status"] == "ok" and t["inversion_method"] == "nntv" and (b["areas"] >= 0).all()
    assert t["inversion_brdf"] == "lambert"  # the surface the inversion assumes: Lambert (albedo 1), whatever the truth's
    r = (egi_operator(b["sun_body"][fit], b["obs_body"][fit], b["normals"]).matrix().numpy() @ b["areas"] - b["flux"][fit])
    assert float(((r / b["sigma"][fit]) ** 2).sum()) == pytest.approx(t["inversion_chi2"], rel=1e-6)
    assert not (b["areas"].size == int((ref > 0).sum()) and np.allclose(np.sort(b["areas"]), np.sort(ref[ref > 0])))


def test_the_solver_group_solves_the_linearised_silhouette(tmp_path):
    """``solver=landweber`` on the occultation's linear route: its estimate overlaps the true
    silhouette (IoU > 0.3; an empty mask scores 0) and the metrics say which solver ran."""
    from cssat.experiments import run_experiment

    m = run_experiment(cfg_of(*OCC_TINY, "solver=landweber"), tmp_path / "lw")
    assert m["status"] == "ok" and m["solver_linear"] == "landweber" and m["iou_linear"] > 0.3, m


def test_total_variation_refuses_an_unknown_that_is_not_an_image():
    import torch

    from cssat._checks import FieldError
    from cssat.sparse.solvers import tv_pdhg

    with pytest.raises(FieldError, match=r"shape: total variation works on images \(H, W\); the unknown has shape \(6,\)"):
        tv_pdhg(torch.eye(6, dtype=torch.float64), torch.ones(6, dtype=torch.float64), (6,))


@pytest.mark.parametrize("base, bad, field", [
    # an image-only solver on the EGI (was an unpacking traceback)
    (EGI_TINY, ["solver=tv"], r"solver: tv works on images; .*solver=nnls\|nnomp\|nnl1\|nntv"),
    (EGI_TINY, ["solver=pnp"], r"solver: pnp works on images; .*solver=nnls\|nnomp\|nnl1\|nntv"),
    (EGI_TINY, ["inversion.brdf=phong"], r"inversion\.brdf: expected one of \[.lambert., .lobes., .simulated.\]"),
    (EGI_TINY, ["inversion.brdf=lobes", "inversion.lobes=[0.5]"], r"inversion\.lobes: expected a list of Blinn–Phong exponents"),
    (EGI_TINY, ["inversion.brdf=lobes", "inversion.lobes=abc"], r"inversion\.lobes: expected a list .* got 'abc'"),
    # settings read without a check: any truthy shadows, a star's RA without its Dec
    (EGI_TINY, ["shadows=maybe"], r"shadows: expected true or false"),
    (["experiment=lightcurve", "scenario.n_steps=3", "render.size=8"], ["shadows=1"], r"shadows: expected true or false"),
    (OCC_TINY, ["star.ra_deg=10"], r"star\.dec_deg: give both"),
    (OCC_TINY, ["star.ra_deg=400", "star.dec_deg=0"], r"star\.ra_deg: must be a finite number in \[0\.0, 360\.0\]"),
    (OCC_TINY, ["star.ra_deg=10", "star.dec_deg=-91"], r"star\.dec_deg"),
    # values a "> 0" check lets through: a wavelength of a kilometre (was a traceback), a pixel of
    # 1e300 m (was refused as a 5e302-slot array), a spin period beyond the span (ran 50 s to a pole 160° off)
    (OCC_TINY, ["optics.wavelength_m=1e9"], r"optics\.wavelength_m: must be a finite number in \[1e-07, 3e-05\]"),
    (OCC_TINY, ["optics.band=U"], r"optics\.band: expected one of"),
    (OCC_TINY, ["star.bv=5"], r"star\.bv"),
    (OCC_TINY, ["event.time_error_s=5"], r"event\.time_error_s"),
    (OCC_TINY, ["event.oracle=2"], r"event\.oracle: expected one of"),
    (OCC_TINY, ["+event.typo=1"], r"event\.typo: not a setting of the occultation"),
    (OCC_TINY, ["array.scintillation=red"], r"array\.scintillation"),
    (OCC_TINY, ["array.spacing_m=0.1"], r"array\.spacing_m: 0.1 m on the ground is less than one aperture"),
    (OCC_TINY, ["silhouette.pixel_m=1e300"], r"silhouette\.pixel_m: .* more than 1000 m"),
    (EGI_TINY, ["inversion.spin=search", "inversion.max_period_s=1e300", "inversion.min_period_s=1800"],
     r"inversion\.max_period_s: 1e\+300 s is longer than the 172800 s the light curve spans"),
])
def test_the_models_settings_are_refused_before_work(tmp_path, base, bad, field):
    from cssat._checks import FieldError
    from cssat.experiments import run_experiment

    with pytest.raises(FieldError, match=field):
        run_experiment(cfg_of(*base, *bad), tmp_path / "bad")
    assert not (tmp_path / "bad" / "arrays.npz").exists()


def test_the_observed_and_scene_models_hand_on_typed_results_and_keep_nothing(tmp_path):
    """Each stage's result is a typed object in ``run.results`` (the settings, the measurement,
    the verdicts), read by the later stages; the model object itself holds nothing after a run.
    The characterise arrays are the measurement handed on, its metrics the verdicts'."""
    from cssat.experiments.context import Run
    from cssat.experiments.forward.base import run_model
    from cssat.experiments.forward.observed import Observed, ObservedMeasured, ObservedVerdicts
    from cssat.experiments.forward.scene import SceneLightCurve, SceneMeasured, ScenePlan
    from cssat.models.observed.config import ObservedSettings
    from cssat.smoke import EXAMPLE_TRACK

    cases = [("lightcurve", SceneLightCurve(), ["experiment=lightcurve", "scenario.n_steps=3", "render.size=8"],
              {"plan": ScenePlan, "measure": SceneMeasured}),
             ("characterise", Observed(), ["experiment=characterise", f"observations={EXAMPLE_TRACK}",
                                           "characterise.tracks=[101]", "characterise.figures=false", "stages.tumbling=off"],
              {"plan": ObservedSettings, "measure": ObservedMeasured, "estimate": ObservedVerdicts})]
    for name, model, overrides, types in cases:
        cfg = cfg_of(*overrides, "threads=1")
        run = Run.from_config(cfg, tmp_path / name)
        metrics = run_model(model, cfg, run)
        assert vars(model) == {}, (name, sorted(vars(model)))
        for stage, typ in types.items():
            assert isinstance(run.results[stage], typ), (name, stage, type(run.results[stage]))
    d, v = run.results["measure"], run.results["estimate"]
    a = np.load(tmp_path / "characterise" / "arrays.npz")
    np.testing.assert_array_equal(a["values"], d.y)
    assert metrics["n_samples"] == len(d.t) == 600 and {str(k) for k in d.tracks} == {"101"}  # the file's track 101: 600 rows
    assert metrics["period_s"] == v.period["period_s"] and abs(metrics["period_s"] / 18.888 - 1) < 1e-3  # MMT's period
    assert run.results["plan"].characterise.track_list() == [101] and run.results["plan"].stages.tumbling == "off"
