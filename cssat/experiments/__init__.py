"""Experiments: configurations of one pipeline of stages (:mod:`cssat.experiments.pipeline`).

An experiment is a YAML file in ``conf/experiment/`` and nothing else: ``cssat experiment=<name>``
composes it and runs the pipeline. :func:`run_experiment` wraps a run with what every run needs:
threads, timing, and a ``metrics.json`` that always ends with a ``status`` ("ok" or "failed",
with the error).
"""

from __future__ import annotations

import hashlib
import importlib
import json
import logging
import platform
import time
import traceback
from pathlib import Path
from typing import Any, Callable

import numpy

import cssat
from cssat._checks import FieldError, int_param
from cssat._record import recording
from cssat.experiments.files import write_json
from cssat.experiments.results import check_complete, clear_results, load_saved, move_aside, result_files, run_lock, write_metrics

__all__ = ["experiment_names", "run_experiment", "config_sha", "provenance", "ConfigError", "FieldError"]

log = logging.getLogger("cssat")

#: the error of a bad config value: a :class:`cssat._checks.FieldError` (its ``field`` says where)
ConfigError = FieldError


def experiment_names() -> list[str]:
    """The experiments: the YAML files of ``conf/experiment/`` (``cssat.conf.experiment``)."""
    import cssat.conf  # local: cssat.conf is the configs (a symlink in a source tree), only listed here

    return sorted(p.stem for p in (Path(cssat.conf.__file__).parent / "experiment").glob("*.yaml"))


def _process_seconds() -> float:
    """Seconds since this process started (Python start-up, imports, Hydra's composition)."""
    import psutil  # heavy: psutil, only for the process start time (seconds_startup)

    return max(0.0, time.time() - psutil.Process().create_time())


def run_experiment(cfg: Any, out_dir: str | Path, finalize: Callable[[], None] | None = None,
                   tags: dict[str, Any] | None = None) -> dict[str, Any]:
    """Run the experiment ``cfg.experiment_name`` into ``out_dir`` and return its metrics.

    The experiment is the pipeline (:func:`cssat.experiments.task.run`) configured by ``cfg``,
    or ``cfg.experiment_module``: a module of your own with ``run(cfg, out_dir) -> metrics``.
    ``seconds_startup`` is the process's time before the run (start-up, imports, composing the
    config), so the ``seconds_*`` keys add up to the wall time.

    The run holds a lock on ``out_dir`` (a second run into it is refused, naming it). It removes
    the old ``metrics.json`` first, so a run killed at any moment leaves no complete-looking set,
    and writes ``metrics.json`` last: the experiment's flat metrics plus ``status``, ``seconds``,
    ``experiment``, ``config_sha`` (a hash of the config without ``resume``, ``progress`` …),
    provenance, ``files`` (every result file with its content hash) and ``inputs`` (the hashes of
    the input files read), sealed by ``metrics_digest`` (the hash of the rest of it, so an edit of
    any value is seen). On failure ``status: failed`` and ``error``, and the exception is
    re-raised. ``finalize`` runs under the lock after that (the app re-writes Hydra's ``.hydra/``
    files there, which a refused second run may have overwritten). ``tags`` (e.g. the sweep's
    ``sweep_id``) are added to ``metrics.json``, also of a skipped run.

    Resuming: when ``cfg.resume`` is true (the default) and ``out_dir`` holds a complete, current
    result set — ``status: ok``, the same ``config_sha``, every listed file with its hash, the same
    input files — the run is skipped and the saved metrics are returned; otherwise the log says
    why it runs again.
    """
    import torch  # heavy: torch (~1 s); the module imports without it

    startup = _process_seconds()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    name = cfg.get("experiment_name")
    sha = config_sha(cfg)
    with run_lock(out_dir):
        saved = load_saved(out_dir)
        if cfg.get("resume", True) and saved is not None:
            why = check_complete(out_dir, saved, sha, cfg)
            if why is None:
                log.info("%s: complete results already in %s, skipped (resume=false to redo)", name, out_dir)
                if tags and any(saved.get(k) != v for k, v in tags.items()):
                    saved.update(tags)
                    saved = write_metrics(out_dir, saved)
                if finalize is not None:
                    finalize()
                return saved
            log.info("%s: running again in %s: %s", name, out_dir, why)
        move_aside(out_dir, saved, name, sha)
        clear_results(out_dir)
        t0 = time.perf_counter()
        metrics: dict[str, Any] = {"experiment": name, "config_sha": sha, **(tags or {}), **provenance()}
        with recording(out_dir) as rec:
            try:
                torch.set_num_threads(int_param(cfg.get("threads", 1), "threads", 1, 1024))
                module_name = cfg.get("experiment_module") or "cssat.experiments.task"
                try:
                    module = importlib.import_module(str(module_name))
                except ImportError as err:
                    raise FieldError("experiment_module", f"cannot import {module_name!r}: {err}") from err
                metrics.update(module.run(cfg, out_dir))
                metrics.update(status="ok", inputs=dict(rec.inputs), seconds_startup=startup)
            except BaseException as err:
                metrics.update(status="failed", error=f"{type(err).__name__}: {err}")
                metrics["seconds"] = time.perf_counter() - t0
                _write_status(out_dir, metrics)
                if not isinstance(err, FieldError):
                    log.debug("%s", traceback.format_exc())
                raise
        metrics["seconds"] = time.perf_counter() - t0
        metrics["files"] = result_files(out_dir, rec.outputs)
        write_metrics(out_dir, metrics)
        if finalize is not None:
            finalize()
    return metrics


