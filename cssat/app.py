"""The ``cssat`` console script: a Hydra app over ``conf/`` (packaged as ``cssat.conf``).

``cssat experiment=sim1 cs.m=4096`` runs one job; ``cssat -m ...`` sweeps. Outputs go to Hydra's
run directory (``outputs/<date>/<time>/`` by default), which this app passes down explicitly:
library code never reads Hydra state.
"""

from __future__ import annotations

import errno
import logging
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator

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
            log.error("job failed: %s", _os_error(err, output_dir) if isinstance(err, OSError) else err)
            return None
        if isinstance(err, FieldError):  # bad input: its field is in the error, not parsed from a message
            log.error("bad input: %s", err)
            sys.exit(2)
        if isinstance(err, OSError):  # the machine, not the input: a full disk, a read-only directory
            writing = err.errno in WRITE_ERRNOS
            log.error("%s: %s", "cannot write the results" if writing else "system error", _os_error(err, output_dir))
            sys.exit(1)
        raise
    key = cfg.get("optimized_metric", "psnr")
    value = metrics.get(key) if key else None
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


#: the errors of a file system that refuses a write: full, read-only, no permission, in the way
WRITE_ERRNOS = (errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EPERM, errno.EDQUOT, errno.EEXIST, errno.ENOTDIR,
                errno.EISDIR, errno.EFBIG)


@contextmanager
def _write_errors_in_one_line(where: str = "the output directory") -> Iterator[None]:
    """Within the block, an OS error of writing (a full disk, a read-only directory) that escapes
    Hydra's own code — the sweep's ``multirun.yaml``, a callback, a launcher — ends the run with
    one line and exit status 1 instead of Hydra's printed traceback. Hydra prints an exception
    itself (``hydra._internal.utils.run_and_report``), so the function it runs is wrapped; where
    that private name is missing, Hydra's own report stands."""
    from hydra._internal import utils as hydra_utils  # startup: hydra is imported already

    original = getattr(hydra_utils, "run_and_report", None)
    caught: list[OSError] = []

    def run_and_report(func: Callable[[], Any]) -> Any:
        def guarded() -> Any:
            try:
                return func()
            except OSError as err:
                if err.errno not in WRITE_ERRNOS:
                    raise
                caught.append(err)
                return None

        return original(guarded)

    if original is not None:
        hydra_utils.run_and_report = run_and_report
    try:
        yield
    finally:
        if original is not None:
            hydra_utils.run_and_report = original
    if caught:
        err = caught[0]
        print(f"cannot write the results: {_os_error(err, where)}", file=sys.stderr)
        sys.exit(1)


def _os_error(err: OSError, where: str | Path) -> str:
    """``<path>: <cause>`` of an OS error, in one line."""
    path = err.filename if err.filename is not None else where
    cause = err.strerror or (os.strerror(err.errno) if isinstance(err.errno, int) else "") or str(err)
    return f"{path}: {cause or type(err).__name__ + ' (the system gave no reason)'}"


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
    logging.raiseExceptions = False  # also in a launcher's worker: a log file on a full disk drops its lines
    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    choice = hc.runtime.choices.get("experiment")
    if choice and cfg.get("experiment_name") != choice:  # an experiment is its YAML: the file names it
        with open_dict(cfg):
            cfg.experiment_name = choice
    if OmegaConf.select(cfg, "catalogue.shard", default=None) is not None and not cfg.get("experiment_module"):
        with open_dict(cfg):  # a catalogue's shard: many files in this job (cssat/catalogue_shards.py)
            cfg.experiment_module = "cssat.catalogue_shards"
    tags = None
    if multirun:  # mark the job directory with its sweep's id (the summary keeps this sweep's jobs)
        sid = sweep_id(hc.sweep.dir)
        if sid is not None:
            out = Path(hc.runtime.output_dir)
            try:
                out.mkdir(parents=True, exist_ok=True)
                atomic_write(out / SWEEP_MARK, lambda tmp: Path(tmp).write_text(sid + "\n"), result=False)
            except OSError as err:  # a full disk: this job fails (its row says so), the sweep goes on
                log.error("job failed: cannot write the results: %s", _os_error(err, out))
                return None
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
#: the launchers (``launcher=<name>``) and the Hydra plugin package each needs (the launchers extra)
LAUNCHER_PLUGINS = {"local": ("hydra_plugins.hydra_joblib_launcher", "hydra-joblib-launcher"),
                    "slurm": ("hydra_plugins.hydra_submitit_launcher", "hydra-submitit-launcher"),
                    "submitit_local": ("hydra_plugins.hydra_submitit_launcher", "hydra-submitit-launcher")}


