"""The task function: a composed config run into its output folder (lightning-hydra-template's
``task``, apart from ``@hydra.main``). The ``forward`` group's model says what is measured: a
:class:`~cssat.experiments.forward.base.ForwardModel` (the EGI, a shadow, a measured file) is
planned and run stage by stage by :func:`~cssat.experiments.forward.base.run_model`; the image
models (pixels, a moving scene) run the image stages — a grid of cells
(:mod:`cssat.experiments.grid`) or one image (:mod:`cssat.experiments.pipeline`). It is what :func:`cssat.experiments.run_experiment`
runs unless ``experiment_module`` names a module of the user's own."""

from __future__ import annotations

from typing import Any

from cssat.experiments import grid
from cssat.experiments.build import build
from cssat.experiments.context import Run
from cssat.experiments.forward.base import ForwardModel, run_model
from cssat.experiments.pipeline import ImagePipeline

__all__ = ["run"]


def run(cfg: Any, out_dir: Any) -> dict[str, Any]:
    """Run the experiment ``cfg`` into ``out_dir``; return its metrics (timings included)."""
    run_ = Run.from_config(cfg, out_dir)
    if cfg.get("grid") is not None:
        return grid.run(cfg, run_)
    with run_.stage("setup"):
        node = cfg.get("forward")
        model = build(node, "forward") if node is not None else None
    if not isinstance(model, ForwardModel):  # an image sensing model (pixels, a moving scene): the image stages
        model = ImagePipeline(model)
    return run_model(model, cfg, run_)
