"""The task function: a composed config run into its output folder (lightning-hydra-template's
``task``, apart from ``@hydra.main``). The ``forward`` group's model says what is measured: a
:class:`~cssat.experiments.forward.base.ForwardModel` (the image models — pixels, a moving scene,
one image or a grid of cells —, the EGI, a scene, a shadow, a measured file), planned and run
stage by stage by the one runner, :func:`~cssat.experiments.forward.base.run_model`. It is what
:func:`cssat.experiments.run_experiment` runs unless ``experiment_module`` names a module of the
user's own."""

from __future__ import annotations

from typing import Any

from cssat._checks import FieldError
from cssat.experiments.build import build
from cssat.experiments.context import Run
from cssat.experiments.forward import PixelSensing
from cssat.experiments.forward.base import STAGES, run_model

__all__ = ["run"]


def run(cfg: Any, out_dir: Any) -> dict[str, Any]:
    """Run the experiment ``cfg`` into ``out_dir``; return its metrics (timings included)."""
    run_ = Run.from_config(cfg, out_dir)
    with run_.stage("setup"):
        node = cfg.get("forward")
        model = build(node, "forward") if node is not None else PixelSensing()
    missing = [s for s in STAGES if not callable(getattr(model, s, None))]
    if missing:
        raise FieldError("forward._target_", f"{type(model).__name__} is not a forward model: it has no stage "
                                             f"{', '.join(missing)} (subclass cssat.experiments.forward.base.ForwardModel)")
    return run_model(model, cfg, run_)
