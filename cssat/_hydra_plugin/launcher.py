"""A joblib launcher for Hydra sweeps that survives a worker killed by the OS.

hydra-joblib-launcher runs the jobs in loky worker processes; when the OS kills one (the OOM
killer, a SIGKILL), loky raises ``TerminatedWorkerError`` for the whole batch and the sweep ends
with no summary. :class:`RobustJoblibLauncher` (``launcher=local``) runs the batch again without
the jobs that finished. The jobs that were running when a worker died are then run one at a time:
a job whose worker dies twice while it runs alone is the one killing it, and is recorded as
failed (its ``metrics.json`` says ``status: failed``) so that the rest of the sweep finishes and
the summary is written; a job that only shared a batch with it is never blamed. ``retries``
bounds the deaths with no job started (nothing to blame).

A job whose directory cannot be written (a full disk: Hydra's own ``.hydra/`` files of the job
fail before the job starts) is logged in one line and costs that job only: the sweep goes on and
its summary says what is missing — never a traceback out of the launcher.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any, Sequence

from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, setup_globals
from omegaconf import OmegaConf

try:
    from hydra_plugins.hydra_joblib_launcher.joblib_launcher import JoblibLauncher
except ImportError:  # pragma: no cover - the launchers extra is not installed
    JoblibLauncher = object  # type: ignore[misc,assignment]

log = logging.getLogger("cssat")

__all__ = ["RobustJoblibLauncher"]


def _job_dir(config: Any, idx: int) -> Path:
    """The directory of job ``idx``: ``hydra.sweep.dir / hydra.sweep.subdir`` with the job number
    (cssat's subdir is ``${hydra.job.num}``; read unresolved, as the number is not set here)."""
    sub = str(OmegaConf.to_container(config.hydra.sweep, resolve=False)["subdir"])
    return Path(str(config.hydra.sweep.dir)) / sub.replace("${hydra.job.num}", str(idx))


def _execute_job(idx: int, overrides: Sequence[str], hydra_context: Any, config: Any, task_function: Any,
                 singleton_state: Any) -> JobReturn:
    """Hydra's ``execute_job`` in a loky worker; an OS error of writing the job's own files (Hydra's
    ``.hydra/``, before cssat's task runs) is the job's failure, in one line, not the sweep's end."""
    from hydra_plugins.hydra_joblib_launcher import _core  # startup: joblib, only when a sweep launches

    logging.raiseExceptions = False  # a job's log file on a full disk: its lines dropped, no "Logging error" tracebacks
    try:
        return _core.execute_job(idx, overrides, hydra_context, config, task_function, singleton_state)
    except OSError as err:
        where = err.filename if err.filename is not None else _job_dir(config, idx)
        logging.getLogger("cssat").error("job %d failed: cannot write its results: %s: %s", idx, where,
                                          err.strerror or err)
        return JobReturn(overrides=list(overrides), status=JobStatus.COMPLETED, _return_value=None)


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
        from joblib import Parallel, delayed  # startup: joblib, only when a sweep launches

        from hydra_plugins.hydra_joblib_launcher import _core  # startup: joblib, only when a sweep launches

        setup_globals()
        cfg = dict(self.joblib)
        cfg["backend"] = "loky"
        _core.process_joblib_cfg(cfg)
        Path(str(self.config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
        state = Singleton.get_state()
        log.info("sweep: launching %d jobs in %s loky workers", len(batch), cfg.get("n_jobs"))
        return Parallel(**cfg)(
            delayed(_execute_job)(initial_job_idx + i, job_overrides[i], self.hydra_context, self.config,
                                  self.task_function, state)
            for i in batch
        )

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int):
        """Run every job; after a worker dies, the jobs that were running then are run again one
        at a time, so a job is blamed (recorded ``failed``) only when its worker dies twice while
        it runs alone — never a job that only shared the batch with the culprit."""
        from joblib.externals.loky.process_executor import TerminatedWorkerError  # startup: joblib, only when a sweep launches

        def done(i: int) -> JobReturn:
            return JobReturn(overrides=list(job_overrides[i]), status=JobStatus.COMPLETED, _return_value=None)

        pending = list(range(len(job_overrides)))
        results: dict[int, Any] = {}
        suspects: list[int] = []  # started when a worker died: from then on run alone
        deaths: dict[int, int] = {}  # worker deaths while the job ran alone
        blind = 0  # deaths with no job started (nothing to blame)
        while True:
            todo = [i for i in pending if i not in results]
            if not todo:
                break
            solo = [i for i in suspects if i not in results]
            batch = solo[:1] or todo
            try:
                results.update(zip(batch, self._run(job_overrides, batch, initial_job_idx)))
                continue
            except TerminatedWorkerError as err:
                log.error("sweep: a worker was killed (%s); running the unfinished jobs again", str(err).splitlines()[0])
            started = []
            for i in batch:
                state = _state(_job_dir(self.config, initial_job_idx + i))
                if state == "done":
                    results[i] = done(i)
                elif state == "started":
                    started.append(i)
            if len(batch) == 1 and started == batch:
                i = batch[0]
                deaths[i] = deaths.get(i, 0) + 1
                if deaths[i] >= 2:  # its worker died twice while it ran alone: the culprit
                    self._fail(i, initial_job_idx, "the job's worker process was killed by the OS twice while it "
                               "ran alone (out of memory?)")
                    results[i] = done(i)
            elif started:
                suspects.extend(i for i in started if i not in suspects)
            else:
                blind += 1
                if blind > self.retries:
                    for i in todo:
                        if i not in results:
                            self._fail(i, initial_job_idx, "the job's worker was killed by the OS")
                            results[i] = done(i)
        return [results[i] for i in pending]

    def _fail(self, i: int, initial_job_idx: int, error: str) -> None:
        from cssat.experiments.files import write_json  # startup: cssat.experiments.files imports numpy

        write_json(_job_dir(self.config, initial_job_idx + i) / "metrics.json",
                   {"status": "failed", "error": error, "experiment": None})
