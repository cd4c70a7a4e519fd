"""Two runs of ``bench_pole_coverage.py --part tumble`` on the same seeds, before and after a
change of the search: found, reliable and wrong-and-reliable in each, and every seed whose
answer moved (L by more than 1°, or its verdict)::

    python benchmarks/compare_tumble_rows.py benchmarks/studies/tumble_ellipse_1000-1099.jsonl benchmarks/studies/tumble_rephase_1000-1099.jsonl
"""

from __future__ import annotations

import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_pole_coverage as B  # noqa: E402


def _rows(name: str) -> dict[int, dict]:
    with open(name) as fh:
        rows = [json.loads(x) for x in fh if x.strip()]
    return {r["seed"]: r for r in B.powerless([r for r in rows if "error" not in r])}


def main(before_name: str, after_name: str) -> None:
    before, after = _rows(before_name), _rows(after_name)
    seeds = sorted(set(before) & set(after))
    print(f"{len(seeds)} seeds in both")
    for label, rows in (("before", before), ("after", after)):
        sub = [rows[s] for s in seeds]
        rel = [r for r in sub if r["verdict"] == "reliable"]
        print(f"  {label}: found {sum(map(B.tumble_found, sub))}, reliable {len(rel)}, reliable and found "
              f"{sum(map(B.tumble_found, rel))}, wrong and reliable {sum(not B.tumble_found(r) for r in rel)} "
              f"(seeds {[r['seed'] for r in rel if not B.tumble_found(r)]}); median cpu {sorted(r['cpu_s'] for r in sub)[len(sub) // 2]:.0f} s")
    print("seeds whose answer moved (L by more than 1°, or the verdict):")
    for s in seeds:
        b, a = before[s], after[s]
        if abs(a["sep_deg"] - b["sep_deg"]) > 1 or a["verdict"] != b["verdict"]:
            print(f"  seed {s}: L {b['sep_deg']:.2f}° off ({b['verdict']}, found {B.tumble_found(b)}) → {a['sep_deg']:.2f}° off "
                  f"({a['verdict']}, found {B.tumble_found(a)}); period {b['period_rel']:.1e} → {a['period_rel']:.1e}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
