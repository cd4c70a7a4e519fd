"""A joblib launcher for Hydra sweeps that survives a worker killed by the OS.

hydra-joblib-launcher runs the jobs in loky worker processes; when the OS kills one (the OOM
killer, a SIGKILL), loky raises ``TerminatedWorkerError`` for the whole batch and the sweep ends
with no summary. :class:`RobustJoblibLauncher` (``launcher=local``) runs the batch again without
the jobs that finished, up to ``retries`` times; a job that was running when a worker died in two
rounds is taken to be the one killing it, and is recorded as failed (its ``metrics.json`` says
``status: failed``) so that the rest of the sweep finishes and the summary is written.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any, Sequence

try:
    from hydra_plugins.hydra_joblib_launcher.joblib_launcher import JoblibLauncher
except ImportError:  # pragma: no cover - the launchers extra is not installed
    JoblibLauncher = object  # type: ignore[misc,assignment]

log = logging.getLogger("cssat")

__all__ = ["RobustJoblibLauncher"]


def _job_dir(config: Any, idx: int) -> Path:
    """The directory of job ``idx``: ``hydra.sweep.dir / hydra.sweep.subdir`` with the job number
    (cssat's subdir is ``${hydra.job.num}``; read unresolved, as the number is not set here)."""
    from omegaconf import OmegaConf

    sub = str(OmegaConf.to_container(config.hydra.sweep, resolve=False)["subdir"])
    return Path(str(config.hydra.sweep.dir)) / sub.replace("${hydra.job.num}", str(idx))


def _state(d: Path) -> str:
    """``done`` (metrics.json with a status), ``started`` (the job wrote its directory), ``new``."""
    try:
        if json.loads((d / "metrics.json").read_text()).get("status") in ("ok", "failed"):
            return "done"
    except (OSError, ValueError):
        pass
    return "started" if (d / ".hydra").exists() else "new"


class RobustJoblibLauncher(JoblibLauncher):
    """:class:`JoblibLauncher` that reruns the jobs a killed worker took down (see the module)."""

    def __init__(self, retries: int = 3, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.retries = int(retries)

    def _run(self, job_overrides, batch: list[int], initial_job_idx: int) -> list:
        """Jobs ``batch`` (their own indices, so each keeps its number and directory) in loky workers."""
        from hydra.core.singleton import Singleton
        from hydra.core.utils import setup_globals
        from joblib import Parallel, delayed

        from hydra_plugins.hydra_joblib_launcher import _core

        setup_globals()
        cfg = dict(self.joblib)
        cfg["backend"] = "loky"
        _core.process_joblib_cfg(cfg)
        Path(str(self.config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
        state = Singleton.get_state()
        log.info("sweep: launching %d jobs in %s loky workers", len(batch), cfg.get("n_jobs"))
        return Parallel(**cfg)(
            delayed(_core.execute_job)(initial_job_idx + i, job_overrides[i], self.hydra_context, self.config,
                                       self.task_function, state)
            for i in batch
        )

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int):
        from hydra.core.utils import JobReturn, JobStatus
        from joblib.externals.loky.process_executor import TerminatedWorkerError

        from cssat.experiments.files import write_json

        pending = list(range(len(job_overrides)))
        results: dict[int, Any] = {}
        suspects: dict[int, int] = {}
        for round_ in range(self.retries + 1):
            batch = [i for i in pending if i not in results]
            if not batch:
                break
            try:
                results.update(zip(batch, self._run(job_overrides, batch, initial_job_idx)))
                break
            except TerminatedWorkerError as err:
                log.error("sweep: a worker was killed (%s); running the unfinished jobs again", str(err).splitlines()[0])
                for i in batch:
                    state = _state(_job_dir(self.config, initial_job_idx + i))
                    if state == "done":
                        results[i] = JobReturn(overrides=list(job_overrides[i]), status=JobStatus.COMPLETED,
                                               _return_value=None)
                    elif state == "started":
                        suspects[i] = suspects.get(i, 0) + 1
                for i, n in suspects.items():
                    if n >= 2 and i not in results:  # running both times a worker died: the culprit
                        d = _job_dir(self.config, initial_job_idx + i)
                        write_json(d / "metrics.json", {"status": "failed", "error": "the job's worker process was "
                                   "killed by the OS twice (out of memory?)", "experiment": None})
                        results[i] = JobReturn(overrides=list(job_overrides[i]), status=JobStatus.COMPLETED,
                                               _return_value=None)
        for i in pending:  # still lost after the last round
            if i not in results:
                d = _job_dir(self.config, initial_job_idx + i)
                write_json(d / "metrics.json", {"status": "failed", "error": "the job's worker was killed by the OS"})
                results[i] = JobReturn(overrides=list(job_overrides[i]), status=JobStatus.COMPLETED, _return_value=None)
        return [results[i] for i in pending]
