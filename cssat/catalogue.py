"""A catalogue of measured light curves at archive scale.

:func:`characterise_file` is the characterise experiment's ``read → clean → period`` (``→
tumbling`` when asked) on one file, in this process and without Hydra: one flat row (a ``dict``
of scalars, :data:`ROW_COLUMNS`). A file that cannot be read or analysed is a row with
``verdict: "failed"`` and the error's line, never an exception, so a Dask bag or a Ray map over
an archive goes on::

    import dask.bag as db
    from cssat.catalogue import characterise_file
    rows = db.from_sequence(paths, npartitions=64).map(characterise_file).compute()

The command line runs the same function in *shards*: ``cssat -m experiment=characterise
observations=<dir or glob> catalogue.shard_size=500 launcher=local`` lists the files (sorted;
:func:`catalogue_files`) and sweeps ``catalogue.shard=0,1,…``; each job characterises its slice of
the list in one process (:func:`cssat.catalogue_shards.run`, through :func:`cssat.experiments.run_experiment`: its lock,
resume and manifest) and writes ``tracks_<shard>.csv`` atomically, hashed in its
``metrics.json``. When the sweep ends, the summary (:mod:`cssat.summary`, also
``cssat-summarize <sweep dir>``) joins the shards' tables into ``catalogue.csv`` — one row per
file, in the sorted order — only when every shard is complete and unedited.

Paths are data: the file list never passes through OmegaConf (no ``${...}`` interpolation of a
file name), and a directory, glob or file name given on the command line is quoted literally
(:func:`literal_override`).

``import cssat.catalogue`` is light (the standard library only); numpy, torch and the readers are
imported by the first call that needs them.
"""

from __future__ import annotations

import csv
import functools
import glob as _glob
import hashlib
import json
import logging
import math
import os
import time
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from cssat.models.observed.config import CatalogueConfig  # startup: stdlib dataclasses only

__all__ = ["characterise_file", "catalogue_files", "listing_sha", "shard_files", "n_shards", "ROW_COLUMNS",
           "DEFAULT_SHARD_SIZE", "read_rows", "write_rows", "shard_table", "literal_override"]

log = logging.getLogger("cssat")

#: the columns of a catalogue row, in order (units: seconds; ``fap`` a probability)
ROW_COLUMNS = ("file", "track", "object_id", "object_name", "verdict", "period_s", "period_err_s", "fap",
               "published_period_s", "why", "warnings", "tumbling", "n_samples", "span_s", "seconds", "status", "error")
_FLOAT_COLUMNS = {"period_s", "period_err_s", "fap", "published_period_s", "span_s", "seconds"}
_INT_COLUMNS = {"n_samples"}
_BOOL_COLUMNS = {"tumbling"}
#: the verdicts of a row: estimate_period's three, and ``failed`` (the file could not be characterised)
VERDICTS = ("periodic", "not periodic", "undetermined", "failed")
#: files per shard when ``catalogue.shard_size`` is not given (the characterise experiment's:
#: :class:`cssat.models.observed.config.CatalogueConfig`)
DEFAULT_SHARD_SIZE = CatalogueConfig.shard_size
#: the experiment whose stages a catalogue runs
EXPERIMENT = "characterise"
#: the stage modes of a catalogue row unless given: the period where the data allow, no tumbling
#: (``catalogue.tumbling=true``/``stages={"tumbling": "auto"}``), never the spin (it needs each
#: object's element set)
DEFAULT_STAGES = {"period": "auto", "tumbling": "off", "spin": "off"}


# --------------------------------------------------------------------------------------- the files

def catalogue_files(observations: str | os.PathLike) -> list[str]:
    """The files of a catalogue, sorted, as absolute paths: every regular, non-hidden file of a
    directory, or the regular files a glob (``*``, ``?``, ``[``; ``**`` any depth) matches. Nothing is interpolated
    or expanded but the glob. A :class:`~cssat._checks.FieldError` naming ``observations`` when
    nothing matches."""
    from cssat._checks import FieldError  # startup: cssat._checks is light; kept local like the rest

    value = os.fspath(observations)
    if os.path.isdir(value):
        with os.scandir(value) as it:
            files = [e.path for e in it if not e.name.startswith(".") and e.is_file()]
        pattern = os.path.join(value, "*")
    else:
        pattern = value
        files = [f for f in _glob.glob(pattern, recursive=True) if os.path.isfile(f) and not os.path.basename(f).startswith(".")]
    if not files:
        raise FieldError("observations", f"no file matches {pattern!r}")
    return sorted(os.path.abspath(f) for f in files)


