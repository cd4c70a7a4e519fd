"""The tests' tumbling experiment once, its metrics and arrays saved for a before/after comparison.

``python benchmarks/bench_tumble_grid.py OUT`` runs ``experiment=inversion_tumbling`` at the config of
``tests/test_inversion_tumble.py``'s ``test_the_tumbling_experiment_finds_the_true_state`` (one
thread) and writes ``OUT.json`` (the metrics but the clocks) and ``OUT.npz`` (its arrays);
``python benchmarks/bench_tumble_grid.py --compare A B`` says which metrics and arrays differ.
Timed from outside (BENCHMARKS.md "The tumbling search's mode-angle grid in one array pass")::

    farm-bench -n 3 --warmup 0 --timeout 900 --vs "env PYTHONPATH=<old checkout> python benchmarks/bench_tumble_grid.py old" -- env PYTHONPATH=$PWD python benchmarks/bench_tumble_grid.py new
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

CLOCKS = ("git_commit", "elapsed_s", "started_utc", "finished_utc")


def run(out: str) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import test_inversion_tumble as T

    from cssat.experiments import run_experiment

    d = Path(tempfile.mkdtemp())
    m = run_experiment(T._cfg("experiment=inversion_tumbling", *T.SMALL, *T.IN_CLASS), d / "run")
    keep = {k: repr(v) for k, v in m.items() if k not in CLOCKS and not k.startswith("seconds")}
    Path(out + ".json").write_text(json.dumps(keep, sort_keys=True))
    a = np.load(d / "run" / "arrays.npz")
    np.savez(out + ".npz", **{k: a[k] for k in a.files})


def compare(a: str, b: str) -> None:
    ma, mb = (json.loads(Path(x + ".json").read_text()) for x in (a, b))
    print("metrics that differ:", {k: (ma.get(k), mb.get(k)) for k in sorted(set(ma) | set(mb)) if ma.get(k) != mb.get(k)})
    xa, xb = np.load(a + ".npz"), np.load(b + ".npz")
    same = [k for k in xa.files if k in xb.files and (np.array_equal(xa[k], xb[k], equal_nan=True)
                                                       if xa[k].dtype.kind == "f" else np.array_equal(xa[k], xb[k]))]
    print("arrays that differ:", sorted((set(xa.files) | set(xb.files)) - set(same)))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--compare"]:
        compare(sys.argv[2], sys.argv[3])
    else:
        run(sys.argv[1])