def _last_value(argv: list[str], key: str) -> str | None:
    """The value of the last ``key=...`` override of ``argv`` (``+key``/``++key`` too), or ``None``."""
    found = None
    for a in argv:
        k, eq, v = a.partition("=")
        if eq and k.lstrip("+") == key:
            found = v
    return found


def _is_file_sweep(value: str) -> bool:
    """A directory or a glob (``*``, ``?``, ``[``), not a Hydra sweep or quoted value of its own."""
    if value[:1] in "'\"" or "(" in value:
        return False
    return os.path.isdir(value) or ("," not in value and any(c in value for c in "*?["))


def _shard_size(argv: list[str]) -> int:
    """``catalogue.shard_size`` of the command line (an integer >= 1) or the experiment's default."""
    from cssat.catalogue import DEFAULT_SHARD_SIZE  # startup: cssat.catalogue is light (the standard library)

    text = _last_value(argv, "catalogue.shard_size")
    if text is None:
        return DEFAULT_SHARD_SIZE
    try:
        size = int(text)
    except ValueError:
        size = 0
    if size < 1 or str(size) != text.strip():
        raise ValueError(f"catalogue.shard_size: expected one integer >= 1 (files a job), got {text!r}")
    return size


def expand_file_sweeps(argv: list[str]) -> list[str]:
    """A multirun's ``observations=<directory>`` or ``observations=<glob>`` (``*``, ``?``, ``[``)
    as a catalogue. With ``experiment=characterise``: *shards* — the sorted file list
    (:func:`cssat.catalogue.catalogue_files`) cut into ``catalogue.shard_size`` files a job, the
    sweep ``catalogue.shard=range(0,K)`` (unless the command line names its shards) with the list's
    size and hash (``catalogue.n_files``, ``catalogue.listing_sha``) that every shard checks; the
    file names themselves are never overrides. Another experiment: one job per file, each path
    quoted literally. The directory or glob is quoted literally too (no ``${...}`` interpolation).
    A pattern that matches nothing, a bad ``catalogue.shard_size``: a ``ValueError`` naming the key."""
    from cssat._checks import FieldError  # startup: light
    from cssat.catalogue import catalogue_files, listing_sha, literal_override, n_shards  # startup: light

    out, extra = [], []
    characterise = _last_value(argv, "experiment") == "characterise"
    for a in argv:
        key, eq, value = a.partition("=")
        if eq and key.lstrip("+") in FILE_SWEEP_KEYS and _is_file_sweep(value):
            try:
                files = catalogue_files(value)
            except FieldError as err:
                raise ValueError(f"{key.lstrip('+')}: {err.detail}") from None
            if characterise:
                size = _shard_size(argv)
                a = literal_override(key, value)
                if _last_value(argv, "catalogue.shard") is None:
                    extra.append(f"catalogue.shard=range(0,{n_shards(len(files), size)})")
                extra += [f"catalogue.n_files={len(files)}", f"catalogue.listing_sha='{listing_sha(files)}'"]
            else:
                a = f"{key}=" + ",".join(literal_override(key, f).partition("=")[2] for f in files)
        elif eq and key.lstrip("+") in FILE_SWEEP_KEYS and value[:1] not in "'\"" and os.path.exists(value):
            a = literal_override(key, value)  # a file's name is data: t_${experiment_name}.txt is that file
        out.append(a)
    return out + extra