def _write_status(out_dir: Path, metrics: dict[str, Any]) -> None:
    """Write a failed run's ``metrics.json``; a disk that refuses it (full, read-only) is logged,
    not raised over the run's own error."""
    try:
        write_json(out_dir / "metrics.json", metrics)
    except OSError as err:
        log.error("could not write %s: %s", out_dir / "metrics.json", err)


#: config keys that do not change a run's results (left out of its config hash). ``threads`` is
#: *in* the hash: BLAS sums in another order on another thread count (sim3's minimum-norm PSNR moves
#: by ~1e-5 dB between 1 and 2 threads), so results of another thread count are not "the same".
_NOT_RESULTS = ("resume", "hydra", "optimized_metric", "tiny")  # and "progress" at any depth: config_sha (tiny: the test size)


def provenance() -> dict[str, Any]:
    """``cssat_version``, ``git_commit`` (of cssat's own checkout, when it is one; else null),
    ``torch_version``, ``numpy_version`` and ``python_version`` of this run."""
    import torch  # heavy: torch (~1 s); the module imports without it

    return {"cssat_version": cssat.__version__, "git_commit": _git_commit(Path(cssat.__file__).resolve().parent.parent),
            "torch_version": torch.__version__, "numpy_version": numpy.__version__,
            "python_version": platform.python_version()}


def _git_commit(root: Path) -> str | None:
    """The commit checked out in ``root`` (read from ``.git`` directly: no subprocess)."""
    git = root / ".git"
    try:
        if git.is_file():  # a worktree: "gitdir: <path>"
            git = (root / git.read_text().split(":", 1)[1].strip()).resolve()
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head
        ref = head.split(None, 1)[1]
        path = git / ref
        if path.exists():
            return path.read_text().strip()
        common = git / "commondir"
        base = (git / common.read_text().strip()).resolve() if common.exists() else git
        if (base / ref).exists():
            return (base / ref).read_text().strip()
        for line in (base / "packed-refs").read_text().splitlines():
            if line.endswith(" " + ref):
                return line.split()[0]
    except (OSError, IndexError):
        pass
    return None


def config_sha(cfg: Any) -> str:
    """A short hash of the resolved config, without the keys that do not change the results
    (``resume``, ``progress`` — also the ``progress`` of the solver and denoiser nodes, …);
    ``threads`` is part of it (the last digits of some results depend on it)."""
    from omegaconf import DictConfig, OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    if isinstance(cfg, DictConfig):
        data = OmegaConf.to_container(cfg, resolve=True)
    else:
        data = dict(cfg)

    def strip(node):
        if isinstance(node, dict):
            return {k: strip(v) for k, v in node.items() if k != "progress"}
        return [strip(v) for v in node] if isinstance(node, list) else node

    data = strip({k: v for k, v in data.items() if k not in _NOT_RESULTS})
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:16]
