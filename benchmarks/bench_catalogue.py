"""A catalogue at archive scale (issue 46, point 6): MMT-format tracks characterised three ways,
tracks per second on 2 cores, and the MMT-9 archive (500,000 tracks) extrapolated.

    python benchmarks/bench_catalogue.py --n 2000 --repeats 3 [--jobs 2] [--shard-size 250]

The files: ``n`` SYNTHETIC MMT-9 tracks (:mod:`benchmarks.mmt_like`, one track a file in the MMT
export format, named ``synthetic_<k>.txt``, object ``SYNTHETIC-<k>``) plus the 20 real MMT-9
tracks of ``../shared/real/mmt`` (when there), in one temporary directory. Then, each repeat:

(a) the shard path: ``cssat -m experiment=characterise observations=<dir>
    catalogue.shard_size=<s> launcher=local hydra.launcher.n_jobs=2`` (joblib workers of 1
    thread each): shards of ``s`` files a job, joined into ``catalogue.csv`` — wall clock from
    the command's start to its end (Python start-up, Hydra, the joblib workers, the join);
(b) :func:`cssat.catalogue.characterise_file` on every file in this one process (1 thread);
(c) astropy: ``ascii.read`` of the file + ``LombScargle.autopower`` on the data-derived grid
    (2/span to the Nyquist of the median step, 10 samples a peak) — the plain baseline.

Printed: tracks per second and ms a track of each (for (a) also core-seconds a track: wall x
jobs / tracks), the ratios to astropy, the extrapolation to 500,000 tracks in core-hours (the
target: <= 8 core-hours, <= 60 ms a track including the reading), and whether (a)'s
``catalogue.csv`` rows equal (b)'s (less ``seconds``). Medians of the repeats; every run listed.
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
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

ROOT = Path(__file__).resolve().parents[1]
REAL_MMT = ROOT.parent / "shared" / "real" / "mmt"
ARCHIVE_TRACKS = 500_000  # MMT-9's archive, about
TARGET_CORE_HOURS = 8.0


def write_mmt(path: Path, tr: dict, k: int) -> None:
    """One SYNTHETIC track as an MMT-9 export (the format of tests/data/real/mmt_*.txt)."""
    t0 = np.datetime64("2021-03-04T21:10:05.000", "ms")
    code = {"periodic": "2 Periodic", "aperiodic": "1 Aperiodic", "nonvariable": "0 Not variable"}[tr["label"]]
    lines = [f"# satellite: {90000 + k} SYNTHETIC-{k} / --", "# catalogue: 1 NORAD", f"# variability: {code}",
             f"# variability_period: {tr['period_s'] if tr['period_s'] else 'None'}", "#",
             "# Date Time StdMag Mag Filter Penumbra Distance Phase Channel Track"]
    for ti, m in zip(tr["t"], tr["mag"]):
        stamp = str(t0 + np.timedelta64(int(round(ti * 1000)), "ms")).replace("T", " ")
        lines.append(f"{stamp}000 {m - 1:.3f} {m:.5f} Clear 0 2000.000 60.0 1 {k}")
    path.write_text("\n".join(lines) + "\n")


def astropy_loop(files: list[str]) -> tuple[float, int, float]:
    """(c): seconds for every file, how many astropy could read, and the CPU seconds. The columns
    are the file's own ``# Date Time ...`` line (the real exports have no ``Track`` column: it is a header line)."""
    from astropy.io import ascii
    from astropy.timeseries import LombScargle

    t0, ok, c0 = time.perf_counter(), 0, time.process_time()
    for f in files:
        try:
            with open(f) as fh:
                names = next(ln[1:].split() for ln in fh if ln.startswith("# Date"))
            tab = ascii.read(f, format="no_header", comment="#", names=names)
        except Exception:  # a file astropy cannot read as its columns
            continue
        stamps = np.array([f"{d}T{s}" for d, s in zip(tab["Date"], tab["Time"])], dtype="datetime64[us]")
        t = (stamps - stamps[0]).astype(np.int64) / 1e6
        y = np.asarray(tab["Mag"], dtype=float)
        LombScargle(t, y).autopower(minimum_frequency=2 / t[-1], maximum_frequency=0.5 / np.median(np.diff(t)),
                                    samples_per_peak=10)
        ok += 1
    return time.perf_counter() - t0, ok, time.process_time() - c0


