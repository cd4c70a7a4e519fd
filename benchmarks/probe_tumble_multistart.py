"""Probe: does a local multi-start in L widen the tumbler's bootstrap 1σ (as it widens the pole's)?

For each seed of ``bench_pole_coverage.py --part tumble`` (the same truth, data and search, with
``error_grids 4, bootstrap 20`` as the L study), the solution's 1σ is computed twice: as shipped
(each bootstrap replicate refitted from the solution) and with every refit also started from 4 L
directions 2° and 4° about the solution (the pole's first 4 ``LOCAL_OFFSETS``: bearings 0, 135, 180,
315°), the lowest χ² kept. Printed
per seed: L's error, the reported ``L_err_deg``, the bootstrap's 1σ both ways and the refined grid's
shift both ways::

    PYTHONPATH=$PWD python benchmarks/probe_tumble_multistart.py 457 460
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"

import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

def main(seeds: list[int]) -> None:
    import bench_pole_coverage as b

    import cssat.inversion.tumble as tm
    import cssat.inversion.tumble_fit as tf
    from cssat.inversion.spin_errors import _offset_pole
    from cssat.inversion.spin_search import LOCAL_OFFSETS

    refine, errors = tf._refine, tf._errors
    multi = {"on": False}
    store: dict = {}

    def refine_multi(fit, x0, alpha0, span_s, maxfev, t_ref, frame):
        best = refine(fit, x0, alpha0, span_s, maxfev, t_ref, frame)
        for dist, bearing in LOCAL_OFFSETS[:4] if multi["on"] else ():
            x1 = np.array(x0, dtype=float)
            x1[5], x1[6] = _offset_pole(float(x0[5]), float(x0[6]), bearing, dist)
            best = min(best, refine(fit, x1, alpha0, span_s, maxfev, t_ref, frame), key=lambda r: r[0])
        return best

    def errors_both(*args, **kw):
        out = errors(*args, **kw)
        multi["on"] = True
        try:
            out2 = errors(*args, **kw)
        finally:
            multi["on"] = False
        store.update(bootstrap=out[0].get("bootstrap_L_err_deg"), bootstrap_multi=out2[0].get("bootstrap_L_err_deg"),
                     grid=out[0]["grid_L_shift_deg"], grid_multi=out2[0]["grid_L_shift_deg"])
        return out

    tf._refine = refine_multi  # _errors' refits call it by its module name
    tm._errors = errors_both  # estimate_tumbling imported _errors by name
    for seed in seeds:
        store.clear()
        row = b.tumble_case(seed, {"error_grids": 4, "bootstrap": 20})
        print(json.dumps({"seed": seed, "verdict": row["verdict"], "sep_deg": row["sep_deg"], "L_err_deg": row["L_err_deg"],
                          **store}), flush=True)


if __name__ == "__main__":
    main([int(s) for s in sys.argv[1:]] or [457, 460])
