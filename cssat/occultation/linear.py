"""The linearised (weak-occulter) shadow as a linear operator, so the silhouette can be
reconstructed by cssat's linear solvers — TV, ℓ1 in the DCT, OMP (issue 25, point 3a).

The ground intensity behind an occulter ``m`` is ``I = |1 − h∗m|² = 1 − 2 Re(h∗m) + |h∗m|²``
(:mod:`cssat.occultation.fresnel`). Dropping the quadratic term (the Born approximation of a
weak occulter, ``|h∗m| ≪ 1``) leaves the linear map

    ``y − 1 ≈ A m``,  ``A m = R(K ∗ (−2 Σ_λ w_λ Re(h_λ ∗ m)))``

— ``K`` the averaging kernel (aperture ∗ star ∗ smear, :func:`~cssat.occultation.record.pattern_kernel`),
``R`` the telescopes' sampling (:func:`~cssat.occultation.record.record`) — optionally with its
rows divided by the samples' 1σ (``sigma``), so a solver's least squares is the χ².

Where it holds: an occulter small against the Fresnel scale ``√(λz)`` (Fresnel number
``a²/(λz) ≪ 1``): its diffraction pattern is weak everywhere. A 10 m satellite at GEO has a
Fresnel number ≈ 1 — its shadow is deep (``I → 0`` behind it, where the linear model predicts
``−1``), so the linearised route is biased there; it is the fast route for small or
semi-transparent occulters, and a starting point for the non-linear fit
(:func:`~cssat.occultation.invert_silhouette` ``init=``).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, int_param
from cssat.occultation.fresnel import aperture_field
from cssat.occultation.record import record, smooth
from cssat.sparse.operators import LinearOperator
from cssat.sparse.problem import Problem
from cssat.sparse.solvers import operator_norm_sq

__all__ = ["ShadowOperator", "invert_linear"]


class ShadowOperator(LinearOperator):
    """``A (J·K, H·W)``: an occulter mask ``(B, H, W)`` (or rows ``(B, H·W)``) ↦ the linearised
    recorded series less 1, rows ``(B, J·K)`` (telescope-major: ``J`` telescopes × ``K`` exposures),
    each row divided by ``sigma`` when given. The geometry's arguments are those of
    :func:`~cssat.occultation.record.record` and :func:`~cssat.occultation.shadow` (``ground``: the
    pattern on a larger ground grid than the mask's). Matrix-free:
    the forward is FFTs and a bilinear sampling; the adjoint is the forward's vector–Jacobian
    product (exact: the map is linear). Follows the input's dtype and device (float64 →
    complex128 kernels)."""

    def __init__(self, shape: Sequence[int], pixel_m: float, wavelength_m: Any, distance_m: float, positions_m: Any,
                 velocity_m_s: Any, times_s: Any, *, kernel: Any = None, weights: Any = None, sigma: Any = None,
                 ground: Any = None):
        super().__init__()
        H, W = (int_param(v, "shape", 1, 1 << 14) for v in shape)
        self.in_shape = (H, W)
        self.n_in = H * W
        self.ground = ground
        self.pixel_m, self.distance_m = float(pixel_m), float(distance_m)
        self.lams = np.atleast_1d(np.asarray(wavelength_m, dtype=np.float64))
        w = np.ones(len(self.lams)) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != self.lams.shape or (w < 0).any() or w.sum() <= 0:
            raise FieldError("weights", f"expected {len(self.lams)} weights >= 0 with a positive sum")
        self.w = w / w.sum()
        self.positions = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
        self.velocity = np.asarray(velocity_m_s, dtype=np.float64).reshape(2)
        self.times = np.asarray(times_s, dtype=np.float64).reshape(-1)
        self.n_out = len(self.positions) * len(self.times)
        self.kernel = np.ones((1, 1)) if kernel is None else np.asarray(kernel, dtype=np.float64)
        if sigma is None:
            self.inv_sigma = None
        else:
            s = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (len(self.positions), len(self.times))).reshape(-1)
            if not (np.isfinite(s).all() and (s > 0).all()):
                raise FieldError("sigma", "the series' 1σ must be finite and > 0")
            self.inv_sigma = 1.0 / s
        self.scale = 1.0  # a constant factor on every row (invert_linear balances the solvers' steps with it)
        # the first call checks the fringe sampling (pixel_m against λz and the grid), later ones skip it
        self._checked = False

    def forward(self, x: Tensor) -> Tensor:
        x = self.flatten_input(x)
        batch = x.shape[:-1]
        m = x.reshape(-1, *self.in_shape)
        lin = None
        for lam, wi in zip(self.lams, self.w):
            f = -2.0 * float(wi) * aperture_field(m, self.pixel_m, float(lam), self.distance_m,
                                                  check_sampling=not self._checked, ground=self.ground).real
            lin = f if lin is None else lin + f
        self._checked = True
        out = record(smooth(lin + 1, self.kernel), self.pixel_m, self.positions, self.velocity, self.times) - 1
        out = out.reshape(*batch, self.n_out)
        if self.inv_sigma is not None:
            out = out * torch.as_tensor(self.inv_sigma, dtype=out.dtype, device=out.device)
        return out * self.scale if self.scale != 1.0 else out

    def adjoint(self, y: Tensor) -> Tensor:
        yb = y.reshape(-1, self.n_out)
        with torch.enable_grad():
            x0 = torch.zeros(yb.shape[0], self.n_in, dtype=yb.dtype, device=yb.device, requires_grad=True)
            (g,) = torch.autograd.grad(self.forward(x0), x0, yb)
        return g.reshape(*y.shape[:-1], self.n_in)

    def extra_repr(self) -> str:
        return (f"shape={self.in_shape}, pixel_m={self.pixel_m:g}, telescopes={len(self.positions)}, "
                f"exposures={len(self.times)}, wavelengths={len(self.lams)}")


def invert_linear(series: Any, sigma: Any, shape: Sequence[int], pixel_m: float, wavelength_m: Any, distance_m: float,
                  positions_m: Any, velocity_m_s: Any, times_s: Any, *, kernel: Any = None, weights: Any = None,
                  solver: Any = None, ground: Any = None) -> tuple[np.ndarray, dict[str, Any]]:
    """The silhouette ``(H, W)`` from the recorded ``series (J, K)`` by a linear solver on the
    linearised model (:class:`ShadowOperator`, rows weighted by ``1/sigma``): ``solver`` any
    cssat solver (``x, info = solver(problem, y)``: the ``solver`` config group's, e.g.
    ``cssat.recon.TV(lam=1e-2, method="pdhg", max_iter=500)``, ``L1()``, ``OMP()``, ``Landweber()``).
    The estimate is clipped to [0, 1]. Returns ``(mask, info)`` with the solver's info and
    ``chi2_per_sample`` of the linear model."""
    if solver is None or isinstance(solver, str) or not callable(solver):
        raise FieldError("solver", f"expected a solver object (x, info = solver(problem, y)), e.g. "
                                   f"cssat.recon.TV(lam=1e-2, method='pdhg', max_iter=500); got {solver!r}")
    y = np.asarray(series, dtype=np.float64)
    op = ShadowOperator(shape, pixel_m, wavelength_m, distance_m, positions_m, velocity_m_s, times_s, kernel=kernel,
                        weights=weights, sigma=sigma, ground=ground)
    if y.size != op.n_out:
        raise FieldError("series", f"expected {len(op.positions)} × {len(op.times)} samples, got shape {y.shape}")

    yw = torch.as_tensor((y.reshape(-1) - 1.0) * (1.0 if op.inv_sigma is None else op.inv_sigma), dtype=torch.float64)
    # weighted by 1/σ the operator's norm is ~1e4: scaled to ‖A‖² = 8, the norm of the image
    # gradient, so that primal–dual steps (1/√(‖A‖² + 8)) move the TV part too (the minimiser of
    # a relative weight is the same)
    c = math.sqrt(8.0 / operator_norm_sq(op, n_iter=30))
    op.scale = c
    x, info = solver(Problem(op, op.in_shape, noise_sigma=c), yw * c)
    op.scale = 1.0
    x = torch.as_tensor(np.asarray(x)).reshape(op.in_shape).to(torch.float64)
    r = op(x.reshape(1, -1))[0] - yw
    info = {k: v for k, v in info.items() if not isinstance(v, (Tensor, np.ndarray))}
    info["chi2_per_sample"] = float((r * r).mean())
    return np.clip(x.numpy(), 0.0, 1.0), info
