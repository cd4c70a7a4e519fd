"""The tumbling search's carried minima made distinct — before and after on the same seeds.

``estimate_tumbling`` carries the ``n_refine`` best minima of its first arc through the
continuation. Before, it carried the best ``n_refine`` whatever they were; in the ellipse study's
seed 932 (L 170° off, called reliable) all three carried were one basin reached from three starts
(L within 2°, periods within 0.03 %) and the true side's minimum, fifth, was never continued. Now
it carries the best *distinct* basins (:func:`cssat.inversion.tumble_fit._distinct_minima`).

Each seed of ``bench_pole_coverage.py --part tumble`` (the same truth, data, search and 1σ) runs
with the code as it is; where the distinct carry kept another set of minima than the best
``n_refine`` (``carry_fired``), the seed runs again with the old carry (``before``: the old code's
row to the bit, the rest of the code being unchanged). One JSON line a seed, appended (resumes)::

    PYTHONPATH=$PWD python benchmarks/bench_tumble_carry.py --first 1100 --seeds 100 --workers 2 --out benchmarks/studies/tumble_carry_1100-1199.jsonl
    PYTHONPATH=$PWD python benchmarks/bench_tumble_carry.py --report benchmarks/studies/tumble_carry_1100-1199.jsonl
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import multiprocessing as mp  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

SEARCH = {"error_grids": 4, "bootstrap": 20}  # the ellipse study's


def _case(seed: int) -> dict:
    import bench_pole_coverage as B
    import cssat.inversion.tumble as T

    new = T._distinct_minima
    fired: list[bool] = []

    def spy(minima, n, arc_s):
        kept = new(minima, n, arc_s)
        fired.append([m[0] for m in kept] != [m[0] for m in minima[:n]])
        return kept

    T._distinct_minima = spy
    try:
        after = B.tumble_case(seed, SEARCH)
    finally:
        T._distinct_minima = new
    row = {**after, "carry_fired": bool(fired and fired[0]), "before": None}
    if row["carry_fired"]:
        T._distinct_minima = lambda minima, n, arc_s: minima[:n]  # the old carry
        try:
            row["before"] = B.tumble_case(seed, SEARCH)
        finally:
            T._distinct_minima = new
    return row


def _run(seed: int) -> dict:
    try:
        return _case(seed)
    except Exception as e:  # noqa: BLE001 - a failed seed is reported, not fatal
        return {"seed": seed, "part": "tumble", "error": repr(e)}


def _found(r: dict) -> bool:
    return r["sep_deg"] < 5 and r["period_rel"] < 1e-3


def report(rows: list[dict]) -> None:
    import bench_pole_coverage as B

    print(f"{len(rows)} seeds; the distinct carry changed the carried minima on {sum(r['carry_fired'] for r in rows)}")
    print("after (the code as it is):")
    B.report([{k: v for k, v in r.items() if k not in ("before", "carry_fired")} for r in rows])
    pairs = [(r["before"], {k: v for k, v in r.items() if k != "before"}) for r in rows if r.get("before")]
    if not pairs:
        return
    print("the seeds where the carry changed, before → after:")
    for label, pick in (("before", 0), ("after", 1)):
        sub = B.powerless([p[pick] for p in pairs])
        rel = [r for r in sub if r["verdict"] == "reliable"]
        print(f"  {label}: found {sum(map(_found, sub))} of {len(sub)}, reliable {len(rel)}, "
              f"wrong and reliable {sum(not _found(r) for r in rel)}")
    for b, a in pairs:
        print(f"  seed {a['seed']}: L {b['sep_deg']:.2f}° ({b['verdict']}) → {a['sep_deg']:.2f}° ({a['verdict']}); "
              f"period {b['period_rel']:.1e} → {a['period_rel']:.1e}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=100)
    p.add_argument("--first", type=int, default=1100)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", default=None, help="JSON lines, appended; seeds already there are skipped")
    p.add_argument("--report", nargs="+", default=None, help="only tabulate these JSON-lines files, pooled")
    args = p.parse_args()
    if args.report:
        rows = []
        for name in args.report:
            with open(name) as fh:
                rows += [json.loads(x) for x in fh if x.strip()]
        return report([r for r in rows if "error" not in r])
    done = set()
    if args.out and os.path.exists(args.out):
        with open(args.out) as fh:
            done = {json.loads(x)["seed"] for x in fh if x.strip()}
    todo = [s for s in range(args.first, args.first + args.seeds) if s not in done]
    rows = []
    with mp.get_context("spawn").Pool(max(args.workers, 1)) as pool:
        for r in pool.imap_unordered(_run, todo):
            rows.append(r)
            print(json.dumps({k: r.get(k) for k in ("seed", "sep_deg", "verdict", "carry_fired", "error")}), file=sys.stderr, flush=True)
            if args.out:
                with open(args.out, "a") as fh:
                    fh.write(json.dumps(r) + "\n")
    report([r for r in rows if "error" not in r])


if __name__ == "__main__":
    main()
