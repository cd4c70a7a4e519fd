"""Reconstruction solvers: an image from its light curve ``y = Φx`` (paper Eq. 5, 6 and beyond).

Every solver is an object with one call signature::

    x, info = solver(problem, y)

``problem`` is a :class:`~cssat.recon.Problem` — the sensing operator ``Φ (m, N)``, the
unknown's shape ``(H, W)`` with ``H W = N`` and the noise level — or what
:meth:`Problem.of` turns into one: a :class:`cssat.physics.Measurement` as it is, an operator or
a dense ``(m, N)`` tensor with ``shape=(H, W)`` (``solver(phi, y, shape)`` as before). ``y`` is
the light curve ``(m,)`` or a batch ``(B, m)``. ``x`` is the reconstruction ``shape`` or ``(B, *shape)``,
*not* clipped to the image range, in ``y``'s dtype and on its device; ``info`` is a flat dict for
``metrics.json`` (tensors in it, such as OMP's ``coefficients``, are arrays to save).
``validate(m, N)`` checks the settings that depend on the problem size before any work.
Settings are checked when the object is built. Every solver takes ``progress`` (keyword): a tqdm
bar of its iterations — ``None`` (default) on a terminal only, ``True`` always, ``False`` never. Build them from the ``solver`` config group
(``_target_``) or directly; a class of your own with the same call works everywhere these do.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param, opt, progress_param
from cssat.recon.denoisers import Denoiser
from cssat.recon.problem import Problem
from cssat.sparse import DCT, batch_omp, sensing_dictionary
from cssat.sparse._io import numpy_io
from cssat.sparse.solvers import SolverInfo, fista_l1, landweber, pnp_pgd, tv_pdhg
from cssat.sparse.tv_admm import ADMM_MAX_PIXELS, flat_fit, inverse_variance, tv_admm, tv_discrepancy

if TYPE_CHECKING:
    from cssat._types import Array, ProblemLike
    from cssat.sparse import LinearOperator

__all__ = ["Solver", "OMP", "L1", "TV", "FluxOnly", "PnP", "Landweber", "default_sparsity", "tv_default_lam"]


class Solver:
    """Base class of the reconstruction solvers."""

    name = "solver"
    #: the unknowns the solver takes: "any" (a vector of any shape) or "image" (an (H, W) grid: TV, PnP)
    unknown = "any"

    def validate(self, m: int, n_pixels: int) -> None:
        """Check the size-dependent settings for ``m`` samples of ``n_pixels`` pixels."""


    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:  # pragma: no cover
        raise NotImplementedError


def _problem(problem: Any, y: Tensor, shape: Sequence[int] | None) -> tuple[LinearOperator, int, int, tuple[int, ...]]:
    """``(operator, m, N, shape)`` of the problem, ``y`` checked against it."""
    prob = Problem.of(problem, shape)
    prob.check(y)
    return prob.operator, prob.m, prob.n, prob.x_shape


def default_sparsity(m: int, n_pixels: int) -> int:
    """The default ``K`` of Eq. 5 for ``m`` Gaussian measurements of ``N = n_pixels`` pixels:
    ``K = m (0.05 + 0.25 (m/N)²)``.

    A fixed ``K/m`` is wrong at both ends: with few measurements OMP over-fits (best near
    ``K/m = 0.05``), with ``m`` near ``N`` it under-fits (``K/m ≥ 0.25``). The rule follows the
    best ``K`` of a sweep on the 128² camera image at m = 1444, 4096, 13225 (BENCHMARKS.md).
    """
    r = m / n_pixels
    return max(1, round(m * (0.05 + 0.25 * r * r)))


class OMP(Solver):
    """Batch-OMP over the CS dictionary ``ΦΨ`` with a 2-D DCT Ψ (paper Eq. 5 / Eq. 6).

    ``epsilon`` (ε, a norm in ``y``'s units) gives the error-constrained Eq. 6,
    ``‖y − ΦΨγ‖₂ ≤ ε``, with ``n_nonzero_coefs`` as a cap (default ``m``); otherwise Eq. 5 with
    ``K = n_nonzero_coefs``, or ``round(k_ratio · m)``, or :func:`default_sparsity` when both are
    null. ``x̂ = Ψγ̂``. ``ΦΨ`` is formed by a fast DCT of Φ's rows
    (:func:`cssat.sparse.sensing_dictionary`), or taken as it is from a
    :class:`cssat.sparse.DictionarySensing`.
    """

    name = "omp"

    def __init__(self, n_nonzero_coefs: int | None = None, k_ratio: float | None = None, epsilon: float | None = None,
                 *, progress: bool | None = None):
        self.progress = progress_param(progress)
        self.n_nonzero_coefs = opt(n_nonzero_coefs, int_param, "n_nonzero_coefs", 1)
        self.k_ratio = opt(k_ratio, float_param, "k_ratio", 0.0, 1.0, open_lo=True)
        self.discrepancy = epsilon == "discrepancy"  # ε² = Σ σᵢ², the problem's noise (Eq. 6 at the noise level)
        if isinstance(epsilon, str) and not self.discrepancy:
            raise FieldError("epsilon", f"expected a number >= 0, null or 'discrepancy', got {epsilon!r}")
        self.epsilon = None if self.discrepancy else opt(epsilon, float_param, "epsilon", 0.0)

    def settings(self, m: int, n_pixels: int) -> tuple[int, float | None]:
        """``(K, tol)`` for :func:`cssat.sparse.batch_omp` (``tol = ε²``, a squared norm)."""
        k = self.n_nonzero_coefs
        if self.epsilon is not None:
            return (m if k is None else int_param(k, "n_nonzero_coefs", 1, m)), self.epsilon ** 2
        if k is None:
            k = default_sparsity(m, n_pixels) if self.k_ratio is None else max(1, round(self.k_ratio * m))
        return int_param(k, "n_nonzero_coefs", 1, m), None

    def validate(self, m: int, n_pixels: int) -> None:
        self.settings(m, n_pixels)

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        prob = Problem.of(problem, shape)
        prob.check(y)
        phi, m, N, shape = prob.operator, prob.m, prob.n, prob.x_shape
        K, tol = self.settings(m, N)
        if self.discrepancy:
            K, tol = (m if self.n_nonzero_coefs is None else int_param(self.n_nonzero_coefs, "n_nonzero_coefs", 1, m),
                      float(prob.variance().sum()))
        t = time.perf_counter()
        D = sensing_dictionary(phi, shape)
        t_dict = time.perf_counter() - t
        gamma, info = batch_omp(D, y.to(D.dtype), n_nonzero_coefs=K, tol=tol, return_info=True, progress=self.progress)
        del D
        x = DCT(shape)(gamma).reshape(*y.shape[:-1], *shape)
        res = info.residual_sq.double().sqrt().reshape(-1) / y.double().reshape(-1, m).norm(dim=1).clamp_min(1e-300)
        return x, {
            "solver_n_nonzero_coefs": K,
            "solver_tol": tol,
            "solver_epsilon": "discrepancy" if self.discrepancy else self.epsilon,
            "omp_atoms": int(info.n_iter.max()),
            "omp_path": info.path,
            "relative_residual": float(res.max()),
            "seconds_dictionary": t_dict,
            "coefficients": gamma,
        }

    def __repr__(self):
        return f"OMP(n_nonzero_coefs={self.n_nonzero_coefs}, k_ratio={self.k_ratio}, epsilon={self.epsilon})"


class _Convex(Solver):
    def __init__(self, lam: float | None, max_iter: int, rtol: float, progress: bool | None = None):
        self.progress = progress_param(progress)
        self.lam = opt(lam, float_param, "lam", 0.0)
        self.max_iter = int_param(max_iter, "max_iter", 1)
        self.rtol = float_param(rtol, "rtol", 0.0)

    def _info(self, lam: float, sinfo) -> dict[str, Any]:
        return {
            "solver_lam": lam, "solver_lam_abs": float(sinfo.lam[0]), "solver_max_iter": self.max_iter,
            "solver_rtol": self.rtol, "solver_iterations": sinfo.n_iter, "solver_converged": sinfo.converged,
            "solver_objective": sinfo.objective[-1] if sinfo.objective else None,
        }


class L1(_Convex):
    """ℓ1 in the DCT by FISTA (Beck & Teboulle 2009): ``min ½‖ΦΨγ − y‖² + λ‖γ‖₁``, ``x̂ = Ψγ̂``.

    ``lam`` is relative: ``λ = lam · ‖(ΦΨ)ᵀy‖∞`` (the solution is zero for ``lam ≥ 1``).
    Stops when the relative change of γ falls below ``rtol`` or after ``max_iter`` iterations.
    """

    name = "l1"

    def __init__(self, lam: float = 1e-3, max_iter: int = 1000, rtol: float = 1e-5, *, progress: bool | None = None):
        super().__init__(lam if lam is not None else 1e-3, max_iter, rtol, progress)

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        phi, m, N, shape = _problem(problem, y, shape)
        t = time.perf_counter()
        A = sensing_dictionary(phi, shape)
        t_dict = time.perf_counter() - t
        gamma, sinfo = fista_l1(A, y.to(A.dtype), lam=self.lam, max_iter=self.max_iter, rtol=self.rtol, return_info=True,
                                progress=self.progress)
        del A
        x = DCT(shape)(gamma).reshape(*y.shape[:-1], *shape)
        return x, {**self._info(self.lam, sinfo), "seconds_dictionary": t_dict, "coefficients": gamma}


def tv_default_lam(ratio: float) -> float:
    """The default relative TV weight at the measurement ratio ``m/N``: ``0.01 (1 − m/N)²``.

    Few measurements need a strong prior, many a faithful fit: on the 128² TESS-like target a fixed
    ``1e-2`` gives 31.1 / 41.2 / 45.1 dB at m = 1444 / 4096 / 13225 and ``1e-3`` gives
    20.6 / 30.7 / 63.6 dB (BENCHMARKS.md).
    """
    return 0.01 * (1.0 - min(max(ratio, 0.0), 1.0)) ** 2


class TV(_Convex):
    """Isotropic total variation on the image: ``min ½‖Φx − y‖² + λ TV(x)``, ``x ≥ 0`` when
    ``nonneg``.

    ``lam`` relative to ``‖Φᵀy‖∞`` (on a centred system's fluctuation rows); ``None``:
    :func:`tv_default_lam` at ``m/N``; ``"discrepancy"``: the largest weight whose solution fits
    the data to the problem's noise, the flat image of the total flux when that already does
    (:func:`cssat.sparse.tv_admm.tv_discrepancy`: a TV estimate that never does worse than the
    flux for lack of regularisation). ``method``: ``pdhg`` (Chambolle–Pock, any operator),
    ``admm`` (an exact ``N × N`` solve: converges where the operator's spectrum is spread over
    decades, as on a centred positive Φ; ``N ≤ 8192``), ``auto`` (``admm`` for a centred system
    or the discrepancy rule where ``N`` allows, else ``pdhg``).
    """

    name = "tv"
    unknown = "image"

    def __init__(self, lam: float | str | None = None, nonneg: bool = True, max_iter: int = 2000, rtol: float = 1e-5,
                 method: str = "auto", *, progress: bool | None = None):
        self.discrepancy = lam == "discrepancy"
        if isinstance(lam, str) and not self.discrepancy:
            raise FieldError("lam", f"expected a number >= 0, null or 'discrepancy', got {lam!r}")
        super().__init__(None if self.discrepancy else lam, max_iter, rtol, progress)
        self.nonneg = bool_param(nonneg, "nonneg")
        self.method = choice_param(method, "method", ("auto", "pdhg", "admm"))

    def _method(self, phi: LinearOperator, N: int) -> str:
        if self.method != "auto":
            return self.method
        wants = self.discrepancy or getattr(phi, "scale_rows", None) is not None
        return "admm" if wants and N <= ADMM_MAX_PIXELS else "pdhg"

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        prob = Problem.of(problem, shape)
        prob.check(y)
        phi, m, N, shape = prob.operator, prob.m, prob.n, prob.x_shape
        method = self._method(phi, N)
        if self.discrepancy:
            if method != "admm":
                raise FieldError("method", f"lam: discrepancy solves TV at many weights: it needs method admm (N ≤ 8192), got {method}")
            var = prob.variance().to(y)
            rows = [tv_discrepancy(phi, yb, shape, var, nonneg=self.nonneg, max_iter=self.max_iter, rtol=self.rtol,
                                   progress=self.progress) for yb in y.reshape(-1, m)]
            x = torch.stack([r[0] for r in rows]).reshape(*y.shape[:-1], *shape)
            info = {k: v for k, v in rows[-1][1].items()}
            info.update(solver_lam_rule="discrepancy", solver_method=method, solver_max_iter=self.max_iter, solver_rtol=self.rtol)
            return x, info
        lam = self.lam if self.lam is not None else tv_default_lam(m / N)
        if method == "admm":
            x, run, alg = tv_admm(phi, y.reshape(-1, m), shape, lam=lam, nonneg=self.nonneg, max_iter=self.max_iter,
                                  rtol=self.rtol, progress=self.progress)
            sinfo = SolverInfo(run.n_iter, run.objective, run.converged, alg.lam_abs, alg.rho)
            x = x.reshape(*y.shape[:-1], *shape)
        else:
            x, sinfo = tv_pdhg(phi, y, shape, lam=lam, nonneg=self.nonneg, max_iter=self.max_iter, rtol=self.rtol,
                               return_info=True, progress=self.progress)
        return x, {**self._info(lam, sinfo), "solver_method": method}


class FluxOnly(Solver):
    """The estimate that knows only the total flux: the constant image ``α𝟙`` that fits ``y`` best
    in least squares, weighted by the problem's noise variances when it has them
    (:func:`cssat.sparse.tv_admm.flat_fit`), ``α ≥ 0``. The baseline every image estimate must
    beat: what the light curve gives when it carries the flux and nothing else."""

    name = "flux"

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        prob = Problem.of(problem, shape)
        prob.check(y)
        w = None
        if prob.noise_var is not None or prob.noise_sigma is not None:
            w = inverse_variance(prob.variance().to(y))
        x = flat_fit(prob.operator, y.reshape(-1, prob.m), w)
        return x.reshape(*y.shape[:-1], *prob.x_shape), {"solver_flux": float(x[-1].sum())}

    def __repr__(self) -> str:
        return "FluxOnly()"


class PnP(Solver):
    """Plug-and-play proximal gradient (Venkatakrishnan et al. 2013):
    ``x ← D(x − Φᵀ(Φx − y)/L, σₖ)`` with any :class:`~cssat.recon.Denoiser` ``D`` and a geometric
    σ schedule from ``sigma_start`` to ``sigma_end`` (image units; the targets are in [0, 1]), one
    iteration per σ. ``init: tv`` starts from a TV solution (λ = 1e-3, 300 iterations).
    BM3D is not offered: its licence is non-commercial.
    """

    name = "pnp"
    unknown = "image"

    def __init__(self, denoiser: Denoiser, max_iter: int = 30, sigma_start: float = 0.1, sigma_end: float = 0.005,
                 init: str = "zero", *, progress: bool | None = None):
        self.progress = progress_param(progress)
        if not callable(denoiser):
            raise FieldError("denoiser", f"expected a denoiser object (image, sigma) -> (image, info), got {denoiser!r}")
        self.denoiser = denoiser
        self.max_iter = int_param(max_iter, "max_iter", 1)
        self.sigma_start = float_param(sigma_start, "sigma_start", 1e-6)
        self.sigma_end = float_param(sigma_end, "sigma_end", 1e-6)
        self.init = choice_param(init, "init", ("zero", "tv"))

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        phi, m, N, shape = _problem(problem, y, shape)
        x0 = tv_pdhg(phi, y, shape, lam=1e-3, max_iter=300, progress=self.progress) if self.init == "tv" else None
        sig = np.geomspace(self.sigma_start, self.sigma_end, self.max_iter)
        x, sinfo = pnp_pgd(phi, y, shape, lambda img, s: self.denoiser(img, s)[0], sigmas=sig, x0=x0, return_info=True,
                           progress=self.progress)
        return x, {
            "solver_denoiser": getattr(self.denoiser, "name", type(self.denoiser).__name__),
            "solver_iterations": sinfo.n_iter,
            "solver_sigma_start": float(sinfo.lam[0]), "solver_sigma_end": float(sinfo.lam[-1]),
            "solver_objective": sinfo.objective[-1],
        }


class Landweber(_Convex):
    """Projected Landweber (:func:`cssat.sparse.solvers.landweber`):
    ``xₖ₊₁ = P(xₖ − τ Φᵀ(Φxₖ − y))``, ``τ = relaxation / ‖Φ‖²``, ``P`` the projection on
    ``x ≥ 0`` when ``nonneg``. Regularised by stopping: ``max_iter`` or the relative change ``rtol``.
    """

    name = "landweber"

    def __init__(self, relaxation: float = 1.0, nonneg: bool = True, max_iter: int = 500, rtol: float = 1e-6,
                 *, progress: bool | None = None):
        super().__init__(None, max_iter, rtol, progress)
        self.relaxation = float_param(relaxation, "relaxation", 0.0, 2.0, open_lo=True)
        self.nonneg = bool_param(nonneg, "nonneg")

    @numpy_io
    def __call__(self, problem: ProblemLike, y: Array, shape: Sequence[int] | None = None) -> tuple[Array, dict[str, Any]]:
        phi, m, N, shape = _problem(problem, y, shape)
        x, sinfo = landweber(phi, y, relaxation=self.relaxation, lower=0.0 if self.nonneg else None,
                             max_iter=self.max_iter, rtol=self.rtol, return_info=True, progress=self.progress)
        return x.reshape(*y.shape[:-1], *shape), {
            "solver_relaxation": self.relaxation, "solver_max_iter": self.max_iter, "solver_rtol": self.rtol,
            "solver_iterations": sinfo.n_iter, "solver_converged": sinfo.converged,
            "solver_objective": sinfo.objective[-1] if sinfo.objective else None,
        }
