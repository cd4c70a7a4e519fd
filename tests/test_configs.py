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
