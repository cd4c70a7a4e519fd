"""Probe: is a wrong L called reliable an ambiguity of the data or a search miss?

For each seed of ``bench_pole_coverage.py --part tumble`` (the same truth, data and search; the
bootstrap off, which does not move the solution), the solution is refined again on the fitted
samples (``tumble_fit._refine``, the final grid of normals, 200 evaluations), and refined from the
truth's L, moments and periods with the solution's phases shifted over 8 × 6 starts (100
evaluations each), the lowest χ² kept. A truth's basin far below the solution's χ² is a search
miss (a start there would find it); one level with it, an ambiguity the data cannot decide::

    PYTHONPATH=$PWD python benchmarks/probe_tumble_mirror.py 932
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"

import math  # noqa: E402
import sys  # noqa: E402

import numpy as np  # noqa: E402


def probe(seed: int) -> dict:
    import bench_pole_coverage as B
    import cssat.inversion.tumble as T
    from cssat.inversion import fibonacci_sphere
    from cssat.inversion.tumble_fit import _refine
    from cssat.inversion.tumble_state import _TFit

    cap: dict = {}
    real = T.estimate_tumbling

    def spy(t, y, sun, obs, **kw):  # the seed's fitted samples and solution, captured
        sol = real(t, y, sun, obs, **kw)
        cap.update(t=t, y=y, sun=sun, obs=obs, sigma=kw["sigma"], sol=sol)
        return sol

    T.estimate_tumbling = spy
    try:
        opts = dict(B.TUMBLE, error_grids=4, bootstrap=0)
        row = B.tumble_case(seed, opts)
    finally:
        T.estimate_tumbling = real
    st, t = cap["sol"].state, cap["t"]
    fit = _TFit(t, cap["y"], np.full(len(t), 1.0 / cap["sigma"]), cap["sun"], cap["obs"],
                fibonacci_sphere(opts["n_normals"]).numpy(), None)
    span = float(t.max() - t.min())
    c_sol, x_sol, _ = _refine(fit, st.vector(), st.alpha, span, 200, st.t_ref_s, st.frame)
    tr = row["truth"]  # i1, i2, mode angle (deg), P_omega, P_phi, L lon, L lat
    x0 = x_sol.copy()
    x0[[0, 1, 2, 3, 5, 6]] = tr[0], tr[1], 1 / tr[3], 1 / tr[4], tr[5], tr[6]
    best = (math.inf, None)
    for dphi in range(0, 360, 45):
        for dt in np.linspace(0, 1 / x0[2], 6, endpoint=False):
            x1 = x0.copy()
            x1[7], x1[4] = (x1[7] + dphi) % 360, x1[4] + dt
            c1, xr, _ = _refine(fit, x1, math.radians(tr[2]), span, 100, st.t_ref_s, st.frame)
            best = min(best, (c1, xr), key=lambda b: b[0])
    return dict(seed=seed, n=len(t), sep_deg=row["sep_deg"], verdict=row["verdict"], chi2_solution=c_sol,
                chi2_truth_basin=best[0], truth_basin_L=(float(best[1][5]), float(best[1][6])), truth_L=(tr[5], tr[6]))


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    for s in map(int, sys.argv[1:]):
        print(probe(s), flush=True)
