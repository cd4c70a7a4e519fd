"""Benchmark: TV on a centred positive system — ADMM with an exact solve against Chambolle–Pock.

The realism maps' problem (issue 22): the TESS-like target at 32², m = 819 samples through the
phase-screen atmosphere at 58″ (V = 10 photometric noise), centred (:class:`cssat.physics.Centered`).
For each relative weight λ both methods minimise ``½‖Ax − b‖² + λ TV(x)``, ``x ≥ 0``:
``tv_admm`` to rtol 1e-5 (its N × N factor formed per ρ = 10 λ, timed in), ``tv_pdhg`` for its
default 2000 iterations. Printed: seconds (median of ``--repeats``), iterations, the objective
each reaches, and the image each returns, against a reference solved by ADMM to rtol 1e-9.
PDHG's images do not change with λ (it stops far from the minimum: its steps scale as 1/‖A‖).
Run from the repository root::

    python benchmarks/tv_centred.py --threads 2 --repeats 3
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import torch

from _timing import median_time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from cssat.data import load_target
    from cssat.physics import Centered, Measurement, PhaseScreenAtmosphere, PhotometricNoise
    from cssat.sparse.solvers import tv_gradient, tv_pdhg
    from cssat.sparse.tv_admm import relative_weight, tv_admm

    n = 32
    x = load_target("tess", n)
    atm = PhaseScreenAtmosphere(object_size_m=10.0, range_km=10.0 / (58.0 * math.pi / 648000) / 1e3)
    op = atm.operator(819, n * n, seed=0, dtype=torch.float64)
    xt = torch.as_tensor(x).reshape(-1)
    y = Measurement(op, PhotometricNoise(magnitude=10.0), seed=1, x_shape=(n, n))(xt)
    C = Centered(op.matrix())
    b = C.data(y)[None]
    ref_w = float(relative_weight(C, b, 1.0)[0])

    def objective(img, lam):
        g = tv_gradient(img.reshape(1, n, n))
        r = C(img.reshape(1, -1)) - b
        return float(0.5 * (r * r).sum() + lam * ref_w * torch.sqrt((g * g).sum(1)).sum())

    print(f"{'λ':>8} | {'method':>6} | {'s':>7} | {'iter':>5} | {'objective':>13} | {'‖x − x*‖/‖x*‖':>13}")
    for lam in (1e-1, 1e-2, 1e-3):
        best = tv_admm(C, b, (n, n), lam=lam, max_iter=20000, rtol=1e-9)[0][0]
        for name, run in (("admm", lambda: tv_admm(C, b, (n, n), lam=lam, max_iter=2000, rtol=1e-5)),
                          ("pdhg", lambda: tv_pdhg(C, b, (n, n), lam=lam, max_iter=2000, rtol=1e-5, return_info=True))):
            C.__dict__.pop("_tv_admm", None)  # ADMM's factor formed inside the timing
            secs, _, out = median_time(run, args.repeats)
            img, info = out[0].reshape(-1, n, n)[0], out[1]
            it = info.n_iter
            err = float((img - best).norm() / best.norm())
            print(f"{lam:8.0e} | {name:>6} | {secs:7.2f} | {it:5d} | {objective(img, lam):13.6e} | {err:13.2e}")
    print(f"(the flat image's objective: {objective(torch.full((n * n,), float(xt.mean()), dtype=torch.float64), 0):.6e}"
          " without the TV term)")


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
