"""Non-negative solvers in the unknown's own basis (an EGI, pixels): :class:`NNLS`, :class:`NNOMP`,
:class:`NNL1` and :class:`NNTV`, the solver-registry face of :func:`cssat.sparse.nonneg.nonneg_solve`
(weights from the problem's noise). An operator may declare its unknown's structure:
``equalities()`` — exact constraints ``C x = 0``, weighted by ``closure`` (an EGI's Minkowski
closure) — and ``differences(k)`` — its neighbours for TV (an EGI's nearest normals); without
them the TV runs on the unknown's grid (an image's pixels)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import torch

from cssat._checks import FieldError, float_param, int_param, opt
from cssat.metrics import float64_array
from cssat.recon.problem import Problem
from cssat.recon.solvers import Solver
from cssat.sparse._io import numpy_io
from cssat.sparse.differences import grid_differences
from cssat.sparse.nonneg import lam_param, nonneg_solve, weighted_system

if TYPE_CHECKING:
    from cssat._types import Array, ProblemLike

__all__ = ["NNLS", "NNOMP", "NNL1", "NNTV"]


class _NonNeg(Solver):
    method = "nnls"

    def __init__(self, closure: float = 0.0, n_nonzero: int | None = None, **extra: Any):
        self.closure = float_param(closure, "closure", 0.0)
        self.n_nonzero = opt(n_nonzero, int_param, "n_nonzero", 1)
        self.extra = extra

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        prob = Problem.of(problem, shape)
        prob.check(y)
        sigma = None
        if prob.noise_sigma is not None:  # as given: the weights 1/σ exactly
            s = prob.sigma()
            sigma = s.numpy() if bool((s > 0).all()) else None
        elif prob.noise_var is not None:
            v = prob.variance()
            sigma = v.clamp_min(float(v.max()) * 1e-12).sqrt().numpy() if float(v.max()) > 0 else None
        rows = y.reshape(-1, prob.m)
        op, extra = prob.operator, dict(self.extra)
        if self.method == "tv":
            neighbours = extra.pop("tv_neighbours", 6)
            if hasattr(op, "differences"):
                extra["differences"] = op.differences(neighbours)
            elif len(prob.x_shape) < 2:
                raise FieldError("solver", f"nntv needs the unknown's neighbours: an operator with differences() (an EGI) "
                                           f"or an image (x_shape of 2 axes or more), not x_shape {prob.x_shape}")
            else:
                extra["differences"] = grid_differences(prob.x_shape)
        C = op.equalities() if hasattr(op, "equalities") else None
        A = float64_array(op.matrix() if hasattr(op, "matrix") else op)
        out, info = [], {}
        for yb in rows:
            yv = float64_array(yb).reshape(-1)
            if not np.isfinite(yv).all():
                raise FieldError("y", f"must be finite: {int((~np.isfinite(yv)).sum())} NaN/inf samples")
            Aw, b = weighted_system(A, yv, sigma, C, self.closure)
            a, info = nonneg_solve(Aw, b, len(yv), method=self.method, weighted=sigma is not None, n_nonzero=self.n_nonzero,
                                   **extra)
            out.append(torch.as_tensor(a, dtype=y.dtype, device=y.device))
        x = torch.stack(out).reshape(*y.shape[:-1], *prob.x_shape)
        extra = {k: v for k, v in info.items() if k not in ("chi2", "n_nonzero", "method")}  # e.g. λ, discrepancy_met
        return x, {"solver_chi2": info["chi2"], "solver_n_nonzero": info["n_nonzero"], **extra}


class NNLS(_NonNeg):
    """Non-negative least squares (Lawson–Hanson, scipy), weighted by the noise; ``closure``: the
    weight of ``Σ a_k n_k = 0`` when the operator carries normals (an EGI operator)."""

    name = "nnls"
    method = "nnls"


class NNOMP(_NonNeg):
    """Non-negative OMP: ``n_nonzero`` atoms at most, or until the weighted residual reaches the
    noise (χ² ≤ m); ``closure`` as :class:`NNLS`."""

    name = "nnomp"
    method = "nnomp"


class NNL1(_NonNeg):
    """Non-negative ℓ1 (FISTA on ``½‖W(Aa − y)‖² + λ Σ a``, ``a ≥ 0``): ``lam`` relative to
    ``‖(WA)ᵀWy‖∞`` or ``"discrepancy"`` (χ² = m, from the problem's noise), ``max_iter``;
    ``closure`` as :class:`NNLS`."""

    name = "nnl1"
    method = "l1"

    def __init__(self, closure: float = 0.0, lam: float | str = 1e-3, max_iter: int = 5000):
        super().__init__(closure, None, lam=lam_param(lam), max_iter=int_param(max_iter, "max_iter", 1))


class NNTV(_NonNeg):
    """Non-negative total variation: on the sphere's grid of normals when the operator carries
    ``normals`` (an EGI operator; ``tv_neighbours`` edges per normal), else on the image's pixel
    grid (anisotropic: each pixel to its next along each axis); ``lam`` relative to
    ``‖(WG)ᵀWy‖∞`` or ``"discrepancy"`` (χ² = m, from the problem's noise), ``max_iter``;
    ``closure`` as :class:`NNLS`."""

    name = "nntv"
    method = "tv"

    def __init__(self, closure: float = 0.0, lam: float | str = 1e-3, tv_neighbours: int = 6, max_iter: int = 5000):
        super().__init__(closure, None, lam=lam_param(lam), tv_neighbours=int_param(tv_neighbours, "tv_neighbours", 1, 32),
                         max_iter=int_param(max_iter, "max_iter", 1))
