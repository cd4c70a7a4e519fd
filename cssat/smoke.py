"""A smoke run of every experiment at a tiny size: does this install work?

``python -m cssat.smoke [--out DIR]`` runs ``cssat experiment=<name> <TINY[name]>`` for every YAML
of ``conf/experiment/`` (its tiny size: the ``tiny`` list of overrides in the YAML) through the ``cssat`` console script — as a user of the installed package
would, from any working directory — and checks that each exits 0 and leaves a complete result set
(``metrics.json`` with ``status: ok`` and its manifest). It exits 1 naming the experiments that
failed. CI runs it from the built wheel installed into a fresh virtual environment (no ``-e``),
where a module missing from the wheel ends in ``ModuleNotFoundError``. A few seconds each.

:data:`TINY` is also the size of the tests' every-experiment runs (``tests/test_pipeline.py``).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Sequence

__all__ = ["TINY", "tiny_overrides", "run_one", "main"]

#: the example MMT-format track shipped in the package (synthetic: tests/data/formats/make_examples.py)
EXAMPLE_TRACK = Path(__file__).parent / "data" / "examples" / "mmt_rocket_body_synthetic.txt"


def tiny_overrides(name: str, conf_dir: Path | None = None) -> list[str]:
    """The overrides of experiment ``name``'s run of a few seconds: the ``tiny`` list of its YAML
    in ``conf_dir/experiment/`` (default: cssat's ``conf/``), else the one of the experiment it
    extends (its ``defaults`` naming another experiment), else none (its own size);
    ``{examples}`` is the folder of the example files shipped in the package."""
    import yaml  # startup: PyYAML, only when the sizes are read

    conf_dir = _conf_dir() if conf_dir is None else Path(conf_dir)
    seen = set()
    while name not in seen:
        seen.add(name)
        path = conf_dir / "experiment" / f"{name}.yaml"
        doc = yaml.safe_load(path.read_text()) if path.exists() else None
        if not isinstance(doc, dict):
            return []
        if doc.get("tiny") is not None:
            return [str(x).replace("{examples}", str(EXAMPLE_TRACK.parent)) for x in doc["tiny"]]
        parents = [d for d in doc.get("defaults") or [] if isinstance(d, str) and d != "_self_" and "/" not in d]
        if not parents:
            return []
        name = parents[0]
    return []


def _conf_dir() -> Path:
    import cssat.conf  # local: cssat.conf is the configs (a symlink in a source tree)

    return Path(cssat.conf.__file__).parent


#: each experiment at a tiny size: the overrides of a run of a few seconds (the ``tiny`` list of its YAML)
TINY: dict[str, list[str]] = {p.stem: tiny_overrides(p.stem) for p in sorted((_conf_dir() / "experiment").glob("*.yaml"))}


def run_one(name: str, out_dir: Path, extra: Sequence[str] = ()) -> str | None:
    """Run experiment ``name`` at its tiny size into ``out_dir`` through the ``cssat`` console
    script; ``None`` when it exits 0 with a complete ``ok`` result set, else why not (one line)."""
    exe = shutil.which("cssat") or shutil.which("cssat", path=str(Path(sys.executable).parent))
    if exe is None:
        return "the cssat console script is not on PATH (is cssat installed in this environment?)"
    cmd = [exe, f"experiment={name}", *TINY.get(name, []), "threads=1", f"hydra.run.dir={out_dir}",
           f"cache_dir={out_dir / 'cache'}", *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=out_dir.parent)
    if proc.returncode != 0:
        tail = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or ["no output"]
        return f"exit {proc.returncode}: {tail[0]}"
    try:
        metrics = json.loads((out_dir / "metrics.json").read_text())
    except (OSError, ValueError) as err:
        return f"no readable metrics.json: {err}"
    from cssat.experiments.results import check_complete  # startup: cssat.experiments.results imports numpy

    why = check_complete(out_dir, metrics, metrics.get("config_sha", ""))
    return None if why is None else f"an incomplete result set: {why}"


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m cssat.smoke [--out DIR] [NAME ...]``: every experiment (or the ones named)."""
    from cssat.experiments import experiment_names  # startup: cssat.experiments imports numpy

    ap = argparse.ArgumentParser(prog="python -m cssat.smoke", description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help="experiments to run (default: every one)")
    ap.add_argument("--out", type=Path, default=None, help="where the runs go (default: a temporary directory)")
    args = ap.parse_args(argv)
    known = experiment_names()
    names = args.names or known
    unknown = [n for n in names if n not in known]
    if unknown:
        ap.error(f"names: {', '.join(unknown)} not among the experiments ({', '.join(known)})")
    root = args.out or Path(tempfile.mkdtemp(prefix="cssat-smoke-"))
    root.mkdir(parents=True, exist_ok=True)
    failed = []
    for name in names:
        t = time.perf_counter()
        why = run_one(name, root.resolve() / name)
        print(f"{name:20s} {'ok' if why is None else 'FAILED: ' + why} ({time.perf_counter() - t:.1f} s)", flush=True)
        if why is not None:
            failed.append(name)
    if failed:
        print(f"smoke: {len(failed)} of {len(names)} experiments failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"smoke: all {len(names)} experiments ran ({root})")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
