"""A catalogue of MMT-format tracks characterised through Hydra's joblib launcher, against a
plain astropy Lomb–Scargle loop over the same files (issue 34, point 6).

    python benchmarks/bench_catalogue.py --n 200 [--jobs 2]

Writes ``n`` synthetic MMT-9 track files (:mod:`benchmarks.mmt_like`, one track each, in the
MMT export format) to a temporary directory, then times

1. ``cssat -m experiment=characterise observations=<dir> characterise.figures=false
   launcher=local`` (2 joblib workers of 1 thread: every file a Hydra job with its own result
   set, ``metrics.json`` and a row of ``summary.csv``) — tracks per second, wall clock;
2. in one process, per file: ``cssat.data.read_light_curve`` + ``cssat.inversion.estimate_period``;
3. in one process, per file: ``astropy.table.Table.read`` + ``LombScargle.autopower`` on the
   data-derived grid (2/span to the Nyquist of the median step) — the plain baseline;

and prints tracks per second and the cost per track of each, and the ratios.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mmt_like import make_tracks  # noqa: E402


def write_mmt(path: Path, tr: dict, k: int) -> None:
    """One track as an MMT-9 export (the format of tests/data/real/mmt_*.txt)."""
    t0 = np.datetime64("2021-03-04T21:10:05.000", "ms")
    code = {"periodic": "2 Periodic", "aperiodic": "1 Aperiodic", "nonvariable": "0 Not variable"}[tr["label"]]
    lines = [f"# satellite: {90000 + k} SYNTHETIC-{k} / --", "# catalogue: 1 NORAD", f"# variability: {code}",
             f"# variability_period: {tr['period_s'] if tr['period_s'] else 'None'}", "#",
             "# Date Time StdMag Mag Filter Penumbra Distance Phase Channel Track"]
    for ti, m in zip(tr["t"], tr["mag"]):
        stamp = str(t0 + np.timedelta64(int(round(ti * 1000)), "ms")).replace("T", " ")
        lines.append(f"{stamp}000 {m - 1:.3f} {m:.5f} Clear 0 2000.000 60.0 1 {k}")
    path.write_text("\n".join(lines) + "\n")


def astropy_loop(files: list[Path]) -> float:
    from astropy.io import ascii
    from astropy.timeseries import LombScargle

    t0 = time.perf_counter()
    for f in files:
        tab = ascii.read(f, format="no_header", comment="#", names=["Date", "Time", "StdMag", "Mag", "Filter", "Penumbra",
                                                                   "Distance", "Phase", "Channel", "Track"])
        stamps = np.array([f"{d}T{s}" for d, s in zip(tab["Date"], tab["Time"])], dtype="datetime64[us]")
        t = (stamps - stamps[0]).astype(np.int64) / 1e6
        y = np.asarray(tab["Mag"], dtype=float)
        LombScargle(t, y).autopower(minimum_frequency=2 / t[-1], maximum_frequency=0.5 / np.median(np.diff(t)),
                                    samples_per_peak=10)
    return time.perf_counter() - t0


def cssat_loop(files: list[Path]) -> float:
    from cssat.data import read_light_curve
    from cssat.inversion import estimate_period

    t0 = time.perf_counter()
    for f in files:
        lc = read_light_curve(f)
        estimate_period(lc.times_s(), lc.values, segments=lc.track_ids())
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="cssat-catalogue-"))
    try:
        files = []
        for k, tr in enumerate(make_tracks(args.n, seed=0)):
            f = work / "tracks" / f"track_{k:05d}.txt"
            f.parent.mkdir(exist_ok=True)
            write_mmt(f, tr, k)
            files.append(f)
        walls, loops, bases = [], [], []
        for r in range(args.repeats):
            sweep = work / f"sweep{r}"
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "cssat.app", "-m", "experiment=characterise",
                            f"observations={work / 'tracks'}", "characterise.figures=false", "launcher=local",
                            f"hydra.launcher.n_jobs={args.jobs}", f"hydra.sweep.dir={sweep}"],
                           check=False, capture_output=True, text=True)
            walls.append(time.perf_counter() - t0)
            loops.append(cssat_loop(files))
            bases.append(astropy_loop(files))
        rows = (sweep / "summary.csv").read_text().splitlines()
        ok = sum(",ok," in r for r in rows[1:])
        wall, loop, base = (statistics.median(v) for v in (walls, loops, bases))
        n = len(files)
        print(f"{n} MMT-format tracks, {args.jobs} joblib workers; summary.csv: {ok} of {len(rows) - 1} rows ok")
        print(f"catalogue (cssat -m, launcher=local): {wall:.1f} s wall, {n / wall:.2f} tracks/s, {wall / n * 1e3:.0f} ms a track")
        print(f"cssat read + estimate_period, one process: {loop / n * 1e3:.1f} ms a track")
        print(f"astropy Table.read + LombScargle, one process: {base / n * 1e3:.1f} ms a track")
        print(f"ratios: period analysis / astropy = {loop / base:.2f}; catalogue job / astropy = {wall * args.jobs / base:.1f} "
              "(per core)")
        print(f"1000 tracks would take about {1000 * wall / n / 60:.1f} min")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
