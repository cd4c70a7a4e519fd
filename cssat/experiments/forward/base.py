"""The one protocol of a forward model, and the one loop that plans and executes it.

A forward model is how an unknown becomes a light curve — pixels through an atmosphere
(:class:`~cssat.experiments.forward.PixelSensing`, a moving scene), the EGI through a scene and
an attitude (:class:`~cssat.experiments.forward.egi.EGILightCurve`), a silhouette through Fresnel
diffraction onto an array of telescopes (:class:`~cssat.experiments.forward.shadow.Shadow`), a
measured file (:class:`~cssat.experiments.forward.observed.Observed`). Each is one class with the
same stages, run by :func:`run_model` in this order, each timed into ``seconds_<stage>``:

``plan``
    build and check every setting of the config — with its full key, in the range its physics
    implies — and the memory estimate; refuse before any work;
``measure``
    the unknown's truth and its light curve (simulated, or read);
``estimate``
    how the solver gets its operator: known, from references, from statistics, or an attitude
    search whose frames give the EGI operator;
``solve``
    the unknown from the light curve (the ``solver`` group's object where the model takes one);
``score``
    the metrics (against the truth where there is one);
``write``
    ``arrays.npz``, tables and figures.

A model declares, in :attr:`ForwardModel.needs`, which earlier stages each stage reads from. A
stage hands on its result by returning it (a typed dataclass: the scene model's
:class:`~cssat.experiments.forward.scene.ScenePlan` and
:class:`~cssat.experiments.forward.scene.SceneMeasured`, the observed model's settings,
:class:`~cssat.experiments.forward.observed.ObservedMeasured` and
:class:`~cssat.experiments.forward.observed.ObservedVerdicts`); a later stage reads it with
``run.result(stage)``, which refuses a stage its needs do not declare; no model keeps what a
stage hands on as an attribute of itself.
:func:`run_stages` runs the first stages alone (a catalogue's row). :func:`run_model`
owns the loop, refuses an order that runs a stage before one it needs (:class:`StageOrderError`),
the timings and the headline line in the log. A new forward model is one subclass and its typed
config registered as ``forward/<name>`` (:func:`cssat.models.register`); an experiment that uses it
is an overlay in ``conf/experiment/``.
"""

from __future__ import annotations

import logging
from typing import Any, Mapping

from cssat._checks import FieldError
from cssat.experiments.context import Run, StageOrderError

__all__ = ["ForwardModel", "run_model", "run_stages", "STAGES", "NEEDS", "StageOrderError", "check_needs"]

log = logging.getLogger("cssat")

#: the stages of every forward model, in the order :func:`run_model` runs them
STAGES = ("plan", "measure", "estimate", "solve", "score", "write")

#: what each stage reads by default: what the stage before it handed on (a model declares its own)
NEEDS: Mapping[str, tuple[str, ...]] = {"plan": (), "measure": ("plan",), "estimate": ("measure",), "solve": ("estimate",),
                                        "score": ("solve",), "write": ("score",)}


def check_needs(model: Any) -> dict[str, tuple[str, ...]]:
    """``model.needs`` checked: every key and every stage needed is one of :data:`STAGES`, no stage
    needs itself; the stages it leaves out need nothing."""
    needs = dict(getattr(model, "needs", NEEDS))
    for stage, deps in needs.items():
        bad = [s for s in (stage, *deps) if s not in STAGES]
        if bad or stage in deps:
            raise StageOrderError(f"{type(model).__name__}.needs[{stage!r}] = {deps!r}: "
                                  f"{'not stages: ' + repr(bad) if bad else 'a stage cannot need itself'} (stages: {STAGES})")
    return {stage: tuple(needs.get(stage, ())) for stage in STAGES}


