"""Benchmark: light curves on irregular time stamps with a tumbling model (issue 23).

1. ``make_scenario(times=...)`` on 10,000 irregular stamps over three nights;
2. the torque-free attitude at those stamps: cssat's exact solution (``torque_free``) against
   scipy's DOP853 integration of Euler's equations and dR/dt = R[ω]× at rtol 1e-12 (the peer),
   with the largest difference of their frames;
3. the whole light curve: the Astra-like model (4,028 facets) with self- and observer-shadowing,
   tumbling, on those stamps (the issue's goal: ≤ 10 s on 2 cores).

Times are medians of ``--repeats`` runs. Run from the repository root::

    python benchmarks/attitude.py --threads 2 --repeats 3
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from _timing import median_time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from scipy.integrate import solve_ivp

    from cssat.optics import simulate_light_curve
    from cssat.scene import astra_like, make_scenario
    from cssat.scene.attitude import torque_free
    from cssat.scene.attitudes import Tumbling

    rng = np.random.default_rng(0)
    t0 = np.datetime64("2020-04-01T19:00:00", "us")
    stamps = np.unique(np.concatenate([t0 + np.timedelta64(d, "D") + rng.uniform(0, 8 * 3600e6, 3400).astype("timedelta64[us]")
                                       for d in range(3)]))[:10000]
    s_sc, _, sc = median_time(lambda: make_scenario(times=stamps), args.repeats)
    print(f"make_scenario, {len(stamps)} irregular stamps over 3 nights: {s_sc:.3f} s")

    I = np.diag([3000.0, 4000.0, 5000.0])
    q0, w0 = np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.01, 0.005, 0.02])
    t = (stamps - stamps[0]).astype(np.int64) * 1e-6

    def integrate():
        def rhs(_, y):
            R, om = y[:9].reshape(3, 3), y[9:]
            wx = np.array([[0, -om[2], om[1]], [om[2], 0, -om[0]], [-om[1], om[0], 0]])
            return np.concatenate([(R @ wx).ravel(), np.linalg.solve(I, np.cross(I @ om, om))])

        sol = solve_ivp(rhs, (0, t[-1]), np.concatenate([np.eye(3).ravel(), w0]), method="DOP853", rtol=1e-12,
                        atol=1e-14, t_eval=t)
        return np.swapaxes(sol.y[:9].T.reshape(-1, 3, 3), 1, 2)

    s_tf, _, F = median_time(lambda: torque_free(I, q0, w0, t), args.repeats)
    s_ivp, _, Fn = median_time(integrate, max(1, args.repeats // 3))
    print(f"torque-free frames: cssat {s_tf:.3f} s, scipy DOP853 {s_ivp:.3f} s, ratio {s_ivp / s_tf:.0f}x; "
          f"max |ΔF| {np.abs(F - Fn).max():.1e} over {t[-1] / 86400:.1f} days")
    mesh = astra_like()
    tumble = Tumbling(np.diag(I), q0, w0)
    s_lc, runs, lc = median_time(lambda: simulate_light_curve(mesh, sc, attitude=tumble), args.repeats)
    print(f"light curve, {len(stamps)} stamps x {len(mesh)} facets, shadows, tumbling: {s_lc:.2f} s "
          f"(runs {', '.join(f'{r:.2f}' for r in runs)})")


if __name__ == "__main__":
    main()
