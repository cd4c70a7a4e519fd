"""The one pipeline every experiment is a configuration of.

    target → forward model (geometry, atmosphere, cs) → noise → operator (reference) → solver
           → denoiser → [repeats → denoiser3d] → scores, arrays, figures

Each stage is a config group, built and checked by :func:`plan` before any work: ``target``,
``forward``, ``geometry``, ``atmosphere``, ``noise``, ``cs``, ``reference`` (``known``,
``full_rank``, ``sparse``, ``min_norm``), ``solver``, ``denoiser``, ``denoiser3d`` and
``figures``. An experiment is a YAML file in ``conf/experiment/`` that picks options of these
groups; a grid of such runs (the solver comparison, the realism maps) is the ``grid`` stage
(:mod:`cssat.experiments.grid`), run by the same image forward model
(:class:`~cssat.experiments.forward.PixelSensing`) as one image (:class:`ImageRun`). Every
stage's time is in ``metrics.json`` as ``seconds_<stage>``.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, int_param
from cssat._progress import progress_bar
from cssat.experiments import report
from cssat.experiments.build import build, build_denoiser, build_solver
from cssat.experiments.context import Run, as_field
from cssat.experiments.estimators import Known
from cssat.experiments.forward.sensing import Geometry, measurements, phi_stats
from cssat.experiments.report import FIGURES, repeats_summary
from cssat.experiments.resources import check_memory
from cssat.metrics import psnr

log = logging.getLogger("cssat")

__all__ = ["Plan", "plan", "measure", "execute", "metrics_of", "ImageRun"]


@dataclass
class Plan:
    """The built stages of one run (what :func:`plan` checked)."""

    name: str
    target: Any
    forward: Any
    geometry: Any
    atmosphere: Any
    noise: Any
    m: int
    reference: Any
    solver: Any
    denoiser: Any
    denoiser3d: Any
    center: Any
    phi_stats: Any
    figures: list[str] = field(default_factory=list)
    memory_estimate: int = 0
    forward_key: str = ""  #: the settings Φ depends on (a grid reuses it)
    information: int = 0  #: modes of the Fisher-information bound (0: none)


#: the forward model of a config without one (by name: this module is what it runs)
DEFAULT_FORWARD = "cssat.experiments.forward.PixelSensing"


def _node(cfg: Any, key: str) -> Any:
    return cfg.get(key) if hasattr(cfg, "get") else None


def plan(cfg: Any, run: Run, forward: Any = None) -> Plan:
    """Build every stage of ``cfg`` and check the run fits in memory, before any work; ``forward``:
    the ``forward`` group's sensing model when the caller has built it already."""
    import torch  # heavy: torch (~1 s); the module imports without it

    target = build(cfg.target, "target")
    if forward is None:
        node = cfg.forward if _node(cfg, "forward") is not None else {"_target_": DEFAULT_FORWARD}
        forward = build(node, "forward")
    geometry = build(cfg.geometry, "geometry") if _node(cfg, "geometry") is not None else Geometry()
    atmosphere = build(cfg.get("atmosphere"), "atmosphere", optional=geometry.kwargs())
    if getattr(atmosphere, "emitters", "pixels") != "pixels":
        raise FieldError("atmosphere.emitters", f"expected 'pixels' (this forward model measures an image's pixels), "
                                                f"got {atmosphere.emitters!r}: use atmosphere=gaussian")
    noise = build(cfg.get("noise"), "noise")
    shape = forward.shape(target)
    N = int(np.prod(shape))
    m = measurements(_node(cfg, "cs"), N)
    reference = build(cfg.reference, "reference") if _node(cfg, "reference") is not None else Known()
    solver = build_solver(cfg.solver, m, N)
    denoiser = build_denoiser(cfg.get("denoiser"))
    denoiser3d = None
    if reference.repeated and reference.repeats >= 2 and _node(cfg, "denoiser3d") is not None:
        denoiser3d = build_denoiser(cfg.denoiser3d, "denoiser3d")
    checks = [(denoiser, shape, "denoiser"), (getattr(solver, "denoiser", None), shape, "solver.denoiser")]
    if denoiser3d is not None:
        checks.append((denoiser3d, (reference.repeats, *shape), "denoiser3d"))
    for obj, shp, name in checks:  # denoisers' settings against the image they will get, before any work
        if obj is not None and hasattr(obj, "check"):
            with as_field(name):
                obj.check(shp)
    figures = list(cfg.get("figures") or [])
    for name in figures:
        choice_param(name, "figures", sorted(FIGURES))
    with as_field("reference"):
        parts, peak = reference.memory(shape[0], m, torch.finfo(run.dtype).bits // 8)
    est = check_memory(parts, run.memory_limit_gb, "lower target.size or cs.m (or the reference sizes)", peak=peak)
    key = json.dumps([_plain(cfg.get(k)) for k in ("target", "forward", "geometry", "atmosphere", "phi_stats")]
                     + [m, str(reference.precision(run))], sort_keys=True, default=str)

    information = int_param(cfg.get("information") or 0, "information", 0, N)
    return Plan(str(cfg.get("experiment_name") or "experiment"), target, forward, geometry, atmosphere, noise, m,
                reference, solver, denoiser, denoiser3d, choice_param(cfg.get("center", "auto"), "center", (True, False, "auto")),
                choice_param(cfg.get("phi_stats", "auto"), "phi_stats", (True, False, "auto")), figures, est, key, information)


def _plain(node: Any) -> Any:
    from omegaconf import OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    return OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node


def measure(p: Plan, run: Run, cache: dict | None = None) -> Any:
    """The target's unknown measured (:class:`cssat.experiments.forward.Measured`), with the
    statistics of Φ; ``cache`` (the grid's) reuses Φ and its statistics across cells whose forward
    settings are the same (one Φ at a time: it may be large)."""
    with run.stage("target"), as_field("target"):
        truth = p.target.load()
    dtype, draw = p.forward.precision(run, *p.reference.precision(run))
    shape = tuple(truth.shape)
    if cache is not None and p.forward_key in cache:
        op, stats = cache[p.forward_key]
    else:
        with run.stage("measure"):
            op = p.forward.operator(run, p.atmosphere, p.m, shape, dtype, draw)
        with run.stage("phi_stats"):
            stats = phi_stats(p.phi_stats, op, shape)
        if cache is not None:
            cache.clear()
            cache[p.forward_key] = (op, stats)
    with run.stage("measure"):
        measured = p.forward.sense(run, truth, op, p.noise, dtype)
        measured.metrics.update({**p.atmosphere.describe(), **stats})
    if p.information and measured.noise_var is not None:
        from cssat.physics.information import mode_information  # heavy: cssat.physics.information imports torch

        with run.stage("information"):
            mat = op.matrix() if hasattr(op, "matrix") else op
            info = mode_information(mat, measured.noise_var, truth, p.information)
            info.pop("info_snr")
            measured.metrics.update(info)
    return measured


def execute(p: Plan, run: Run, cache: dict | None = None) -> dict[str, Any]:
    """Run the stages of ``p``; return ``{"metrics", "arrays", "recs", "rows", "measured"}``."""
    from cssat.experiments.reconstruct import denoise, reconstruct, scores  # heavy: cssat.experiments.reconstruct imports torch

    measured = measure(p, run, cache)
    x, shape, est = measured.truth, measured.shape, p.reference
    y = measured.y
    est.prepare(run, measured)
    measured.measurement = None  # the estimate holds what it needs of Φ: free the rest now
    recs, rows = [], []

    bar = progress_bar(est.repeats, f"{p.name}: repeats", run.progress if est.repeats > 1 else False, unit="repeat")
    for r in range(est.repeats):
        op, row = est.operator(run, r)
        rec = reconstruct(p.solver, op, y, shape, denoiser=p.denoiser, center=getattr(est, "center", p.center),
                          dtype=run.dtype, noise_var=getattr(est, "noise_var", measured.noise_var))
        del op
        for k in ("solver", "dictionary", "denoise"):
            run.add_seconds(k, rec.metrics.pop(f"seconds_{k}", 0.0))
        row.update(est.baseline(run, r, lambda phi: psnr(x, reconstruct(p.solver, phi, y, shape, dtype=run.dtype).image,
                                                             data_range=1.0)))
        with run.stage("score"):
            row.update(scores(rec.image, rec.denoised, x))
        rows.append(row)
        recs.append(rec)
        bar.update()
        if est.repeated:
            log.info("%s repeat %d: ‖Φ̂−Φ‖/‖Φ‖ %.3f, PSNR %.2f dB, 2-D denoised %.2f dB", p.name, r,
                     row.get("phi_relative_error", float("nan")), row["psnr"], row["psnr_denoised"])
    bar.close()
    est.finish()
    out: dict[str, Any] = {"recs": recs, "rows": rows, "measured": measured}
    if est.repeated:
        stack, den2 = np.stack([r.image for r in recs]), np.stack([r.denoised for r in recs])
        if p.denoiser3d is not None:
            with run.stage("denoise_3d"):
                den3, dm3 = denoise(p.denoiser3d, stack, field="denoiser3d")
            dm3.pop("seconds_denoise", None)
        else:
            den3, dm3 = stack.copy(), {"denoiser": "none"}
        with run.stage("score"):
            out.update(stack=stack, den2=den2, den3=den3, psnr3=[psnr(x, d, data_range=1.0) for d in den3],
                       denoiser_3d=dm3.get("denoiser"))
    return out


def metrics_of(p: Plan, run: Run, res: dict[str, Any]) -> dict[str, Any]:
    """The flat metrics of an executed plan (the headline ``psnr``/``ssim`` first)."""
    measured, recs, rows = res["measured"], res["recs"], res["rows"]
    n = measured.shape[0]
    N = int(np.prod(measured.shape))
    common = {"m": p.m, "n": n, "n_pixels": N, "measurement_ratio": p.m / N, **measured.metrics, **p.geometry.describe(),
              **p.reference.describe(), "seed": run.seed, "dtype": run.dtype_name, "device": str(run.device),
              "target": getattr(p.target, "image", None), "peak_memory_estimate_gb": p.memory_estimate / 2**30}
    if p.reference.repeated:
        out = repeats_summary(rows, res["psnr3"])
        out.update(common, **{k: v for k, v in recs[-1].metrics.items() if k.startswith("solver")},
                   denoiser=recs[-1].metrics["denoiser"], denoiser_3d=res["denoiser_3d"])
        return out
    out = {**rows[0], **common, **recs[0].metrics}
    out["psnr_gain_denoised"] = out["psnr_denoised"] - out["psnr"]
    return out


class ImageRun:
    """One image run of the image forward models (``forward: pixels``, ``moving``): what their
    stages do when the config has no ``grid`` — ``plan`` is :func:`plan` (every stage built and
    checked, the memory estimated), ``measure`` runs :func:`execute` (the measurement, the
    operator estimate of the ``reference`` group and the ``solver`` and denoisers over the
    repeats, each timed by its own stages), ``score`` is :func:`metrics_of`, ``write`` the
    report's arrays and figures."""

    def __init__(self, cfg: Any, run: Run, sensing: Any):
        """Plan ``cfg`` with ``sensing``, the ``forward`` group's image model."""
        self.p = plan(cfg, run, sensing)

    def measure(self, run: Run) -> dict[str, Any]:
        """:func:`execute`'s result: the measurement, the operator and the reconstructions."""
        return execute(self.p, run)

    def score(self, run: Run, res: dict[str, Any]) -> dict[str, Any]:
        return metrics_of(self.p, run, res)

    def write(self, run: Run, res: dict[str, Any], metrics: dict[str, Any]) -> None:
        report.write(self.p, run, res, metrics)

    def headline(self, metrics: dict[str, Any]) -> None:
        report.log_headline(self.p, metrics)
        return None
