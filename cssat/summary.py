"""Sweep summaries: ``summary.csv`` (one row per job) and a plot of PSNR against the swept values.

Written by a Hydra callback at the end of every multirun (:class:`SummaryCallback`, registered in
``conf/config.yaml``), and by the standalone ``cssat-summarize <sweep dir>`` for sweeps that were
interrupted or had failures. A job is a sub-directory with Hydra's ``.hydra/overrides.yaml``; its
row holds the swept values, every scalar metric of its ``metrics.json``, ``seconds`` and
``status`` (``ok``, ``failed``, ``missing`` when the job left no metrics or its metrics are
another sweep's, ``corrupt`` when they cannot be read, were edited since the run — ``metrics.json`` carries the
digest of itself — or a result file no longer has its hash).
``cssat-summarize`` exits 1 when a row is not ``ok``.

A catalogue sweep (``cssat -m experiment=characterise observations=<dir>``: jobs of
``catalogue.shard``, :mod:`cssat.catalogue`) also gets ``catalogue.csv``, the shards' tables
joined — one row per file — written atomically and only when every shard is complete and its
table still has its hash; otherwise the summary says which shard is not, and no ``catalogue.csv``
is left (:func:`join_catalogue`).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import yaml

from cssat._tmpfiles import atomic_write

if TYPE_CHECKING:
    from omegaconf import DictConfig

log = logging.getLogger("cssat")

__all__ = ["collect", "summarize", "join_catalogue", "SummaryCallback", "main"]


def _parse_overrides(path: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in yaml.safe_load(path.read_text()) or []:
        key, _, value = str(item).partition("=")
        if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"":  # a quoted value (a file path)
            value = value[1:-1]
        out[key.lstrip("+~")] = value
    return out


def _number(text: Any) -> Any:
    if not isinstance(text, str):
        return text
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


SWEEP_MARK = ".cssat-sweep"
#: held by the sweep's main process from its start to its summary: one sweep per directory
SWEEP_LOCK = ".cssat-sweep.lock"


def sweep_id(directory: str | Path) -> str | None:
    """The id of the sweep that last ran in ``directory`` (a sweep or a job directory), if any."""
    try:
        return (Path(directory) / SWEEP_MARK).read_text().strip() or None
    except OSError:
        return None


def collect(sweep_dir: str | Path) -> tuple[list[dict[str, Any]], list[str]]:
    """Rows of a sweep (one per job directory, in job order) and the override keys that vary.

    Only the jobs of the sweep that last ran in ``sweep_dir`` count: each job marks its directory
    with the sweep's id, so folders left by an earlier, larger sweep into the same directory are
    left out. A job whose ``metrics.json`` cannot be read is a row with ``status: corrupt``."""
    sweep_dir = Path(sweep_dir)
    current = sweep_id(sweep_dir)
    jobs = sorted(
        (p.parent.parent for p in sweep_dir.glob("*/.hydra/overrides.yaml")),
        key=lambda p: (0, int(p.name)) if p.name.isdigit() else (1, p.name),
    )
    if current is not None:
        jobs = [j for j in jobs if sweep_id(j) == current]
    rows, overrides = [], []
    for job in jobs:
        ov = _parse_overrides(job / ".hydra" / "overrides.yaml")
        overrides.append(ov)
        row: dict[str, Any] = {"job": job.name}
        metrics_path = job / "metrics.json"
        if metrics_path.exists():
            try:
                metrics = json.loads(metrics_path.read_text())
                if not isinstance(metrics, dict):
                    raise ValueError("not a JSON object")
            except (OSError, ValueError) as err:
                metrics = {"status": "corrupt", "error": f"{metrics_path}: {err}"}
            for k, v in metrics.items():
                if v is None or isinstance(v, (int, float, str, bool)):
                    row[k] = v
            row.update(_verify(job, metrics, current))
        else:
            row["status"] = "missing"
        rows.append(row)
    keys: list[str] = []
    for ov in overrides:
        for k in ov:
            if k not in keys:
                keys.append(k)
    swept = [k for k in keys if len({ov.get(k) for ov in overrides}) > 1]
    for row, ov in zip(rows, overrides):
        for k in swept:
            row[k] = _number(ov.get(k))
    return rows, swept


def _verify(job: Path, metrics: dict, current: str | None) -> dict[str, Any]:
    """``{}`` when the job's ``metrics.json`` is this sweep's and its result files still hash as
    listed; else the ``status`` (``missing``: another sweep's results; ``corrupt``) and ``error``."""
    from cssat.experiments.results import files_problem, seal_problem  # startup: cssat.experiments.results imports numpy

    sid = metrics.get("sweep_id")
    if current is not None and sid is not None and sid != current:
        return {"status": "missing", "error": f"the job did not run in this sweep (its results are of sweep {sid})"}
    if metrics.get("status") != "ok":
        return {}
    why = seal_problem(metrics)
    if why is not None:
        return {"status": "corrupt", "error": why}
    files = metrics.get("files")
    if not isinstance(files, dict):
        return {"status": "corrupt", "error": "metrics.json lists no result files"}
    why = files_problem(job, files)
    return {} if why is None else {"status": "corrupt", "error": why}


#: swept config keys in words, and those plotted as a ratio of the pixel count
AXIS_WORDS = {"cs.m": "m / N (measurement ratio)", "cs.ratio": "m / N (measurement ratio)",
              "reference.n": "N_ref / N (references per pixel)", "target.size": "image size (pixels per side)",
              "noise.relative": "relative noise level", "noise.magnitude": "V magnitude", "seed": "seed",
              "geometry.angular_size_arcsec": "angular size (arcsec)"}
PER_PIXEL = ("cs.m", "reference.n")


def plot_values(rows: list[dict[str, Any]], swept: list[str]) -> tuple[list[dict[str, Any]], list[str], dict[str, str]]:
    """``(rows, swept, labels)`` for :func:`cssat.plots.sweep_figure`: ``cs.m`` and
    ``reference.n`` as ratios of ``n_pixels`` where the rows know it, the keys in words."""
    out = []
    for r in rows:
        r = dict(r)
        for key in PER_PIXEL:
            v, npix = r.get(key), r.get("n_pixels")
            if isinstance(v, (int, float)) and npix:
                r[key] = v / npix
        out.append(r)
    return out, swept, {k: AXIS_WORDS[k] for k in swept if k in AXIS_WORDS}


def summarize(sweep_dir: str | Path, metric: str = "psnr", collected: tuple | None = None,
              figure_format: str = "png") -> tuple[Path, Path | None]:
    """Write ``summary.csv`` and ``summary_<metric>.<figure_format>`` into ``sweep_dir``; return
    their paths. ``collected``: the result of :func:`collect` when the caller has it already."""
    from cssat.experiments.files import write_csv  # startup: cssat.experiments.files imports numpy
    from cssat.plots import save_figure, sweep_figure  # startup: cssat.plots imports numpy

    sweep_dir = Path(sweep_dir)
    rows, swept = collected if collected is not None else collect(sweep_dir)
    first = ["job", *swept, "status", metric]
    cols = first + sorted({k for r in rows for k in r} - set(first))

    csv_path = sweep_dir / "summary.csv"
    write_csv(csv_path, rows, cols)
    values, names, labels = plot_values(rows, swept)
    fig = sweep_figure(values, names, metric, labels=labels)
    png = None
    if fig is not None:
        png = sweep_dir / f"summary_{metric}.{figure_format}"
        save_figure(fig, png)
    n_ok = sum(r.get("status") == "ok" for r in rows)
    log.info("sweep summary: %d jobs (%d ok) -> %s", len(rows), n_ok, csv_path)
    return csv_path, png


def join_catalogue(sweep_dir: str | Path, rows: list[dict[str, Any]]) -> bool:
    """Join a catalogue sweep's shards into ``sweep_dir/catalogue.csv``
    (:func:`cssat.catalogue_shards.join_shards`) and log it; ``False`` when it is a catalogue sweep and
    the catalogue could not be joined (the log says why), else ``True``."""
    from cssat.catalogue_shards import join_shards  # startup: light

    path, why = join_shards(sweep_dir, rows)
    if why is not None:
        log.error("catalogue not joined: %s", why)
        return False
    if path is not None:
        n = sum(int(r.get("n_files") or 0) for r in rows)
        failed = sum(int(r.get("n_failed") or 0) for r in rows)
        log.info("catalogue: %d files (%d failed to characterise) in %d shards -> %s", n, failed, len(rows), path)
    return True


try:  # the callback needs hydra, which cssat depends on; keep the import cheap for the CLI
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover
    Callback = object  # type: ignore[misc,assignment]


#: set when the last multirun of this process had a job that did not end ``ok`` (the app then exits 1)
SWEEP_FAILED = False
#: set when every job of the last multirun was refused as bad input (its ``error`` a ``FieldError``:
#: the app then exits 2, as a single bad run does)
SWEEP_BAD_INPUT = False
#: the sweep directories this process holds (their ``FileLock``), from a multirun's start to its end
_SWEEP_LOCKS: dict[str, Any] = {}


class SummaryCallback(Callback):
    """Hydra callback: marks the sweep directory with a new sweep id when a multirun starts, and
    :func:`summarize` s it when the multirun ends (noting whether every job ended ``ok``)."""

    def __init__(self, metric: str = "psnr"):
        self.metric = metric

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        from filelock import FileLock, Timeout  # startup: filelock, loaded only when on_multirun_start() runs

        d = Path(config.hydra.sweep.dir)
        d.mkdir(parents=True, exist_ok=True)
        lock = FileLock(str(d / SWEEP_LOCK), timeout=0)
        try:
            lock.acquire()
        except Timeout:
            try:
                other = (d / (SWEEP_LOCK + ".pid")).read_text().strip()
            except OSError:
                other = "?"
            log.error("hydra.sweep.dir: %s is in use by another cssat sweep (pid %s); wait for it or choose "
                      "another hydra.sweep.dir", d, other)
            sys.exit(2)
        _SWEEP_LOCKS[str(d)] = lock  # module state, not the callback's: Hydra pickles callbacks to the workers
        (d / (SWEEP_LOCK + ".pid")).write_text(str(os.getpid()))
        atomic_write(d / SWEEP_MARK, lambda tmp: Path(tmp).write_text(uuid.uuid4().hex + "\n"), result=False)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        global SWEEP_FAILED, SWEEP_BAD_INPUT
        try:
            collected = collect(config.hydra.sweep.dir)
            SWEEP_FAILED = any(r.get("status") != "ok" for r in collected[0]) or not collected[0]
            SWEEP_BAD_INPUT = bool(collected[0]) and all(
                r.get("status") == "failed" and str(r.get("error", "")).startswith("FieldError:") for r in collected[0])
            summarize(config.hydra.sweep.dir, self.metric, collected, str(config.get("figure_format") or "png"))
            if not join_catalogue(config.hydra.sweep.dir, collected[0]):
                SWEEP_FAILED = True
        except Exception as err:  # a summary must never turn a finished sweep into a traceback
            if isinstance(err, OSError):  # a full disk, a read-only directory: the results are not all written
                SWEEP_FAILED = True
            log.error("sweep summary failed: %s (run cssat-summarize %s)", _one_line(err), config.hydra.sweep.dir)
        lock = _SWEEP_LOCKS.pop(str(config.hydra.sweep.dir), None)
        if lock is not None:
            lock.release()


def _one_line(err: BaseException) -> str:
    """An error in one line (an OSError: ``<path>: <cause>``)."""
    if isinstance(err, OSError) and err.strerror:
        return f"{err.filename}: {err.strerror}" if err.filename else err.strerror
    lines = str(err).strip().splitlines()
    return lines[0] if lines else type(err).__name__


def main(argv: Sequence[str] | None = None) -> int:
    """``cssat-summarize <sweep dir> [--metric psnr] [--format png|pdf|svg]``."""
    ap = argparse.ArgumentParser(prog="cssat-summarize", description="Summarise a cssat sweep directory.")
    ap.add_argument("sweep_dir", help="a multirun directory (outputs/multirun/<date>/<time>)")
    ap.add_argument("--metric", default="psnr", help="metric to plot (default: psnr)")
    ap.add_argument("--format", default="png", choices=["png", "pdf", "svg"], help="figure format (default: png)")
    args = ap.parse_args(argv)
    d = Path(args.sweep_dir)
    if not d.is_dir():
        ap.error(f"sweep_dir: {d} is not a directory")
    if not any(d.glob("*/.hydra/overrides.yaml")):
        ap.error(f"sweep_dir: no job directories (*/.hydra/overrides.yaml) in {d}")
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    collected = collect(d)
    rows = collected[0]
    catalogue = any(r.get("catalogue_table") is not None for r in rows)
    if not catalogue and not any(args.metric in r for r in rows):
        columns = sorted({k for r in rows for k in r if isinstance(r[k], (int, float)) and not isinstance(r[k], bool)})
        ap.error(f"--metric: no job has {args.metric!r}; numeric columns: {', '.join(columns) or 'none'}")
    try:
        csv_path, png = summarize(d, args.metric, collected, args.format)
        joined = join_catalogue(d, rows)
    except OSError as err:  # a full disk, a read-only directory: one line, nothing half-written
        log.error("cannot write the summary: %s", _one_line(err))
        return 1
    print(csv_path)
    if png:
        print(png)
    if catalogue and joined:
        print(d / "catalogue.csv")
    bad = [f"{r['job']}: {r.get('status')}" for r in rows if r.get("status") != "ok"]
    if bad or not rows or not joined:
        log.error("not every job ended ok: %s", "; ".join(bad) or ("no jobs" if not rows else "the catalogue"))
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
