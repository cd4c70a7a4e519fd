"""The ``cssat`` console script: a Hydra app over ``conf/`` (packaged as ``cssat.conf``).

``cssat experiment=sim1 cs.m=4096`` runs one job; ``cssat -m ...`` sweeps. Outputs go to Hydra's
run directory (``outputs/<date>/<time>/`` by default), which this app passes down explicitly:
library code never reads Hydra state.
"""

from __future__ import annotations

import errno
import glob
import logging
import os
import sys
from pathlib import Path
from typing import Any, Callable

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.core.plugins import Plugins
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict

from cssat import __version__, _cli_check, summary
from cssat._checks import FieldError
from cssat._tmpfiles import atomic_write
from cssat.summary import SWEEP_MARK, sweep_id

log = logging.getLogger("cssat")

#: the metrics a sweeper may optimise (``optimized_metric``): every experiment that reconstructs
#: an image writes them
OPTIMIZED_METRICS = ("psnr", "ssim", "psnr_denoised", "ssim_denoised")


def task(cfg: Any, output_dir: str | Path, multirun: bool = False, finalize: Callable[[], None] | None = None,
         tags: dict[str, Any] | None = None) -> float | None:
    """Run one job of the app into ``output_dir`` and return the metric named by
    ``cfg.optimized_metric`` (default ``psnr``; ``None`` when it is null or not a number), the
    value a sweeper such as Optuna's optimises.

    A bad config exits with status 2 after logging one line naming the field; in a multirun a
    failed job is logged and returns ``None`` (its ``metrics.json`` says ``status: failed``), so
    the sweep goes on.
    """
    from tqdm.contrib.logging import logging_redirect_tqdm  # startup: tqdm, only when a job runs

    from cssat.experiments import run_experiment  # startup: cssat.experiments imports numpy, only when a job runs

    try:
        key = cfg.get("optimized_metric", "psnr")
        if key is not None and key not in OPTIMIZED_METRICS:  # checked before any work
            raise FieldError("optimized_metric", f"expected one of {list(OPTIMIZED_METRICS)} or null, got {key!r}")
        with logging_redirect_tqdm():  # log lines printed above the progress bars, not through them
            metrics = run_experiment(cfg, output_dir, finalize=finalize, tags=tags)
    except Exception as err:
        if multirun:
            log.error("job failed: %s", err)
            return None
        if isinstance(err, FieldError):  # bad input: its field is in the error, not parsed from a message
            log.error("bad input: %s", err)
            sys.exit(2)
        if isinstance(err, OSError):  # the machine, not the input: a full disk, a read-only directory
            writing = err.errno in (errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EPERM, errno.EDQUOT,
                                    errno.EEXIST, errno.ENOTDIR, errno.EISDIR)
            log.error("%s: %s", "cannot write the results" if writing else "system error", _os_error(err, output_dir))
            sys.exit(1)
        raise
    key = cfg.get("optimized_metric", "psnr")
    value = metrics.get(key) if key else None
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _os_error(err: OSError, where: str | Path) -> str:
    """``<path>: <cause>`` of an OS error, in one line."""
    path = err.filename if err.filename is not None else where
    return f"{path}: {err.strerror or err}"


def _check_output_dir(overrides: list[str], multirun: bool) -> str | None:
    """Why the run's output directory cannot be written (a file in its place, a read-only or
    unwritable parent), or ``None``; checked before Hydra creates it."""
    key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    given = [o.split("=", 1)[1] for o in overrides if o.split("=", 1)[0].lstrip("+") == key]
    path = Path(given[-1]) if given and "${" not in given[-1] else Path("outputs" if not given else ".")
    p = path if str(path) else Path(".")
    if p.exists() and not p.is_dir():
        return f"{key}: {p} exists and is not a directory"
    while not p.exists():
        p = p.parent
    if not os.access(p, os.W_OK | os.X_OK):
        return f"{key}: {p} is not writable (read-only file system or no permission)"
    return None


