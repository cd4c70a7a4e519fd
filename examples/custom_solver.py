"""A solver of your own, used exactly where cssat's are.

Any object with ``x, info = solver(problem, y)`` is a solver: ``problem`` carries the operator
``Φ`` (``problem.operator``) and the unknown's shape (``problem.x_shape``); a
``cssat.physics.Measurement`` is passed as it is. Here: Tikhonov-regularised least squares in
closed form, ``x = Φᵀ(ΦΦᵀ + αI)⁻¹y``, clipped to the image range, compared with cssat's OMP,
TV and projected Landweber on the same light curve, and with the flat image that the total flux
alone gives. In a Hydra run the same class plugs in through a YAML with its ``_target_`` on the
search path (docs/guides/extending.md).

    python examples/custom_solver.py --size 32
"""

import argparse

import torch

from cssat.data import load_target
from cssat.metrics import psnr
from cssat.physics import GaussianAtmosphere, Measurement
from cssat.recon import OMP, TV, Landweber, Problem


class Tikhonov:
    """``min ‖Φx − y‖² + α‖x‖²`` with ``α = alpha · ‖Φ‖_F² / N`` (relative to the mean column
    energy), solved as ``x = Φᵀ(ΦΦᵀ + αI)⁻¹y`` (an ``m × m`` system)."""

    name = "tikhonov"

    def __init__(self, alpha: float = 1e-2):
        self.alpha = alpha

    def __call__(self, problem, y):
        problem = Problem.of(problem)                      # a Problem, a Measurement, ...
        phi = problem.operator.matrix(dtype=y.dtype)
        a = self.alpha * float((phi * phi).sum()) / phi.shape[1]
        gram = phi @ phi.T + a * torch.eye(phi.shape[0], dtype=y.dtype)
        x = phi.T @ torch.linalg.solve(gram, y)
        return x.reshape(problem.x_shape).clamp(0, 1), {"solver_alpha": a}


ap = argparse.ArgumentParser()
ap.add_argument("--size", type=int, default=32)
ap.add_argument("--ratio", type=float, default=0.4)
args = ap.parse_args()

n = args.size
x = torch.tensor(load_target("tess", n), dtype=torch.float64)
phi = GaussianAtmosphere().operator(round(args.ratio * n * n), n * n, seed=0, dtype=torch.float64)
meas = Measurement(phi, x_shape=(n, n))
y = meas(x)
print(f"{'flat image':>18}: PSNR {psnr(x, torch.full_like(x, float(x.mean())), data_range=1.0):6.2f} dB")
for solver in (Tikhonov(), OMP(), TV(), Landweber()):
    x_hat, info = solver(meas, y)
    print(f"{type(solver).__name__:>18}: PSNR {psnr(x, x_hat.clamp(0, 1), data_range=1.0):6.2f} dB")