def cssat_loop(files: list[str]) -> tuple[float, list[dict], float]:
    """(b): seconds for every file through characterise_file, the rows, and the CPU seconds."""
    import torch

    from cssat.catalogue import characterise_file

    torch.set_num_threads(1)
    t0, c0 = time.perf_counter(), time.process_time()
    rows = [characterise_file(f) for f in files]
    return time.perf_counter() - t0, rows, time.process_time() - c0


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children and their descendants."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def shard_sweep(tracks: Path, sweep: Path, jobs: int, shard_size: int) -> tuple[float, int, float, float]:
    """(a): wall seconds of the whole command, its exit status, and the seconds the shards' jobs
    spent inside their runs (``seconds`` of each job's ``metrics.json``: the files characterised
    and the table written, without Python's and Hydra's start-up, the launching and the join;
    on a shared machine wall x jobs also counts the cores others took), and the CPU seconds of
    the whole command with its workers (start-up, Hydra, joblib, the jobs, the join: core-seconds
    this command used, whatever others took of the machine)."""
    c0 = _children_cpu()
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "cssat.app", "-m", "experiment=characterise", f"observations={tracks}",
                          f"catalogue.shard_size={shard_size}", "launcher=local", f"hydra.launcher.n_jobs={jobs}",
                          f"hydra.sweep.dir={sweep}"], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    cpu = _children_cpu() - c0
    if res.returncode != 0:
        print(res.stderr[-2000:], file=sys.stderr)
    try:
        with open(sweep / "summary.csv", newline="") as f:
            inside = sum(float(r["seconds"]) for r in csv.DictReader(f) if r.get("seconds"))
    except OSError:
        inside = float("nan")
    return wall, res.returncode, inside, cpu


