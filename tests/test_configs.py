"""The config tree composes: every experiment with every option of every group, each object built."""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_module

import cssat.conf
from cssat.experiments.build import build, build_denoiser, build_model, build_solver

CONF = Path(cssat.conf.__file__).parent
GROUPS = ("atmosphere", "noise", "solver", "denoiser", "target", "model", "reference", "forward", "geometry")
EXPERIMENTS = sorted(p.stem for p in (CONF / "experiment").glob("*.yaml"))


def options(group):
    """A group's options: its YAML files, and for ``forward`` the typed configs in Hydra's ConfigStore."""
    if group == "forward":
        from cssat.models import FORWARD_CONFIGS, register_configs

        register_configs()
        return sorted(FORWARD_CONFIGS)
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


def compose_cfg(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def test_every_group_has_options_and_every_experiment_is_listed():
    from cssat.experiments import experiment_names

    for g in GROUPS:
        assert options(g), g
    assert set(EXPERIMENTS) == set(experiment_names()) and {"sim1", "sim2", "sim3", "solvers", "realism", "lightcurve"} <= set(EXPERIMENTS)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
@pytest.mark.parametrize("group", ["atmosphere", "noise", "solver", "denoiser"])
def test_every_experiment_composes_with_every_option(experiment, group):
    for option in options(group):
        cfg = compose_cfg(f"experiment={experiment}", f"{group}={option}")
        assert cfg.experiment_name == experiment
        obj = build(cfg[group], group)
        assert callable(obj) or hasattr(obj, "operator"), (group, option)
        if group == "solver" and "size" in cfg.target:  # an image target
            from cssat.experiments.forward import measurements

            N = cfg.target.size ** 2
            build_solver(cfg.solver, measurements(cfg.cs, N), N)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_builds_its_nested_objects(experiment):
    cfg = compose_cfg(f"experiment={experiment}")
    for option in options("target"):  # an image experiment takes every image target
        if option != "scene" and "size" in cfg.target:
            assert build(compose_cfg(f"experiment={experiment}", f"target={option}").target, "target").kind == "image"
    for key in ("model", "reference.model"):
        node = cfg.get(key.split(".")[0])
        if node is not None and (key == "model" or "model" in node):
            mesh = build_model(cfg.model if key == "model" else cfg.reference.model, key)
            assert len(mesh) > 100
            group_key = "model" if key == "model" else f"model@{key}"
            for option in options("model"):
                if option != "file":  # needs a path
                    build_model(compose_cfg(f"experiment={experiment}", f"{group_key}={option}")[key.split(".")[0]]
                                if key == "model" else
                                compose_cfg(f"experiment={experiment}", f"{group_key}={option}").reference.model, key)
    if "denoiser3d" in cfg:
        assert callable(build_denoiser(cfg.denoiser3d, "denoiser3d"))
    if "grid" in cfg:  # every cell of a grid builds its stages
        from cssat.experiments.context import Run
        from cssat.experiments.grid import cells
        from cssat.experiments.pipeline import plan

        for _, cell in cells(cfg):
            assert callable(plan(cell, Run.from_config(cell, ".")).solver)


def test_the_file_model_requires_a_path():
    from cssat.experiments import ConfigError

    cfg = compose_cfg("experiment=lightcurve", "model=file")
    with pytest.raises(Exception, match="path"):
        build_model(cfg.model)
    cfg = compose_cfg("experiment=lightcurve", "model=file", "model.path=null")
    with pytest.raises(ConfigError, match="^model.path"):
        build_model(cfg.model)


def test_the_forward_models_configs_are_typed_dataclasses_in_one_place():
    """Every ``forward`` option is a dataclass in Hydra's ConfigStore (no YAML repeats its
    defaults); ``forward.<key>=…`` overrides a field, a key that is not one is refused when the
    config is composed, and a bad value is a FieldError naming the full key before any work."""
    import dataclasses
    import math

    import torch
    from hydra.errors import ConfigCompositionException

    from cssat._checks import FieldError
    from cssat.models import FORWARD_CONFIGS
    from cssat.models.moving.config import MovingConfig

    assert not list((CONF / "forward").glob("*.yaml"))
    assert {"pixels", "moving", "egi", "scene", "shadow", "observed"} <= set(options("forward"))
    for name in options("forward"):
        node = compose_cfg(f"forward={name}").forward
        assert dataclasses.is_dataclass(FORWARD_CONFIGS[name]) and node._target_.rsplit(".", 1)[-1] in (
            "PixelSensing", "MovingScene", "EGILightCurve", "SceneLightCurve", "Shadow", "Observed")
    # overrides of the old YAML keys keep their meaning: the model gets them
    moving = build(compose_cfg("forward=moving", "forward.step_s=2.5", "forward.lat_deg=-30", "forward.dtype=float64").forward,
                   "forward")
    assert (moving.step_s, moving.lat_deg, moving.dtype, moving.draw_dtype) == (2.5, -30.0, torch.float64, None)
    assert build(compose_cfg("experiment=realism").forward, "forward").dtype == torch.float64  # the experiment's forward.dtype
    # a key that is not a field: refused by the schema; forced in with "+", refused by the model's build
    with pytest.raises(ConfigCompositionException, match="forward.n_normals"):
        compose_cfg("experiment=inversion", "forward.n_normals=3")
    with pytest.raises(FieldError, match=r"^forward\.n_normals: not a setting of the egi forward model"):
        build(compose_cfg("experiment=inversion", "+forward.n_normals=3").forward, "forward")
    # a bad value: the dataclass's own check, naming the full key
    with pytest.raises(FieldError, match=r"^forward\.dtype: expected one of \['float32', 'float64'\], got 'float16'"):
        build(compose_cfg("forward.dtype=float16").forward, "forward")
    with pytest.raises(FieldError, match=r"^forward\.lat_deg: expected a finite number"):
        build(compose_cfg("forward=moving", "forward.lat_deg=nan").forward, "forward")
    with pytest.raises(FieldError, match=r"^forward\.step_s: must be a finite number in \(0\.0, inf\]"):
        MovingConfig(step_s=0)
    assert math.isclose(MovingConfig(step_s=3).step_s, 3.0)


def test_the_observed_models_settings_are_typed_with_one_set_of_defaults():
    """The characterise experiment's groups (observations, observed, stages, characterise,
    period, tumbling, catalogue) come from their dataclasses (its YAML repeats none of them);
    the overrides keep their meaning and reach the model's typed settings."""
    import yaml
    from omegaconf import OmegaConf

    from cssat.experiments.forward.observed import observed_settings
    from cssat.models.observed.config import ObservedConfig

    own = yaml.safe_load((CONF / "experiment" / "characterise.yaml").read_text())
    groups = [k for k in ObservedConfig.SETTINGS if k != "observations"]
    assert not set(groups) & set(own), "a group's defaults repeated in characterise.yaml"
    cfg = compose_cfg("experiment=characterise")
    for k in groups:
        assert OmegaConf.get_type(cfg[k]) is ObservedConfig.SETTINGS[k], k
    assert cfg.observations is None and cfg.catalogue.shard_size == 500 and cfg.characterise.min_samples == 20
    s = observed_settings(compose_cfg("experiment=characterise", "observations=some/file.txt", "period.n_surrogates=5",
                                      "stages.tumbling=off", "characterise.tracks=[101]", "period.method=pdm",
                                      "tumbling.order=2", "observed.kind=flux"))
    assert (s.observations, s.period.n_surrogates, s.period.method, s.stages.tumbling, s.characterise.track_list(),
            s.tumbling.order, s.observed.kind) == ("some/file.txt", 5, "pdm", "off", [101], 2, "flux")
    assert s.period.options() == {"n_surrogates": 5}  # the method's own defaults for the rest; method apart
    assert "settings" not in compose_cfg("experiment=lightcurve") and "period" not in compose_cfg("experiment=lightcurve")


@pytest.mark.parametrize("overrides, start", [
    (["forward.foo=1"], "forward.foo: no such key; forward is a typed config (cssat.models.pixels.config.PixelsConfig)"),
    (["+forward.foo=1"], "forward.foo: no such key; forward is a typed config"),
    (["experiment=characterise", "+period.foo=1"], "period.foo: no such key; period is a typed config"),
    (["experiment=characterise", "stages.bogus=on"], "stages.bogus: no such key; stages is a typed config"),
])
def test_the_command_line_check_does_not_suggest_adding_a_key_to_a_typed_config(overrides, start):
    """A typed node (a forward model's config, the characterise groups) takes no other key, not
    even with '+': the one-line refusal lists its fields and suggests no '+key=...'; an untyped
    node still gets the suggestion."""
    from cssat._cli_check import check

    why = check(overrides)
    assert why.startswith(start) and "+" not in why and "takes only: " in why, why
    field = overrides[-1].lstrip("+").split("=")[0].split(".")[0]
    fields = {"forward": "dtype", "period": "n_surrogates", "stages": "tumbling"}[field]
    assert fields in why.split("takes only: ")[1].split(", ")
    assert check(["cs.foo=1"]).endswith("(add a new one with +cs.foo=...)")
    assert check(["experiment=characterise", "period.n_surrogates=5", "stages.spin=off"]) is None


@pytest.mark.parametrize("value, shown", [("2", "2"), ("0", "0"), ("yes", "'yes'"), ("true,on", "'on'")])
def test_a_typed_boolean_takes_only_true_or_false_on_the_command_line(value, shown):
    """OmegaConf reads 2, 'yes' and 'on' into a dataclass's bool as true (0 as false): the
    command line's check refuses them, naming the key, the allowed values and the value, every
    value of a sweep included; true and false pass."""
    from cssat._cli_check import check

    base = ["experiment=inversion", "inversion.shape=parametric"]
    assert check([*base, f"inversion.parametric.booms={value}"]) == \
        f"inversion.parametric.booms: expected true or false, got {shown}"
    assert check([*base, "inversion.parametric.booms=true", "inversion.split_nights=false"]) is None
    assert "does not support deletion" in check([*base, "~inversion.parametric.booms"])  # not "got None"


def test_the_scene_models_settings_are_typed_with_one_set_of_defaults():
    """The light curve's own settings (render.*, shadows, earthshine, earth_albedo, magnitudes.*,
    observations, observed.*) come from cssat.models.scene.config; lightcurve.yaml keeps only
    what differs (observed.time_col); a wrong type is refused when composed, a bad value when
    planned, naming the key."""
    import yaml
    from hydra.errors import ConfigCompositionException
    from omegaconf import OmegaConf

    from cssat._checks import FieldError
    from cssat.models.scene.config import RenderConfig, SceneConfig, SceneSettings

    own = yaml.safe_load((CONF / "experiment" / "lightcurve.yaml").read_text())
    assert set(own) & set(SceneConfig.SETTINGS) == {"observed"} and own["observed"] == {"time_col": "time_utc"}
    cfg = compose_cfg("experiment=lightcurve", "render.size=8", "shadows=false", "magnitudes.band=R")
    assert OmegaConf.get_type(cfg.render) is RenderConfig and cfg.earthshine == "auto" and cfg.earth_albedo == 0.3
    s = SceneSettings.from_config(cfg)
    assert (s.render.size, s.render.n_images, s.shadows, s.magnitudes.band, s.observed.time_col) == (8, 5, False, "R",
                                                                                                      "time_utc")
    with pytest.raises(ConfigCompositionException, match=r"render\.size"):
        compose_cfg("experiment=lightcurve", "render.size=big")
    for override, key in (("render.n_images=30", "render.n_images"), ("shadows=maybe", "shadows"),
                          ("earth_albedo=1.5", "earth_albedo"), ("earthshine=sometimes", "earthshine")):
        with pytest.raises(FieldError) as err:
            SceneSettings.from_config(compose_cfg("experiment=lightcurve", override))
        assert err.value.field == key, (override, str(err.value))


def test_the_egi_models_settings_are_typed_with_one_set_of_defaults():
    """The inversion's own settings (nights.*, inversion.*, shadows, observations, observed.*) come
    from cssat.models.egi.config: inversion.yaml sets none of their values but observed.time_col;
    the tumbling experiment overrides two; a wrong type is refused when composed, an unknown key
    or a bad value when planned, naming the key — a key that moved to the solver group says so."""
    import yaml
    from hydra.errors import ConfigCompositionException
    from omegaconf import OmegaConf

    from cssat._checks import FieldError
    from cssat._cli_check import check
    from cssat.models.egi.config import EGIConfig, EGISettings, InversionConfig, NightsConfig

    own = yaml.safe_load((CONF / "experiment" / "inversion.yaml").read_text())
    assert set(own) & set(EGIConfig.SETTINGS) == {"observed"} and own["observed"] == {"time_col": "time_utc"}
    cfg = compose_cfg("experiment=inversion_tumbling", "nights.n=2", "inversion.shape=parametric", "inversion.parametric.panels=1")
    assert OmegaConf.get_type(cfg.nights) is NightsConfig and OmegaConf.get_type(cfg.inversion) is InversionConfig
    s = EGISettings.from_config(cfg)
    # inversion_tumbling.yaml's own values over the typed defaults; the rest the defaults
    assert (s.nights.n, s.nights.fit, s.inversion.spin, s.inversion.n_normals, s.inversion.parametric.panels,
            s.inversion.search_normals, s.shadows, s.observations) == (2, None, "tumbling", 1000, 1, 1000, True, None)
    assert s.inversion.search() == {"n_poles": 60, "n_starts": 6, "n_refine": 2, "coarse_normals": 200, "coarse_samples": 400,
                                    "max_samples": 1200, "min_period_s": 120.0, "max_period_s": 3000.0, "split_nights": False,
                                    "error_grids": 1, "bootstrap": 0, "local_starts": 0}
    with pytest.raises(ConfigCompositionException, match=r"nights\.n"):
        compose_cfg("experiment=inversion", "nights.n=many")
    with pytest.raises(ConfigCompositionException, match=r"inversion\.split_nights"):
        compose_cfg("experiment=inversion", "inversion.split_nights=maybe")
    for override, key in (("nights.n=0", "nights.n"), ("nights.fit=4", "nights.fit"), ("inversion.spin=guess", "inversion.spin"),
                          ("inversion.n_normals=8", "inversion.n_normals"), ("inversion.closure=-1", "inversion.closure"),
                          ("inversion.error_grids=0", "inversion.error_grids"), ("inversion.bootstrap=-1", "inversion.bootstrap"),
                          ("inversion.local_starts=9", "inversion.local_starts"),
                          ("+inversion.lam=0.1", "inversion.lam"), ("+inversion.parametric.wings=2", "inversion.parametric.wings"),
                          ("shadows=maybe", "shadows"), ("+observed.bogus=1", "observed.bogus")):
        with pytest.raises(FieldError) as err:
            EGISettings.from_config(compose_cfg("experiment=inversion", override))
        assert err.value.field == key, (override, str(err.value))
    with pytest.raises(FieldError, match=r"inversion\.method: the EGI's solve is the solver group's: solver=nnls"):
        EGISettings.from_config(compose_cfg("experiment=inversion", "+inversion.method=tv"))
    why = check(["experiment=inversion", "+inversion.lam=0.1"])
    assert why.startswith("inversion.lam: no such key; the EGI's solve is the solver group's"), why