class ForwardModel:
    """A forward model of the one pipeline: the stages of :data:`STAGES` as methods. Each stage
    that takes longer than a moment may time its own parts with ``run.stage(name)``;
    :func:`run_model` times the rest under the stage's own name (``plan`` as ``setup``)."""

    name = "forward"
    #: a stage whose method times its own parts (``run.stage``) is not timed again around them
    timed_inside: tuple[str, ...] = ()
    #: stage → the earlier stages whose results it reads (:func:`run_model` refuses another order)
    needs: Mapping[str, tuple[str, ...]] = NEEDS

    def __init__(self, **settings: Any) -> None:
        """A model whose settings are the experiment's groups takes none in its ``forward`` node:
        a key there is a :class:`FieldError` naming it."""
        if settings:
            key = sorted(settings)[0]
            raise FieldError(key, f"not a setting of the {self.name} forward model (its typed config: cssat.models)")

    def plan(self, cfg: Any, run: Run) -> None:  # pragma: no cover - abstract
        """Build and check every setting of ``cfg`` and the memory estimate, before any work."""
        raise NotImplementedError

    def measure(self, run: Run) -> None:  # pragma: no cover - abstract
        """The unknown's truth (if any) and its light curve."""
        raise NotImplementedError

    def estimate(self, run: Run) -> None:
        """The operator the solver gets (default: the measurement's own: known)."""

    def solve(self, run: Run) -> None:  # pragma: no cover - abstract
        """The unknown from the light curve."""
        raise NotImplementedError

    def score(self, run: Run) -> dict[str, Any]:  # pragma: no cover - abstract
        """The run's flat metrics."""
        raise NotImplementedError

    def write(self, run: Run, metrics: dict[str, Any]) -> None:  # pragma: no cover - abstract
        """The run's arrays, tables and figures under ``run.out_dir``."""
        raise NotImplementedError

    def headline(self, metrics: dict[str, Any], run: Run) -> str | None:
        """The one line the log gets at the end (``None``: none), from the run's ``metrics`` (its
        ``seconds_*`` included) and, where it needs them, its stages' results (``run.result``)."""
        return None


def run_model(model: ForwardModel, cfg: Any, run: Run, stages: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Plan ``model`` on ``cfg`` (nothing computed when a setting is refused), then run its stages
    in the order of ``stages`` (default :data:`STAGES`); return its metrics with
    ``seconds_<stage>`` of every stage. A stage about to run before one it needs
    (``model.needs``) is a :class:`StageOrderError`, before it runs; ``run.stages_done`` lists
    the stages run, in order."""
    needs = check_needs(model)
    order = STAGES if stages is None else tuple(stages)
    if sorted(order) != sorted(STAGES):
        raise StageOrderError(f"the stages to run {order!r} are not the stages {STAGES!r}")
    names = {"plan": "setup"}
    done: list[str] = []
    run.stages_done, run.needs, run.results = done, needs, {}
    metrics: dict[str, Any] = {}
    for stage in order:
        missing = [s for s in needs[stage] if s not in done]
        if missing:
            raise StageOrderError(f"{model.name}: stage {stage!r} would run before {missing}, which it needs "
                                  f"(the order: {order!r}; its needs: {needs[stage]!r})")
        method = getattr(model, stage)
        args = {"plan": (cfg, run), "write": (run, metrics)}.get(stage, (run,))
        run.current = stage
        if stage in model.timed_inside and stage not in ("score", "write"):
            out = method(*args)
        else:
            with run.stage(names.get(stage, stage)):
                out = method(*args)
        run.results[stage] = out
        if stage == "score":
            metrics = out
        done.append(stage)
    run.current = None
    metrics.update(run.timings())
    line = model.headline(metrics, run)
    if line:
        log.info("%s", line)
    return metrics


def run_stages(model: ForwardModel, cfg: Any, run: Run, stages: tuple[str, ...]) -> Any:
    """The first stages of a run of ``model`` on ``cfg`` — ``stages``, in :data:`STAGES`' order
    from ``plan`` (e.g. ``("plan", "measure", "estimate")``: a catalogue's row, a test) — with
    :func:`run_model`'s bookkeeping (each result in ``run.results``, read by the next with
    ``run.result``; a stage whose needs have not run refused) but no timing around them (the
    parts a stage times itself still are) and no metrics. Returns the last stage's result; when
    a stage fails, ``run.results`` keeps those of the stages before it."""
    needs = check_needs(model)
    order = tuple(stages)
    if order != STAGES[:len(order)]:
        raise StageOrderError(f"run_stages runs a prefix of {STAGES!r}, got {order!r}")
    done: list[str] = []
    run.stages_done, run.needs, run.results = done, needs, {}
    out = None
    try:
        for stage in order:
            missing = [s for s in needs[stage] if s not in done]
            if missing:  # a model that declares a need on a later stage
                raise StageOrderError(f"{model.name}: stage {stage!r} needs {missing}, which have not run")
            run.current = stage
            args = {"plan": (cfg, run), "write": (run, run.results.get("score"))}.get(stage, (run,))
            out = run.results[stage] = getattr(model, stage)(*args)
            done.append(stage)
    finally:
        run.current = None
    return out

