"""A catalogue's shard jobs: the function each job of ``cssat -m
experiment=characterise observations=<dir or glob>`` runs (:func:`run`: the job's slice of the
sorted file list through :func:`cssat.catalogue.characterise_file`, its ``tracks_<shard>.csv``),
the settings of the ``catalogue`` group checked once before any job (:func:`check_config`), and
the join of the shards' tables into the sweep's ``catalogue.csv`` (:func:`join_shards`, from
complete, unedited shards only). The module docstring of :mod:`cssat.catalogue` has the whole
picture; this module is light too (the standard library)."""

from __future__ import annotations

import csv
import logging
from pathlib import Path
from typing import Any, Mapping, Sequence

from cssat.catalogue import (DEFAULT_SHARD_SIZE, ROW_COLUMNS, checked_options, options_text, catalogue_files, characterise_file,
                             listing_sha, n_shards, shard_files, shard_table, write_rows)

__all__ = ["run", "check_config", "join_shards", "options_of"]

log = logging.getLogger("cssat")


def _catalogue_settings(cfg: Any) -> dict[str, Any]:
    """The ``catalogue`` group checked (:class:`~cssat.models.observed.config.CatalogueConfig`; a
    FieldError naming the key), its ``shard`` required."""
    from dataclasses import asdict  # startup: stdlib

    from cssat._checks import int_param  # startup: not at import (stdlib only)
    from cssat.models.observed.config import CatalogueConfig, typed_group  # startup: stdlib dataclasses only

    cat = typed_group(CatalogueConfig, cfg.get("catalogue"), "catalogue")
    int_param(cat.shard, "catalogue.shard", 0)
    return asdict(cat)


def options_of(cfg: Any) -> dict[str, Any]:
    """:func:`characterise_file`'s settings of a characterise config: its ``observed``,
    ``characterise``, ``period`` and ``tumbling`` groups; the stages ``stages.period``, the
    tumbling stage only with ``catalogue.tumbling=true`` (then ``stages.tumbling``'s mode), no spin."""
    from cssat.experiments.build import settings  # startup: not at import (stdlib only)
    from cssat.models.observed.config import CatalogueConfig, StagesConfig, typed_group  # startup: stdlib only

    st = typed_group(StagesConfig, cfg.get("stages"), "stages")
    tumble = typed_group(CatalogueConfig, cfg.get("catalogue"), "catalogue").tumbling
    return {"observed": settings(cfg.get("observed")), "characterise": settings(cfg.get("characterise")),
            "period": settings(cfg.get("period")), "tumbling": settings(cfg.get("tumbling")),
            "stages": {"period": st.period, "tumbling": st.tumbling if tumble else "off", "spin": "off"}}


def check_config(cfg: Any) -> None:
    """Every setting a shard of ``cfg`` uses checked (``catalogue.*``, then the rows' groups):
    a FieldError naming the first bad key. Run once by ``cssat -m`` before the sweep's jobs, and
    by each shard before its first file."""
    _catalogue_settings(cfg)
    checked_options(options_text(**options_of(cfg)))


