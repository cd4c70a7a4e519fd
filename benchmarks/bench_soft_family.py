"""Benchmark: the box-wing fit with cast or soft shadows on a truth inside its family.

The truth is ``tests/test_shadow_fit_bench.py``'s (wings 3.125 their width, hinge 35°, gap 0.5 m,
albedos 0.35 / 0.15, ``divisions`` 2), simulated by :func:`bench_shadow_fit.fit_truth` (600 s
cadence, 2 % noise, seed 3); each row fits it from the EGI start (wings 3.75 their width) with
``fit_box_wing(visibility=...)`` at the given ``outer × inner`` and ``softness``, and prints the
held-out rms over the true mesh's, the volume IoU and the fitted wings' aspect, gap and albedos::

    python benchmarks/bench_soft_family.py --outer 3 5 --inner 30
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--outer", type=int, nargs="+", default=[3, 5])
    ap.add_argument("--inner", type=int, default=30)
    ap.add_argument("--softness", type=float, nargs="+", default=[0.1, 0.3])
    args = ap.parse_args(argv)
    import bench_shadow_fit as bench
    import torch

    from cssat.inversion.parametric import box_wing_mesh

    torch.set_num_threads(1)
    P = np.array([1.0, 0.8, 1.3, 5.0, 1.6, math.radians(35), 0.5, 0.35, 0.15])
    geo = bench.geometry(step_s=600.0)
    truth = bench.Truth(box_wing_mesh(P, divisions=2), 0, True, P, "in the family")
    print("| fit from the EGI | outer × inner | held-out rms ratio | IoU | wings' aspect, gap | albedos bus / panel | CPU s |")
    print("|---|---|---:|---:|---|---|---:|")
    for outer in args.outer:
        for vis, soft in [("cast", None)] + [("soft", s_) for s_ in args.softness]:
            st = dict(divisions=2, outer=outer, inner=args.inner, visibility=vis, **({"softness": soft} if soft else {}))
            (r,) = bench.fit_truth("box_wing", geo, seed=3, floor=0.02, mesh=truth, n_points=20_000, oracle=False,
                                   fit_settings=st)["rows"]
            q = r["params"]
            label = "cast (held fixed)" if vis == "cast" else f"soft, softness {soft:g}"
            print(f"| {label} | {outer} × {args.inner} | {r['rms_ratio']:.2f} | {r['iou']:.2f} | "
                  f"{q['length'] / q['width']:.2f}, {q['gap']:.2f} | {q['cd_bus']:.2f} / {q['cd_panel']:.2f} | {r['cpu_s']:.0f} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
