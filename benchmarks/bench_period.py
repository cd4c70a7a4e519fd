"""Benchmark: the period of SYNTHETIC MMT-like satellite tracks (issue 34, point 3) — not real data:
the real-track numbers are ``benchmarks/bench_real_mmt.py``'s.

On the synthetic tracks of :mod:`mmt_like` (cadence 0.1 s, two interleaved channels, gaps,
white noise and drifts; rocket bodies, glinting satellites, sinusoids, non-variable tracks and
red noise), compares

* cssat's :func:`cssat.inversion.estimate_period` with its defaults: ``periodic`` and
  ``period_s``;
* astropy's plain Lomb–Scargle on a grid from the data: ``autopower(minimum_frequency=2/span,
  maximum_frequency=0.5/median_step, samples_per_peak=10)``, the period ``1/f_peak``, periodic
  when ``false_alarm_probability(power.max()) < 1e-3``.

Printed: for periodic tracks the fraction called periodic with a period within 1 % of the
truth (and, in brackets, the fraction whose best period is within 1 % whatever the verdict), for
the others the fraction called not periodic, by kind; the median time per track of each method
(median of ``--repeats`` runs per track) and their ratio; the time for a 2000-sample track.
Single-threaded (BLAS, OpenMP, numba, torch). Run from the repository root::

    python benchmarks/bench_period.py --n 200 --repeats 3 [--json /tmp/period.json]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mmt_like import make_tracks  # noqa: E402

TOL = 0.01


def _limit_threads():
    """Everything single-threaded; returns the threadpoolctl context (kept alive) or None."""
    ctx = None
    try:
        from threadpoolctl import threadpool_limits

        ctx = threadpool_limits(1)
    except ImportError:
        pass
    if "torch" in sys.modules:
        import torch

        torch.set_num_threads(1)
    try:
        import numba

        numba.set_num_threads(1)
    except Exception:  # noqa: BLE001 — numba absent or not initialised
        pass
    return ctx


def astropy_period(t, y):
    """Plain Lomb–Scargle on a data-derived grid: (period_s, periodic, fap)."""
    from astropy.timeseries import LombScargle

    span = float(t.max() - t.min())
    dt = np.diff(np.sort(t))
    step = float(np.median(dt[dt > 0]))
    ls = LombScargle(t, y)
    f, p = ls.autopower(minimum_frequency=2.0 / span, maximum_frequency=0.5 / step, samples_per_peak=10)
    i = int(np.argmax(p))
    fap = float(ls.false_alarm_probability(p[i], minimum_frequency=2.0 / span, maximum_frequency=0.5 / step,
                                           samples_per_peak=10))
    return 1.0 / float(f[i]), bool(fap < 1e-3), fap


def cssat_period(t, y, **kw):
    from cssat.inversion import estimate_period

    r = estimate_period(t, y, **kw)
    return r


def _timed(fn, repeats):
    ts, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), out


def rel_err(p, truth):
    return abs(p / truth - 1.0) if (truth and np.isfinite(p)) else float("inf")


def relation(p, truth):
    """A short name of how a wrong period relates to the truth."""
    if not np.isfinite(p):
        return "nan"
    r = p / truth
    for name, k in (("P", 1), ("P/2", 0.5), ("2P", 2), ("P/3", 1 / 3), ("P/4", 0.25), ("3P", 3), ("2P/3", 2 / 3),
                    ("3P/2", 1.5), ("4P", 4)):
        if abs(r / k - 1) < TOL:
            return name
    if abs(r / 1 - 1) < 0.05:
        return "~P(1-5%)"
    return f"x{r:.3g}"


def run(tracks, repeats, kw=None, with_astropy=True):
    kw = kw or {}
    rows = []
    for i, d in enumerate(tracks):
        t, y = d["t"], d["mag"]
        # as the characterise experiment: each channel its own zero point, the full turn of a rocket body
        kw_d = {"zero_points": d.get("channels"), "convention": "double_peaked" if d["kind"] == "rocket" else "photometric",
                **kw}
        tc, r = _timed(lambda: cssat_period(t, y, **kw_d), repeats)
        row = {"i": i, "kind": d["kind"], "label": d["label"], "truth": d["period_s"], "n": len(t),
               "span": float(t[-1] - t[0]), "c_periodic": r.get("verdict", "periodic" if r["periodic"] else "") == "periodic",
               "c_verdict": r.get("verdict"), "c_best": float(r["best_period_s"]),
               "c_fap": float(r["fap"]), "c_repeat": float(r["repeat"]), "c_chi2n": float(r["chi2_per_sample"]),
               "c_nharm": int(r["n_harmonics"]), "c_f0": float(r["f0_period_s"]), "c_time": tc,
               "c_warn": r["warnings"], "meta": d["meta"]}
        if with_astropy:
            ta, (pa, oka, fapa) = _timed(lambda: astropy_period(t, y), repeats)
            row.update(a_period=pa, a_periodic=oka, a_fap=fapa, a_time=ta)
        rows.append(row)
    return rows


def score(rows):
    """Per kind: (n, cssat fraction right, cssat best-within-1%, astropy right, astropy best-within-1%)."""
    out = {}
    for kind in sorted({r["kind"] for r in rows}, key=lambda k: (rows[[x["kind"] for x in rows].index(k)]["label"], k)):
        rs = [r for r in rows if r["kind"] == kind]
        if rs[0]["label"] == "periodic":
            c = np.mean([r["c_periodic"] and rel_err(r["c_best"], r["truth"]) < TOL for r in rs])
            cb = np.mean([rel_err(r["c_best"], r["truth"]) < TOL for r in rs])
            a = np.mean([r.get("a_periodic", False) and rel_err(r.get("a_period", np.nan), r["truth"]) < TOL for r in rs])
            ab = np.mean([rel_err(r.get("a_period", np.nan), r["truth"]) < TOL for r in rs])
        else:
            c = np.mean([not r["c_periodic"] for r in rs])
            a = np.mean([not r.get("a_periodic", True) for r in rs])
            cb = ab = np.nan
        out[kind] = (len(rs), rs[0]["label"], c, cb, a, ab)
    return out


def summary(rows):
    per = [r for r in rows if r["label"] == "periodic"]
    non = [r for r in rows if r["label"] != "periodic"]
    c_hit = np.mean([r["c_periodic"] and rel_err(r["c_best"], r["truth"]) < TOL for r in per])
    c_rej = np.mean([not r["c_periodic"] for r in non])
    out = {"cssat_periodic_hit": float(c_hit), "cssat_nonperiodic_reject": float(c_rej)}
    if "a_period" in rows[0]:
        out["astropy_periodic_hit"] = float(np.mean([r["a_periodic"] and rel_err(r["a_period"], r["truth"]) < TOL
                                                     for r in per]))
        out["astropy_nonperiodic_reject"] = float(np.mean([not r["a_periodic"] for r in non]))
    return out


def print_table(rows):
    sc = score(rows)
    print(f"{'kind':<12} {'label':<12} {'n':>4}  {'cssat':>7} {'(best)':>7}  {'astropy':>7} {'(best)':>7}")
    for kind, (n, label, c, cb, a, ab) in sc.items():
        fmt = lambda v: "" if not np.isfinite(v) else f"{v:.3f}"  # noqa: E731
        print(f"{kind:<12} {label:<12} {n:>4}  {c:>7.3f} {fmt(cb):>7}  {a:>7.3f} {fmt(ab):>7}")
    s = summary(rows)
    per = [r for r in rows if r["label"] == "periodic"]
    non = [r for r in rows if r["label"] != "periodic"]
    print(f"{'ALL periodic':<25} {len(per):>4}  {s['cssat_periodic_hit']:>7.3f} {'':>7}  "
          f"{s.get('astropy_periodic_hit', np.nan):>7.3f}   (within 1 % and called periodic)")
    print(f"{'ALL not periodic':<25} {len(non):>4}  {s['cssat_nonperiodic_reject']:>7.3f} {'':>7}  "
          f"{s.get('astropy_nonperiodic_reject', np.nan):>7.3f}   (called not periodic)")
    tc = float(np.median([r["c_time"] for r in rows]))
    line = f"median time per track: cssat {tc * 1e3:.1f} ms"
    if "a_time" in rows[0]:
        ta = float(np.median([r["a_time"] for r in rows]))
        line += f", astropy {ta * 1e3:.1f} ms, ratio cssat/astropy {tc / ta:.2f}"
    print(line)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-channel-offset", action="store_true", help="no zero-point offset between channels")
    ap.add_argument("--json", default=None, help="write the per-track results there")
    args = ap.parse_args(argv)

    import cssat.inversion  # noqa: F401 — imported first so that torch (if it comes) is limited too

    ctx = _limit_threads()  # noqa: F841
    tracks = make_tracks(args.n, args.seed, channel_offset=not args.no_channel_offset)
    cssat_period(tracks[0]["t"], tracks[0]["mag"])  # warm the imports
    astropy_period(tracks[0]["t"], tracks[0]["mag"])
    rows = run(tracks, args.repeats)
    print(f"{args.n} MMT-like tracks (seed {args.seed}), {args.repeats} repeats; periodic: fraction called periodic "
          f"within {TOL:.0%} of the truth ((best): best period within {TOL:.0%} whatever the verdict); "
          "others: fraction called not periodic")
    print_table(rows)
    # a 2000-sample track: the longest periodic one (else the longest)
    big = max(tracks, key=lambda d: (len(d["t"]), d["label"] == "periodic"))
    tc, _ = _timed(lambda: cssat_period(big["t"], big["mag"]), max(args.repeats, 3))
    ta, _ = _timed(lambda: astropy_period(big["t"], big["mag"]), max(args.repeats, 3))
    print(f"{len(big['t'])}-sample track ({big['kind']}, span {big['t'][-1]:.1f} s): cssat {tc * 1e3:.1f} ms, "
          f"astropy {ta * 1e3:.1f} ms, ratio {tc / ta:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, default=float, indent=0))
        print(f"per-track results: {args.json}")


if __name__ == "__main__":
    main()
