"""Benchmark: one loss-and-gradient evaluation of the soft-shadowed box-wing, the soft shadows
computed on every (sample, cell) pair against only where the cell faces both the Sun and the
observer (``soft_visibility(front_only=True)``, what ``fit_box_wing(visibility="soft")`` uses),
each ray's soft hit of every occluder built with its gradient (``hit_floor=None``) — and, front
only, the default that builds only the hits above ``HIT_FLOOR`` (1e-12; a no-gradient pass
finds them).

Sizes: the shadow-fit benchmark's fitted nights (``bench_shadow_fit.geometry``: 451 samples at
120 s), the b702-like platform's parameters (``benchmarks/_platforms.py``) — the box-wing with a
mirror pair of dishes (``nominal``), and the finer family with its parts (``FINE``) — at
``divisions`` 4 and 2, dishes 4 × 16 cells, τ = 0.1 m and 0.01 m (the fits' continuation runs
from ~0.1 × the bus's half-size down to a few mm); one thread. Prints the median wall time of
``--repeats`` evaluations each, the ratios, and the largest differences of the light curve and
of its gradient against every pair's (front only: round-off; the floor: ~1e-13).

Run from the repository root::

    PYTHONPATH=$PWD python benchmarks/bench_soft_front.py --repeats 5
"""

from __future__ import annotations

import os

if __name__ == "__main__":
    for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    import torch

    import _platforms
    import bench_shadow_fit as bench
    from _timing import median_time
    from cssat.inversion.parametric import box_wing, box_wing_light_curve
    from cssat.inversion.soft_shadow import HIT_FLOOR, soft_visibility

    torch.set_num_threads(1)
    geo = bench.geometry(120.0)
    fit = geo.night < 2
    S, V = geo.sun[fit], geo.observer[fit]
    _, nominal = _platforms.b702_like()
    parts, params = _platforms.FINE["b702_like"]
    print(f"{int(fit.sum())} samples; median of {args.repeats} loss-and-gradient evaluations, one thread")
    print("| family | divisions | τ (m) | cells | all pairs (s) | front only (s) | front, floor (s) | all ÷ front | front ÷ floor "
          "| max |Δy|/max y: front, floor | max |Δ∇|/max |∇|: front, floor |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|")
    for label, kw, p in (("box-wing, 2 dishes", dict(dishes=2), nominal), ("finer family", parts, list(params.values()))):
        for div in (4, 2):
            for tau in (0.1, 0.01):
                kk = dict(kw, divisions=div, **bench.DISH_CELLS)
                q0 = torch.tensor(p, dtype=torch.float64)

                def evaluate(front_only, floor):
                    q = q0.clone().requires_grad_(True)
                    vis = soft_visibility(q, S, V, tau=tau, front_only=front_only, hit_floor=floor, **kk)
                    y = box_wing_light_curve(q, S, V, vis, range_km=1e-3, irradiance=1.0, **kk)
                    (g,) = torch.autograd.grad(y.sum(), q)
                    return y.detach(), g

                t_all, _, (y_all, g_all) = median_time(lambda: evaluate(False, None), args.repeats)
                t_front, _, (y_front, g_front) = median_time(lambda: evaluate(True, None), args.repeats)
                t_floor, _, (y_floor, g_floor) = median_time(lambda: evaluate(True, HIT_FLOOR), args.repeats)

                def rel(a, b):
                    return float((a - b).abs().max() / a.abs().max())

                cells = len(box_wing(q0, **kk)[1])
                print(f"| {label} | {div} | {tau} | {cells} | {t_all:.3f} | {t_front:.3f} | {t_floor:.3f} | "
                      f"{t_all / t_front:.2f} | {t_front / t_floor:.2f} | {rel(y_all, y_front):.0e}, {rel(y_all, y_floor):.0e} "
                      f"| {rel(g_all, g_front):.0e}, {rel(g_all, g_floor):.0e} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