@hydra.main(version_base="1.3", config_path="pkg://cssat.conf", config_name="config")
def _hydra_main(cfg: DictConfig) -> float | None:
    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    choice = hc.runtime.choices.get("experiment")
    if choice and cfg.get("experiment_name") != choice:  # an experiment is its YAML: the file names it
        with open_dict(cfg):
            cfg.experiment_name = choice
    tags = None
    if multirun:  # mark the job directory with its sweep's id (the summary keeps this sweep's jobs)
        sid = sweep_id(hc.sweep.dir)
        if sid is not None:
            out = Path(hc.runtime.output_dir)
            out.mkdir(parents=True, exist_ok=True)
            (out / SWEEP_MARK).write_text(sid + "\n")
            tags = {"sweep_id": sid}

    def save_hydra_files() -> None:
        """Hydra wrote ``.hydra/`` before this run took the directory's lock; a second run refused
        by the lock may have overwritten them since: write this run's again, under the lock."""
        sub = hc.output_subdir
        if not sub:
            return
        d = Path(hc.runtime.output_dir) / sub
        task_cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]) if "hydra" in cfg else cfg
        for name, node in (("config.yaml", task_cfg), ("overrides.yaml", OmegaConf.create(list(hc.overrides.task)))):
            atomic_write(d / name, lambda tmp, node=node: OmegaConf.save(node, tmp), result=False)

    return task(cfg, hc.runtime.output_dir, multirun=multirun, finalize=save_hydra_files, tags=tags)


def _register_launcher() -> None:
    """Register cssat's joblib launcher with Hydra (``launcher=local``): an editable install maps
    ``hydra_plugins.cssat_launcher`` into place, where Hydra's own package scan does not look."""
    try:
        from hydra_plugins.cssat_launcher.launcher import RobustJoblibLauncher  # local: optional (launchers extra)
    except ImportError:  # the launchers extra (hydra-joblib-launcher) is not installed
        return
    if isinstance(RobustJoblibLauncher, type) and RobustJoblibLauncher.__mro__[1] is not object:
        Plugins.instance().register(RobustJoblibLauncher)


#: the keys whose value a sweep may give as a directory or a glob of files (a catalogue)
FILE_SWEEP_KEYS = ("observations",)


def expand_file_sweeps(argv: list[str]) -> list[str]:
    """A multirun's ``observations=<directory>`` or ``observations=<glob>`` (``*``, ``?``, ``[``)
    as Hydra's sweep of those files, sorted and quoted: one job per file (a catalogue of
    thousands of tracks through Hydra's launchers). A pattern that matches nothing is a
    ``ValueError`` naming the key."""
    out = []
    for a in argv:
        key, eq, value = a.partition("=")
        if eq and key.lstrip("+") in FILE_SWEEP_KEYS and "(" not in value and "," not in value and (
                os.path.isdir(value) or any(c in value for c in "*?[")):
            pattern = os.path.join(value, "*") if os.path.isdir(value) else value
            files = sorted(f for f in glob.glob(pattern) if os.path.isfile(f) and not os.path.basename(f).startswith("."))
            if not files:
                raise ValueError(f"{key}: no file matches {pattern!r}")
            quote = lambda f: "'" + f.replace("\\", "\\\\").replace("'", "\\'") + "'"  # noqa: E731
            a = f"{key}=" + ",".join(quote(os.path.abspath(f)) for f in files)
        out.append(a)
    return out


def main() -> None:
    """Console-script entry point. A sweep (``-m``) whose jobs did not all end ``ok`` exits 1,
    after every job has run and the summary is written."""
    logging.raiseExceptions = False  # a log file on a full disk: drop its lines, never print tracebacks
    if "--version" in sys.argv[1:] or "-V" in sys.argv[1:]:  # cssat's version, not Hydra's
        print(f"cssat {__version__}")
        return
    _register_launcher()
    if any(a in ("-m", "--multirun") for a in sys.argv[1:]):
        try:
            sys.argv[1:] = expand_file_sweeps(sys.argv[1:])
        except ValueError as err:
            print(f"bad input: {err}", file=sys.stderr)
            sys.exit(2)
    overrides = _cli_check.overrides_of(sys.argv[1:])
    if overrides:  # a mistake on the command line: one line naming the key, exit 2 (not Hydra's text)
        why = _cli_check.check(overrides)
        if why is not None:
            print(f"bad input: {why}", file=sys.stderr)
            sys.exit(2)
    why = _check_output_dir(overrides or [], any(a in ("-m", "--multirun") for a in sys.argv[1:]))
    if why is not None and overrides is not None:
        print(f"cannot write the results: {why}", file=sys.stderr)
        sys.exit(1)
    _hydra_main()
    if summary.SWEEP_FAILED:
        log.error("sweep: not every job ended ok (see summary.csv)")
        sys.exit(1)


if __name__ == "__main__":
    main()
