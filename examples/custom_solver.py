"""A solver of your own, used exactly where cssat's are.

Any object with ``x, info = solver(phi, y, shape)`` is a solver: here projected Landweber
iterations (gradient steps on ½‖Φx − y‖², clipped to the image range [0, 1]), compared with OMP
and cssat's TV on the same light curve. In a Hydra run the same class plugs in through a YAML
with its ``_target_`` on the search path (README: "Extending cssat").

    python examples/custom_solver.py --size 32
"""

import argparse

import torch

from cssat.data import load_target
from cssat.metrics import psnr
from cssat.physics import GaussianAtmosphere, Measurement
from cssat.recon import OMP, TV
from cssat.sparse import MatrixOperator
from cssat.sparse.solvers import operator_norm_sq


class ProjectedLandweber:
    """``x ← clip(x − Φᵀ(Φx − y) / ‖Φ‖², 0, 1)``, ``n_iter`` times, from ``Φ⁺y``."""

    name = "landweber"

    def __init__(self, n_iter: int = 200):
        self.n_iter = n_iter

    def __call__(self, phi, y, shape):
        op = phi if not isinstance(phi, torch.Tensor) else MatrixOperator(phi)
        step = 1.0 / operator_norm_sq(op, dtype=y.dtype)
        x = op.A_dagger(y).clamp(0, 1)                     # start from the least-squares image
        for _ in range(self.n_iter):
            x = (x - step * op.A_adjoint(op.A(x) - y)).clamp(0, 1)
        return x.reshape(*y.shape[:-1], *shape), {"solver_iterations": self.n_iter}


ap = argparse.ArgumentParser()
ap.add_argument("--size", type=int, default=32)
ap.add_argument("--ratio", type=float, default=0.4)
args = ap.parse_args()

n = args.size
x = torch.tensor(load_target("tess", n), dtype=torch.float64)
phi = GaussianAtmosphere().operator(round(args.ratio * n * n), n * n, seed=0, dtype=torch.float64)
y = Measurement(phi)(x)
for solver in (ProjectedLandweber(), OMP(), TV()):
    x_hat, info = solver(phi, y, (n, n))
    print(f"{type(solver).__name__:>18}: PSNR {psnr(x, x_hat.clamp(0, 1), data_range=1.0):6.2f} dB")
