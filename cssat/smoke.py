"""A smoke run of every experiment at a tiny size: does this install work?

``python -m cssat.smoke [--out DIR]`` runs ``cssat experiment=<name> <TINY[name]>`` for every YAML
of ``conf/experiment/`` through the ``cssat`` console script — as a user of the installed package
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

__all__ = ["TINY", "run_one", "main"]

#: each experiment at a tiny size: the overrides of a run of a few seconds
#: the example MMT-format track shipped in the package (synthetic: tests/data/formats/make_examples.py)
EXAMPLE_TRACK = Path(__file__).parent / "data" / "examples" / "mmt_rocket_body_synthetic.txt"

TINY: dict[str, list[str]] = {
    "sim1": ["target.size=12", "cs.m=100"],
    "sim2": ["target.size=12", "cs.m=80", "dtype=float64"],
    "sim3": ["target.size=12", "cs.m=80", "reference.pool=150", "reference.n=80", "reference.repeats=2",
             "reference.n_nonzero_coefs=10", "denoiser3d.n_iter=1"],
    "solvers": ["target.size=12", "grid.axes.0.values=[0.5]", "grid_options.pnp.max_iter=2",
                "grid_options.pnp.denoiser.n_iter=1", "grid_options.tv.max_iter=50", "grid_options.l1.max_iter=50"],
    "realism": ["target.size=12", "grid.axes.0.values=[0.058,60]", "grid.axes.1.values=[8]", "grid_options.tv.max_iter=50",
                "~grid.axes.0.cells.leo_pass",  # its 160 samples need N >= 160
                "atmosphere.n_radial=16", "atmosphere.n_angular=4", "atmosphere.n_layers=2"],
    "lightcurve": ["scenario.n_steps=3", "render.size=8"],
    "inversion": ["nights.n=2", "nights.fit=1", "scenario.step_s=900", "inversion.spin=known", "inversion.n_normals=64"],
    "inversion_tumbling": ["nights.n=2", "nights.fit=1", "scenario.step_s=900", "inversion.spin=known",
                           "inversion.n_normals=64"],
    "occultation": ["silhouette.size=24", "silhouette.pixel_m=0.5", "invert.iters=5", "invert.shape_iters=5"],
    "characterise": [f"observations={EXAMPLE_TRACK}", "characterise.tracks=[101]"],
}


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
    missing = [n for n in known if n not in TINY]
    if missing:
        print(f"no tiny size for {', '.join(missing)} (add it to cssat.smoke.TINY)", file=sys.stderr)
        return 1
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