def run(cfg: Any, out_dir: str | Path) -> dict[str, Any]:
    """One shard of a catalogue (``experiment_module`` of a job with ``catalogue.shard`` set; run
    by :func:`cssat.experiments.run_experiment`): the sorted files of ``observations`` (a
    directory or glob), checked against the list the sweep was cut from (``catalogue.n_files``,
    ``catalogue.listing_sha``), shard ``catalogue.shard``'s slice characterised
    (:func:`characterise_file`) and written to ``tracks_<shard>.csv``. Returns the shard's metrics
    (files, ok, failed, periodic; the sweep's shape, for the join)."""
    from cssat._checks import FieldError  # startup: not at import (stdlib only)

    check_config(cfg)  # every setting checked before any file
    cat = _catalogue_settings(cfg)
    options = options_of(cfg)
    observations = cfg.get("observations")
    if not observations:
        raise FieldError("observations", "a catalogue needs a directory or glob of light-curve files: observations=<dir>")
    files = catalogue_files(str(observations))
    sha = listing_sha(files)
    if cat["n_files"] is not None and (len(files) != cat["n_files"] or (cat["listing_sha"] and sha != cat["listing_sha"])):
        raise FieldError("observations", f"the files changed since the sweep listed them ({cat['n_files']} files, list "
                                         f"{cat['listing_sha']}; now {len(files)}, {sha}): run the sweep again")
    k, size = cat["shard"], cat["shard_size"]
    total = n_shards(len(files), size)
    if k >= total:
        raise FieldError("catalogue.shard", f"{len(files)} files in shards of {size} make {total} shards (0 to {total - 1}), "
                                            f"got {k}")
    rows = [characterise_file(p, **options) for p in shard_files(files, k, size)]
    out = Path(out_dir)
    write_rows(out / shard_table(k), rows)
    verdicts = [r["verdict"] for r in rows]
    log.info("catalogue shard %d of %d: %d files, %d periodic, %d failed -> %s", k, total, len(rows),
             verdicts.count("periodic"), verdicts.count("failed"), out / shard_table(k))
    return {"psnr": None, "catalogue_shard": k, "catalogue_shard_size": size, "catalogue_n_shards": total,
            "catalogue_n_files": len(files), "catalogue_listing_sha": sha, "catalogue_table": shard_table(k),
            "n_files": len(rows), "n_ok": sum(r["status"] == "ok" for r in rows),
            "n_failed": sum(r["status"] != "ok" for r in rows), "n_periodic": verdicts.count("periodic"),
            "seconds_characterise": sum(r["seconds"] for r in rows)}


# ----------------------------------------------------------------------------------------- the join

def join_shards(sweep_dir: str | Path, rows: Sequence[Mapping[str, Any]]) -> tuple[Path | None, str | None]:
    """Join a catalogue sweep's shard tables into ``sweep_dir/catalogue.csv`` (atomically, one row
    per file in the sorted order) when every shard is complete; return ``(path, None)``, or
    ``(None, why)`` when it is not joined (a shard failed, is missing or was edited: ``rows`` are
    the summary's, :func:`cssat.summary.collect`, their status verified against each job's
    manifest) — a stale ``catalogue.csv`` of an earlier sweep is then removed. ``(None, None)``:
    not a catalogue sweep."""
    sweep_dir = Path(sweep_dir)
    shards = [r for r in rows if r.get("catalogue_table") is not None]
    if not shards:
        return None, None
    target = sweep_dir / "catalogue.csv"

    def refuse(why: str) -> tuple[None, str]:
        target.unlink(missing_ok=True)
        return None, why

    bad = [r for r in rows if r.get("status") != "ok"]
    if bad:
        return refuse("not every shard is complete: " + "; ".join(
            f"job {r.get('job')}: {r.get('status')}" + (f" ({str(r.get('error')).splitlines()[0]})" if r.get("error") else "")
            for r in bad) + " (run the same command again: the complete shards are skipped)")
    shape = {(r.get("catalogue_n_files"), r.get("catalogue_listing_sha"), r.get("catalogue_shard_size"),
              r.get("catalogue_n_shards")) for r in shards}
    if len(shape) != 1:
        return refuse("the shards were cut from different file lists (catalogue.n_files, listing_sha or shard_size differ)")
    n_files, _, _, total = shape.pop()
    by_shard = {int(r["catalogue_shard"]): r for r in shards}
    missing = [k for k in range(int(total)) if k not in by_shard]
    if missing or len(by_shard) != len(shards):
        return refuse(f"shards {missing or 'twice'} of 0 to {int(total) - 1} are not in this sweep")
    lines: list[str] = []
    header = None
    for k in range(int(total)):
        path = sweep_dir / str(by_shard[k]["job"]) / str(by_shard[k]["catalogue_table"])
        with open(path, newline="") as f:
            table = list(csv.reader(f))
        if not table or table[0] != list(ROW_COLUMNS):
            return refuse(f"{path}: not a catalogue table (its header is not {', '.join(ROW_COLUMNS)})")
        header = table[0]
        lines.extend(map(tuple, table[1:]))
    files = [r[0] for r in lines]
    if len(files) != int(n_files) or len(set(files)) != len(files) or files != sorted(files):
        return refuse(f"the shards hold {len(files)} rows, the list {n_files} files (or a file twice, or out of order)")

    from cssat._tmpfiles import atomic_write  # startup: light

    def write(tmp: str) -> None:
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            w.writerows(lines)

    atomic_write(target, write, result=False)
    return target, None