def literal_paths(argv: list[str]) -> list[str]:
    """A single run's ``observations=<path>`` quoted literally when that path exists as written,
    so Hydra does not interpolate a ``${...}`` in a file's name (a value with ``${...}`` that is
    no file is left to Hydra: a deliberate ``${oc.env:DATA}/track.txt``)."""
    from cssat.catalogue import literal_override  # startup: light

    out = []
    for a in argv:
        key, eq, value = a.partition("=")
        if eq and key.lstrip("+") in FILE_SWEEP_KEYS and value[:1] not in "'\"" and os.path.exists(value):
            a = literal_override(key, value)
        out.append(a)
    return out


def missing_launcher(argv: list[str]) -> str | None:
    """One line naming the ``launchers`` extra when ``launcher=<name>`` needs a Hydra plugin that is
    not installed (Hydra's own error: ``Could not find 'hydra/launcher/joblib'``), else ``None``."""
    import importlib.util  # startup: the standard library

    name = _last_value(argv, "launcher")
    if name not in LAUNCHER_PLUGINS:
        return None
    module, dist = LAUNCHER_PLUGINS[name]
    try:
        found = importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        found = False
    if found:
        return None
    return (f"launcher: launcher={name} needs {dist}, which is not installed: pip install 'cssat[launchers]' "
            f"(or leave launcher out: the jobs then run one after another)")


def main() -> None:
    """Console-script entry point. A sweep (``-m``) whose jobs did not all end ``ok`` exits 1,
    after every job has run and the summary is written — 2 when every job was refused as bad
    input (a ``FieldError``: the same exit as one bad run)."""
    logging.raiseExceptions = False  # a log file on a full disk: drop its lines, never print tracebacks
    if "--version" in sys.argv[1:] or "-V" in sys.argv[1:]:  # cssat's version, not Hydra's
        print(f"cssat {__version__}")
        return
    _register_launcher()
    why = missing_launcher(sys.argv[1:])
    if why is not None:
        print(f"bad input: {why}", file=sys.stderr)
        sys.exit(2)
    try:
        if any(a in ("-m", "--multirun") for a in sys.argv[1:]):
            sys.argv[1:] = expand_file_sweeps(sys.argv[1:])
        else:
            sys.argv[1:] = literal_paths(sys.argv[1:])
    except ValueError as err:
        print(f"bad input: {err}", file=sys.stderr)
        sys.exit(2)
    overrides = _cli_check.overrides_of(sys.argv[1:])
    if overrides:  # a mistake on the command line: one line naming the key, exit 2 (not Hydra's text)
        why = _cli_check.check(overrides)
        if why is None and _last_value(overrides, "catalogue.n_files") is not None:  # a catalogue: its settings, once
            why = _cli_check.check_catalogue(overrides)
        if why is not None:
            print(f"bad input: {why}", file=sys.stderr)
            sys.exit(2)
    why = _check_output_dir(overrides or [], any(a in ("-m", "--multirun") for a in sys.argv[1:]))
    if why is not None and overrides is not None:
        print(f"cannot write the results: {why}", file=sys.stderr)
        sys.exit(1)
    multirun = any(a in ("-m", "--multirun") for a in sys.argv[1:])
    where = _last_value(overrides or [], "hydra.sweep.dir" if multirun else "hydra.run.dir")
    with _write_errors_in_one_line(where or "the output directory (outputs/)"):
        _hydra_main()
    if summary.SWEEP_BAD_INPUT:  # every job refused its config: the command line is wrong, as a single run's exit 2
        log.error("sweep: every job was refused as bad input (see each job's error in summary.csv)")
        sys.exit(2)
    if summary.SWEEP_FAILED:
        log.error("sweep: not every job ended ok (see summary.csv)")
        sys.exit(1)


if __name__ == "__main__":
    main()