def same_rows(catalogue: Path, rows: list[dict]) -> bool:
    """Whether the shards' joined rows equal characterise_file's (less ``seconds``); the first
    difference printed."""
    from cssat.catalogue import read_rows

    strip = lambda rs: [{k: v for k, v in r.items() if k != "seconds"} for r in rs]  # noqa: E731
    a, b = strip(read_rows(catalogue)), strip(rows)
    for x, y in zip(a, b):
        if x != y:
            print("  first difference:", Path(str(x["file"])).name, {k: (x[k], y.get(k)) for k in x if x[k] != y.get(k)})
            break
    return a == b


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000, help="synthetic tracks (default 10,000)")
    ap.add_argument("--jobs", type=int, default=2, help="joblib workers of the shard path (1 thread each)")
    ap.add_argument("--shard-size", type=int, default=None,
                    help="files a shard (default: 500, or fewer so that each worker gets >= 4 shards)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--real", default=str(REAL_MMT), help="the real MMT-9 tracks (default ../shared/real/mmt)")
    ap.add_argument("--no-real", action="store_true", help="leave out the real tracks")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="cssat-catalogue-"))
    try:
        tracks = work / "tracks"
        tracks.mkdir()
        for k, tr in enumerate(make_tracks(args.n, seed=0)):
            write_mmt(tracks / f"synthetic_{k:06d}.txt", tr, k)
        n_real = 0
        if Path(args.real).is_dir() and not args.no_real:
            for f in sorted(Path(args.real).glob("*.txt")):
                shutil.copy(f, tracks / f"real_{f.name}")
                n_real += 1
        from cssat.catalogue import catalogue_files

        files = catalogue_files(tracks)
        n = len(files)
        size = args.shard_size or max(1, min(500, -(-n // (4 * args.jobs))))
        print(f"{n} MMT-format files: {args.n} SYNTHETIC (benchmarks/mmt_like.py) + {n_real} real MMT-9 "
              f"(../shared/real/mmt); shards of {size} ({-(-n // size)} jobs), {args.jobs} joblib workers of 1 thread")
        print(f"load before: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} "
              f"on {os.cpu_count()} cores")
        sweeps, cpus, loops, bases, agree, rows = [], [], [], [], [], []
        cpu_a_all, cpu_b_all, cpu_c_all = [], [], []
        for r in range(args.repeats):
            wall, rc, cpu, cpu_cmd = shard_sweep(tracks, work / f"sweep{r}", args.jobs, size)
            cpu_a_all.append(cpu_cmd)
            sweeps.append(wall)
            cpus.append(cpu)
            loop, rows, cpu_b = cssat_loop(files)
            cpu_b_all.append(cpu_b)
            loops.append(loop)
            base, n_astropy, cpu_c = astropy_loop(files)
            cpu_c_all.append(cpu_c)
            bases.append(base)
            agree.append(rc == 0 and same_rows(work / f"sweep{r}" / "catalogue.csv", rows))
            print(f"  run {r + 1}: (a) {wall:.1f} s wall, {cpu:.1f} s in the jobs (rc {rc}), (b) {loop:.1f} s, (c) {base:.1f} s "
                  f"[load {os.getloadavg()[0]:.2f}]; CPU s: (a) {cpu_cmd:.1f} (the command and its workers), (b) {cpu_b:.1f}, "
                  f"(c) {cpu_c:.1f}", flush=True)
        wall, loop, base = (statistics.median(v) for v in (sweeps, loops, bases))
        ok = sum(r["status"] == "ok" for r in rows)
        verdicts = {v: sum(r["verdict"] == v for r in rows) for v in ("periodic", "not periodic", "undetermined", "failed")}
        core_a = wall * args.jobs / n
        cpu_a = statistics.median(cpus) / n
        print(f"rows: {ok} of {n} ok; verdicts {verdicts}; astropy read {n_astropy} of {n}")
        print(f"(a) shards through Hydra's joblib launcher: {wall:.1f} s wall, {n / wall:.1f} tracks/s on {args.jobs} "
              f"cores, {core_a * 1e3:.1f} core-ms a track (wall x {args.jobs} / tracks; inside the jobs "
              f"{cpu_a * 1e3:.1f} ms a track); catalogue.csv = (b)'s rows: {all(agree)}")
        print(f"(b) characterise_file, one process: {loop:.1f} s, {n / loop:.1f} tracks/s, {loop / n * 1e3:.1f} ms a track")
        per_c = base / max(n_astropy, 1)  # the files astropy could read (not the real ones it cannot parse)
        print(f"(c) astropy ascii.read + LombScargle, one process: {base:.1f} s for {n_astropy} files, "
              f"{1 / per_c:.1f} tracks/s, {per_c * 1e3:.1f} ms a track")
        print(f"ratios: (b)/(c) = {loop / n / per_c:.2f}; (a) per core / (c) = {core_a / per_c:.2f}; "
              f"(a) per core / (b) = {core_a / (loop / n):.2f}")
        cpu_cmd_a = statistics.median(cpu_a_all) / n
        cpu_b = statistics.median(cpu_b_all) / n
        cpu_c = statistics.median(cpu_c_all) / max(n_astropy, 1)
        print(f"CPU (core-ms a track, what this benchmark itself used, not the load of others): (a) {cpu_cmd_a * 1e3:.1f} "
              f"(the whole command: start-up, Hydra, workers, join), (b) {cpu_b * 1e3:.1f}, (c) {cpu_c * 1e3:.1f}")
        for name, per in (("(a) CPU", cpu_cmd_a), ("(b) CPU", cpu_b), ("(a) wall x jobs", core_a),
                          ("(a) inside the jobs", cpu_a), ("(b) wall", loop / n), ("(c) CPU", cpu_c)):
            hours = ARCHIVE_TRACKS * per / 3600
            print(f"MMT archive, {ARCHIVE_TRACKS:,} tracks by {name}: {hours:.1f} core-hours "
                  f"({'within' if hours <= TARGET_CORE_HOURS else 'over'} the {TARGET_CORE_HOURS:g}), "
                  f"{hours / args.jobs:.1f} h on {args.jobs} cores")
        print("all runs (s): (a) " + ", ".join(f"{v:.1f}" for v in sweeps) + " (inside the jobs " + ", ".join(f"{v:.1f}" for v in cpus)
              + "); (b) " + ", ".join(f"{v:.1f}" for v in loops)
              + "; (c) " + ", ".join(f"{v:.1f}" for v in bases)
              + "; CPU (a) " + ", ".join(f"{v:.1f}" for v in cpu_a_all) + "; CPU (b) " + ", ".join(f"{v:.1f}" for v in cpu_b_all))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