def listing_sha(files: Sequence[str]) -> str:
    """A 16-hex-digit hash of a file list (its order and names): every shard checks that it sees
    the list the sweep was cut from."""
    h = hashlib.blake2b(digest_size=8)
    for f in files:
        h.update(os.fsencode(f) + b"\0")
    return h.hexdigest()


def n_shards(n_files: int, shard_size: int) -> int:
    """The number of shards of ``n_files`` files, ``shard_size`` a shard (the last one shorter)."""
    return max(1, -(-int(n_files) // int(shard_size)))


def shard_files(files: Sequence[str], shard: int, shard_size: int) -> list[str]:
    """Shard ``shard``'s slice of the sorted file list."""
    return list(files[shard * shard_size:(shard + 1) * shard_size])


def shard_table(shard: int) -> str:
    """The name of shard ``shard``'s table in its job directory."""
    return f"tracks_{int(shard)}.csv"


def literal_override(key: str, value: str) -> str:
    """``key=value`` as a Hydra override that gives ``value`` to the config *literally*: quoted,
    with OmegaConf's ``${`` escaped (a file named ``t_${experiment_name}.txt`` is that file, not
    ``t_characterise.txt``), backslashes kept as they are (``a\\b`` stays one backslash) and a
    quote escaped."""
    out, i = [], 0
    while i < len(value):  # OmegaConf: a run of k backslashes before "${" is 2k, then "\${"
        if value.startswith("${", i):
            j = len(out)
            while j > 0 and out[j - 1] == "\\":
                j -= 1
            out[j:] = ["\\"] * (2 * (len(out) - j))
            out.append("\\${")
            i += 2
        else:
            out.append(value[i])
            i += 1
    text = "".join(out)
    quoted, run = [], 0  # Hydra's quoted string: backslashes before a quote (or the closing one) doubled
    for c in text:
        if c == "\\":
            run += 1
            continue
        if c == "'":
            quoted.append("\\" * (2 * run) + "\\'")
        else:
            quoted.append("\\" * run + c)
        run = 0
    quoted.append("\\" * (2 * run))
    return f"{key}='{''.join(quoted)}'"


# ------------------------------------------------------------------------------------------ a row

class _Config(dict):
    """A plain mapping with attribute access: the config :class:`Observed` reads, without OmegaConf
    (so a path holding ``${...}`` is never interpolated)."""

    def __getattr__(self, key: str) -> Any:
        try:
            return self[key]
        except KeyError:
            raise AttributeError(key) from None


@functools.lru_cache(maxsize=1)
def _experiment_defaults() -> dict[str, Any]:
    """The characterise experiment's groups with their defaults (their typed configs:
    :mod:`cssat.models.observed.config`), so a row uses the experiment's own defaults."""
    from dataclasses import asdict  # startup: stdlib

    from cssat.models.observed.config import CharacteriseConfig, PeriodConfig, ReadConfig, TumblingConfig  # startup: light

    return {"observed": asdict(ReadConfig()), "characterise": asdict(CharacteriseConfig()),
            "period": asdict(PeriodConfig()), "tumbling": asdict(TumblingConfig())}


def _plain(node: Any) -> dict[str, Any]:
    """A config group (``DictConfig``, mapping or ``None``) as a plain ``dict``."""
    if node is None:
        return {}
    if hasattr(node, "_get_node"):  # an OmegaConf node: its values, resolved
        from omegaconf import OmegaConf  # startup: omegaconf, only for a DictConfig

        return dict(OmegaConf.to_container(node, resolve=True))
    return dict(node)


def options_text(observed: Any, characterise: Any, period: Any, tumbling: Any, stages: Any) -> str:
    """The row's settings as canonical JSON (the cache key of their check): the experiment's
    defaults with the given groups over them."""
    from cssat._checks import FieldError  # startup: not at import (stdlib only)

    base = _experiment_defaults()
    groups = {"observed": {**base["observed"], **_plain(observed)},
              "characterise": {**base["characterise"], **_plain(characterise), "figures": False},
              "period": {**base["period"], **_plain(period)},
              "tumbling": {**base["tumbling"], **_plain(tumbling)},
              "stages": {**DEFAULT_STAGES, **_plain(stages)}}
    if groups["stages"].get("spin") != "off":
        raise FieldError("stages.spin", f"a catalogue row runs no spin stage (it needs each object's element set): "
                                        f"expected 'off', got {groups['stages'].get('spin')!r}")
    try:
        return json.dumps(groups, sort_keys=True)
    except TypeError as err:
        raise FieldError("options", f"the settings must be plain values (JSON): {err}") from None


@functools.lru_cache(maxsize=32)
def checked_options(options: str) -> dict[str, Any]:
    """Every setting checked once (the experiment's own check, :func:`observed_settings`), before
    any file: a bad one raises a FieldError naming it."""
    from cssat.experiments.forward.observed import observed_settings  # heavy: imports torch

    groups = json.loads(options)
    observed_settings(_Config(groups, observations="(checked)", scenario=_Config(tle=None)))
    return groups


def _finite(v: Any) -> Any:
    """A numpy or Python number as a Python one; non-finite floats as ``None`` (empty in a CSV)."""
    if v is None or isinstance(v, (bool, str)):
        return v
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _one_line(err: BaseException) -> str:
    """An error in one line: a FieldError's own ``<field>: <detail>``, else ``<Type>: <message>``."""
    from cssat._checks import FieldError  # startup: not at import (stdlib only)

    lines = str(err).strip().splitlines()
    first = lines[0] if lines else ""
    return first if isinstance(err, FieldError) else f"{type(err).__name__}: {first}".rstrip(": ")


def characterise_file(path: str | os.PathLike, *, observed: Mapping[str, Any] | None = None,
                      characterise: Mapping[str, Any] | None = None, period: Mapping[str, Any] | None = None,
                      tumbling: Mapping[str, Any] | None = None, stages: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Characterise one light-curve file and return its catalogue row (:data:`ROW_COLUMNS`).

    The characterise experiment's stages (:class:`cssat.experiments.forward.observed.Observed`):
    ``read`` (``observed``: :func:`cssat.data.read_light_curve`'s settings), ``clean``
    (``characterise``: penumbra, ``min_samples``, range to 1000 km), ``period``
    (:func:`cssat.experiments.forward.verdicts.period_stage`; ``period``: the options of
    :func:`cssat.inversion.estimate_period`) and — only when ``stages={"tumbling": "auto"}`` or
    ``"on"`` — ``tumbling`` (``tumbling``: its options). Each group is the experiment's default
    (its typed config, :mod:`cssat.models.observed.config`) with the given keys over it; the spin
    stage never runs.

    The row: ``file`` (as given), ``track`` (the file's track ids, ``;``-joined),
    ``object_id``, ``object_name``, ``verdict`` (``periodic`` | ``not periodic`` |
    ``undetermined`` | ``failed``), ``period_s`` and ``period_err_s`` (s; empty unless
    periodic), ``fap`` (false-alarm probability), ``published_period_s`` (the file's own, s),
    ``why`` (the verdict in one sentence), ``warnings`` (``"; "``-joined), ``tumbling``
    (True/False; ``None`` when the stage did not run), ``n_samples``, ``span_s`` (s),
    ``seconds`` (this call's wall time, s — the one column that differs between runs),
    ``status`` (``ok`` | ``failed``) and ``error`` (the error's line, ``None`` when ok).

    A bad setting raises :class:`~cssat._checks.FieldError` naming it (``period.min_periods``)
    before the file is read; anything wrong with the file is a ``failed`` row.
    """
    t0 = time.perf_counter()
    options = checked_options(options_text(observed, characterise, period, tumbling, stages))
    if not isinstance(path, (str, os.PathLike)):
        from cssat._checks import FieldError  # startup: light

        raise FieldError("path", f"expected a file's path (str or os.PathLike), got {type(path).__name__} {path!r}")
    row: dict[str, Any] = dict.fromkeys(ROW_COLUMNS)
    row["file"] = os.fspath(path)
    try:
        _characterise(row, options)
        row["status"] = "ok"
    except Exception as err:  # the file's fault (unreadable, too few samples, …): its row says so
        row.update(verdict="failed", status="failed", error=_one_line(err))
    row["seconds"] = time.perf_counter() - t0
    return row


def _characterise(row: dict[str, Any], options: dict[str, Any]) -> None:
    """The stages of :func:`characterise_file` into ``row`` (what was known before a failure
    too: the exception's ``partial_metrics`` where the experiment leaves them)."""
    from cssat.experiments.context import Run  # heavy: the experiments' package imports numpy
    from cssat.experiments.forward.base import run_stages  # heavy: the experiments' package imports numpy
    from cssat.experiments.forward.observed import Observed  # heavy: imports torch

    cfg = _Config(options, observations=row["file"], scenario=_Config(tle=None))
    run_ = Run(out_dir=Path("."), dtype=None, device=None, seed=0)  # nothing written, nothing drawn
    try:
        verdicts = run_stages(Observed(), cfg, run_, ("plan", "measure", "estimate"))
    except Exception as err:
        measured = run_.results.get("measure")
        known = {**(measured.metrics if measured is not None else {}), **(getattr(err, "partial_metrics", None) or {})}
        _describe(row, known, measured.lc if measured is not None else None)
        raise
    measured = run_.results["measure"]
    _describe(row, measured.metrics, measured.lc)
    m, res = verdicts.metrics, verdicts.period
    if res is not None:
        verdict = m.get("verdict") or res.get("verdict") or ("periodic" if res["periodic"] else "not periodic")
        periodic = verdict == "periodic"
        row.update(verdict=verdict, period_s=_finite(res["period_s"]) if periodic else None,
                   period_err_s=_finite(res["period_err_s"]) if periodic else None, fap=_finite(res["fap"]),
                   why=res.get("verdict_why") or m.get("verdict_why") or res.get("why"),
                   warnings="; ".join(map(str, res.get("warnings") or [])) or None)
    else:  # the period stage off, or the whole curve out of the search's reach
        stage = str(m.get("stage_period"))
        row.update(verdict=m.get("verdict") or ("undetermined" if stage != "off" else None),
                   why=m.get("verdict_why") or f"the period stage: {stage}")
    if m.get("stage_tumbling") == "ok":
        row["tumbling"] = bool(m["tumbling"])


def _describe(row: dict[str, Any], m: Mapping[str, Any], lc: Any) -> None:
    """The file's own description (object, tracks, samples, span) into ``row``."""
    track = m.get("track")
    if track is None and lc is not None and getattr(lc, "tracks", None) is not None:
        track = ";".join(dict.fromkeys(str(k) for k in lc.tracks))
    n = m.get("n_samples")
    row.update(track=_text(track), object_id=_text(m.get("object_id")), object_name=_text(m.get("object_name")),
               published_period_s=_finite(m.get("published_period_s")), n_samples=None if n is None else int(n),
               span_s=_finite(m.get("span_s")))


def _text(v: Any) -> str | None:
    return None if v is None else str(v)


# ---------------------------------------------------------------------------------------- tables

def write_rows(path: str | os.PathLike, rows: Iterable[Mapping[str, Any]]) -> None:
    """Write catalogue rows as a CSV (:data:`ROW_COLUMNS`, floats to full precision, ``None``
    empty) atomically: a reader sees the old file or the whole new one, never a part."""
    from cssat._tmpfiles import atomic_csv  # startup: light

    atomic_csv(path, [{k: r.get(k) for k in ROW_COLUMNS} for r in rows], list(ROW_COLUMNS))


def _typed(name: str, text: str) -> Any:
    if text == "":
        return None
    if name in _FLOAT_COLUMNS:
        return float(text)
    if name in _INT_COLUMNS:
        return int(text)
    if name in _BOOL_COLUMNS:
        return text == "True"
    return text


def read_rows(path: str | os.PathLike) -> list[dict[str, Any]]:
    """The rows of a catalogue table (``catalogue.csv`` or a shard's), typed as
    :func:`characterise_file` returns them (numbers, booleans, ``None`` for empty)."""
    with open(path, newline="") as f:
        return [{k: _typed(k, v) for k, v in r.items()} for r in csv.DictReader(f)]
