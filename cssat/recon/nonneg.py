"""Non-negative solvers in the unknown's own basis (the EGI of :mod:`cssat.inversion`; pixels):
:class:`NNLS`, :class:`NNOMP`, :class:`NNL1` and :class:`NNTV`, the solver-registry face of
:func:`cssat.inversion.recover_egi` (weights from the problem's noise)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import torch

from cssat._checks import FieldError, float_param, int_param, opt
from cssat.recon.problem import Problem
from cssat.recon.solvers import Solver
from cssat.sparse._io import numpy_io

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
        from cssat.inversion import recover_egi

        prob = Problem.of(problem, shape)
        prob.check(y)
        sigma = None
        if prob.noise_var is not None or prob.noise_sigma is not None:
            v = prob.variance()
            sigma = v.clamp_min(float(v.max()) * 1e-12).sqrt().numpy() if float(v.max()) > 0 else None
        rows = y.reshape(-1, prob.m)
        extra = dict(self.extra)
        if self.method == "tv" and not hasattr(prob.operator, "normals"):
            from cssat.inversion.recover import grid_differences

            if len(prob.x_shape) < 2:
                raise FieldError("solver", f"nntv needs the unknown's neighbours: an EGI operator (normals) or an image "
                                           f"(x_shape of 2 axes or more), not x_shape {prob.x_shape}")
            extra["differences"] = grid_differences(prob.x_shape)
        out, info = [], {}
        for yb in rows:
            a, info = recover_egi(prob.operator, yb, sigma=sigma, normals=getattr(prob.operator, "normals", None),
                                  method=self.method, closure=self.closure if hasattr(prob.operator, "normals") else 0.0,
                                  n_nonzero=self.n_nonzero, **extra)
            out.append(torch.as_tensor(a, dtype=y.dtype, device=y.device))
        x = torch.stack(out).reshape(*y.shape[:-1], *prob.x_shape)
        return x, {"solver_chi2": info["chi2"], "solver_n_nonzero": info["n_nonzero"]}


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
        from cssat.inversion.recover import lam_param

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
        from cssat.inversion.recover import lam_param

        super().__init__(closure, None, lam=lam_param(lam), tv_neighbours=int_param(tv_neighbours, "tv_neighbours", 1, 32),
                         max_iter=int_param(max_iter, "max_iter", 1))
