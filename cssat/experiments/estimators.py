"""How the solver gets its operator (the ``reference`` group): the truth, or an estimate from
reference satellites (paper §4: Eq. 22–30).

* :class:`Known` — Φ itself (Simulation 1; an oracle where Φ is an atmosphere's);
* :class:`Statistics` — only Φ's statistics: ``E[Φ]`` and the light curve's scatter;
* :class:`FullRank` — ``Φ̂ = Y_ref X_ref⁻¹`` from ``N_ref = N`` references (Eq. 24, Simulation 2);
* :class:`Sparse` — ``Φᵀ = ΨA``, ``A`` sparse, from ``N_ref < N`` references drawn from a pool
  in each of ``repeats`` draws (Eq. 26–30, Simulation 3), with the minimum-norm baseline beside it;
* :class:`MinNorm` — ``Φ̂ = Y_ref X_ref⁺`` from the same draws (the baseline as the estimate).

An estimate is an object with :meth:`~Known.memory` (the large arrays, checked before any work),
:meth:`~Known.prepare` (once: render and measure the references), :meth:`~Known.operator` (the
operator of repeat ``r`` and the repeat's metrics) and :meth:`~Known.baseline`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable

from cssat._checks import FieldError, bool_param, choice_param, dtype_param, float_param, int_param, opt
from cssat.experiments.context import Run, as_field
from cssat.experiments.refsets import reference_set
from cssat.experiments.resources import peak_rss_bytes

if TYPE_CHECKING:
    import torch

    from cssat.experiments.forward import Measured

__all__ = ["Known", "Statistics", "FullRank", "Sparse", "MinNorm", "T0_AUTO", "BASELINE_ALL_MAX"]


class Known:
    """The solver gets the true Φ (the paper's Simulation 1)."""

    name = "known"
    repeats = 1
    repeated = False  #: whether the run is a stack of repeats (sim3's metrics and arrays)

    def memory(self, n: int, m: int, itemsize: int) -> tuple[dict[str, int], int | None]:
        """The large arrays (bytes): ``Φ``, ``ΦΨ`` and the OMP's Gram ``ΨᵀΦᵀΦΨ``; no known peak."""
        N = n * n
        return {"Φ": m * N * itemsize, "ΦΨ": m * N * itemsize, "Gram": N * N * itemsize}, None

    def precision(self, run: Run) -> tuple[torch.dtype, torch.dtype | None]:
        """``(dtype of Φ and y, dtype Φ is drawn in)``."""
        return run.dtype, None

    def prepare(self, run: Run, measured: Measured) -> None:
        self._op = measured.measurement.operator

    def operator(self, run: Run, r: int) -> tuple[Any, dict[str, Any]]:
        return self._op, {}

    def baseline(self, run: Run, r: int, solve: Callable[[Any], Any]) -> dict[str, Any]:
        return {}

    def finish(self) -> None:
        """Release what :meth:`prepare` holds."""
        self._op = None

    def describe(self) -> dict[str, Any]:
        return {"reference": self.name}


class Statistics(Known):
    """Φ unknown, its statistics known: the solver gets ``E[Φ] = 𝟙φ̄ᵀ`` — the mean
    transmission of each pixel (the mean of Φ's rows; a long record gives it to ``O(m^−½)``) —
    and, as the noise it must fit to, the photon noise plus the atmosphere's own scatter of the
    light curve about ``φ̄ᵀx``, ``xᵀCx``, estimated from the data as ``var(y) − mean σ²``
    (clamped at 0). No centring: ``E[Φ]`` has rank 1. With independent samples the light curve
    holds only the flux and one more number (:func:`cssat.physics.information.statistics_fisher`),
    so any estimate is at best the flux's flat image: this is that bound, measured."""

    name = "statistics"
    center = False  #: E[Φ] has rank 1: nothing to centre

    def prepare(self, run: Run, measured: Measured) -> None:
        import torch  # heavy: torch (~1 s); the module imports without it

        from cssat.sparse import MatrixOperator  # heavy: cssat.sparse imports torch

        phi = measured.measurement.operator.matrix()
        self._op = MatrixOperator(phi.mean(0, keepdim=True).expand(phi.shape[0], -1).contiguous())
        y = measured.y.double()
        var = measured.noise_var
        if var is not None:
            var = torch.as_tensor(var, dtype=torch.float64)
            scatter = max(float(y.var()) - float(var.mean()), 0.0)  # the atmosphere's xᵀCx, from the data
            self.noise_var = var + scatter


class _References(Known):
    """Shared settings of the estimates from reference images: the reference ``model`` (a mesh),
    ``noise`` (white, a fraction of each image's maximum), ``seed`` (null: the run's + 1000),
    ``shadows`` and the on-disk ``cache_dir`` of rendered sets."""

    def __init__(self, model: Any, noise: float = 0.01, seed: int | None = None, shadows: bool = True,
                 cache_dir: str | None = None):
        self.model = model
        self.noise = float_param(noise, "noise", 0.0)
        self.seed = opt(seed, int_param, "seed", 0)
        self.shadows = bool_param(shadows, "shadows")
        self.cache_dir = None if not cache_dir else str(cache_dir)

    def ref_seed(self, run: Run) -> int:
        return run.seed + 1000 if self.seed is None else self.seed

    def render(self, run: Run, size: int, count: int) -> torch.Tensor:
        """``(count, size, size)`` float32 reference images (from the cache when there)."""
        with run.stage("references"):
            images, self.cached = reference_set(self.cache_dir, size, count, self.ref_seed(run), self.model,
                                                self.noise, self.shadows, run.progress)
        return images

    def describe(self) -> dict[str, Any]:
        return {"reference": self.name, "reference_noise": self.noise, "reference_cached": self.cached,
                "peak_rss_gb": peak_rss_bytes() / 2**30}


class FullRank(_References):
    """``Φ̂ = Y_ref X_ref⁻¹`` (Eq. 24) from ``n = N`` reference images (null: ``N``), their light
    curves ``Y_ref = noise(Φ X_ref)`` (Eq. 22, noise seeded with the run's seed + 2); one LU solve
    in ``dtype`` (float64: ``X_ref``'s rcond is ~1e-8), Φ drawn in float32 and held exactly."""

    name = "full_rank"

    def __init__(self, model: Any, n: int | None = None, noise: float = 0.01, seed: int | None = None,
                 shadows: bool = True, dtype: str = "float64", cache_dir: str | None = None):
        super().__init__(model, noise, seed, shadows, cache_dir)
        self.n = opt(n, int_param, "n", 1)
        self.dtype = dtype_param(dtype, "dtype")

    def n_ref(self, N: int) -> int:
        return N if self.n is None else int_param(self.n, "n", N, N)

    def memory(self, n: int, m: int, itemsize: int) -> tuple[dict[str, int], int | None]:
        """In the reference stage (``dtype``) these live together: ``Φ``, ``Y_ref``, ``X_ref`` and
        its LU factor, then ``Φ̂`` in place of ``X_ref``; in the reconstruction (the run's dtype)
        ``Φ̂Ψ`` and the OMP's Gram."""
        N, ref = n * n, torch_itemsize(self.dtype)
        self.n_ref(N)
        parts = {"Φ": m * N * ref, "Y_ref": m * N * ref, "X_ref": N * N * ref, "LU": N * N * ref}
        at_lu = sum(parts.values()) + N * N * 4  # + the float32 renders while X_ref is built
        at_solve = 3 * m * N * ref + N * N * ref
        later = m * N * ref + m * N * itemsize + N * N * itemsize
        return parts, max(at_lu, at_solve, later)

    def precision(self, run: Run) -> tuple[torch.dtype, torch.dtype | None]:
        import torch  # heavy: torch (~1 s); the module imports without it

        return self.dtype, torch.float32

    def prepare(self, run: Run, measured: Measured) -> None:
        import torch  # heavy: torch (~1 s); the module imports without it

        from cssat.reference import estimate_sensing_full_rank, relative_error  # heavy: cssat.reference imports torch

        n, N = measured.shape[0], math.prod(measured.shape)
        n_ref, meas = self.n_ref(N), measured.measurement
        refs = self.render(run, n, n_ref)
        with run.stage("reference_light_curves"):
            Xt = refs.reshape(n_ref, N).to(dtype=self.dtype, device=run.device)  # X_refᵀ: reference k is row k
            del refs
            phi = meas.matrix()
            Y_ref = _noisy(meas, phi @ Xt.T, measured.truth, torch.Generator().manual_seed(run.seed + 2))  # Eq. 22, (m, N_ref)
        with run.stage("estimate"), as_field("reference"):
            self._op, rcond = estimate_sensing_full_rank(Xt.T, Y_ref, return_rcond=True)  # Eq. 24
        del Xt, Y_ref
        self._metrics = {"phi_relative_error": relative_error(self._op, phi), "x_ref_rcond": rcond,
                         "reference_dtype": str(self.dtype).replace("torch.", ""), "reference_n": n_ref}

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), **self._metrics}


def torch_itemsize(dtype: torch.dtype) -> int:
    import torch  # heavy: torch (~1 s); the module imports without it

    return torch.finfo(dtype).bits // 8


#: ``n_nonzero_coefs: auto``: T₀ = round(200 · (64 / n)^1.5) — the paper-size default 200 at 64²,
#: 71 at 128². The estimate's Batch-OMP updates cost ``m · N · T₀² / 2`` value reads, ∝ n⁴ T₀²
#: with m ∝ N: this rule makes them grow only as n, what lets 9 repeats at 128² fit 30 minutes on
#: 2 cores. It is a compute budget, not a model choice (BENCHMARKS.md, the T₀ tables).
T0_AUTO = (200, 64, 1.5)

#: ``baseline: auto`` computes the minimum-norm baseline on every repeat while ``m · N`` is at most
#: this (64²: 3277 × 4096), else on the first repeat only (at 128² ~2 minutes a repeat)
BASELINE_ALL_MAX = 2**24


class Sparse(_References):
    """The rank-deficient estimate (Eq. 26–30): each of ``repeats`` draws takes ``n`` references
    (null: ``round(ratio · N)``) from a pool of ``pool`` (null: ``round(pool_ratio · N)``),
    rendered once; ``Y_ref`` (Eq. 22) and ``Φᵀ = ΨA`` with ``A`` sparse by batch-OMP (``T₀ =
    n_nonzero_coefs``: an integer, ``auto`` = :data:`T0_AUTO`'s rule, or null; ``ε₀ = epsilon``, a
    norm in the light curves' units), atoms selected on the normalised columns of ``D = X_refᵀΨ``
    (``normalize``). The solver gets ``Φ̂Ψ = Âᵀ`` (:class:`cssat.sparse.DictionarySensing`).
    ``baseline``: the minimum-norm ``Y_ref X_ref⁺`` reconstructed beside it — ``true`` (every
    repeat), ``first``, ``false`` or ``auto`` (every repeat up to ``m·N`` = :data:`BASELINE_ALL_MAX`)."""

    name = "sparse"
    repeated = True

    def __init__(self, model: Any, n: int | None = None, ratio: float | None = 0.8, pool: int | None = None,
                 pool_ratio: float | None = 1.953125, repeats: int = 9, n_nonzero_coefs: int | str | None = "auto",
                 epsilon: float | None = None, normalize: bool = True, baseline: bool | str = "auto",
                 noise: float = 0.01, seed: int | None = None, shadows: bool = True, cache_dir: str | None = None):
        super().__init__(model, noise, seed, shadows, cache_dir)
        self.n, self.pool = opt(n, int_param, "n", 1), opt(pool, int_param, "pool", 1)
        self.ratio = opt(ratio, float_param, "ratio", 0.0, 1.0, open_lo=True)
        self.pool_ratio = opt(pool_ratio, float_param, "pool_ratio", 0.0, open_lo=True)
        self.repeats = int_param(repeats, "repeats", 1, 1000)
        self.t0 = n_nonzero_coefs if n_nonzero_coefs in ("auto", None) else int_param(n_nonzero_coefs, "n_nonzero_coefs", 1)
        self.epsilon = opt(epsilon, float_param, "epsilon", 0.0)
        if self.t0 is None and self.epsilon is None:
            raise FieldError("n_nonzero_coefs", "give T0 (Eq. 28), auto, or reference.epsilon (Eq. 29)")
        self.normalize = bool_param(normalize, "normalize")
        self.baseline_mode = choice_param(baseline, "baseline", (True, False, "first", "auto"))

    def sizes(self, N: int) -> tuple[int, int]:
        """``(N_ref, pool)`` at ``N`` pixels."""
        pool = self.pool
        if pool is None:
            pool = max(1, round(float_param(self.pool_ratio, "pool_ratio", 0.0) * N))
        n_ref = self.n if self.n is not None else max(1, round(float_param(self.ratio, "ratio", 0.0, 1.0) * N))
        return int_param(n_ref, "n", 1, min(pool, N)), pool

    def settings(self, N: int) -> tuple[int | None, float | None]:
        """``(T₀, ε₀²)`` at ``N`` pixels."""
        t0 = self.t0
        if t0 == "auto":
            t0 = min(N, max(1, round(T0_AUTO[0] * (T0_AUTO[1] / math.sqrt(N)) ** T0_AUTO[2])))
        t0 = None if t0 is None else int_param(t0, "n_nonzero_coefs", 1, N)
        return t0, None if self.epsilon is None else self.epsilon ** 2

    def baseline_repeats(self, m: int, N: int) -> int:
        """How many repeats (the first ones) get the minimum-norm baseline."""
        mode = self.baseline_mode
        if mode == "auto":
            return self.repeats if m * N <= BASELINE_ALL_MAX else 1
        return {True: self.repeats, False: 0, "first": 1}[mode]

    def memory(self, n: int, m: int, itemsize: int) -> tuple[dict[str, int], int | None]:
        """The pool (float32) and, when formed once, its light curves ``(m, pool)``; ``Φ``,
        ``Y_ref``, ``D = X_refᵀΨ``, the OMP's Gram ``(N, N)``, and the coefficients ``Âᵀ``, ``Φ̂``
        and the baseline's (each ``m × N``)."""
        N = n * n
        n_ref, pool = self.sizes(N)
        self.settings(N)
        shared = m * pool * itemsize if _share_light_curves(pool, n_ref, self.repeats) else 0
        return {"pool": pool * N * 4, "pool light curves": shared, "Φ": m * N * itemsize, "Y_ref": m * n_ref * itemsize,
                "D": 2 * n_ref * N * itemsize, "Gram": N * N * itemsize, "coefficients": 4 * m * N * itemsize}, None

    def prepare(self, run: Run, measured: Measured) -> None:
        self._meas, self._shape, self._truth = measured.measurement, measured.shape, measured.truth
        n, N = measured.shape[0], math.prod(measured.shape)
        self.n_ref, self.pool_n = self.sizes(N)
        self.estimate = self.settings(N)
        self.n_baseline = self.baseline_repeats(measured.measurement.shape[0], N)
        self._flat = self.render(run, n, self.pool_n).reshape(self.pool_n, N)
        with run.stage("reference_light_curves"):
            share = _share_light_curves(self.pool_n, self.n_ref, self.repeats)
            self._light = _pool_light_curves(self._meas.matrix(), self._flat) if share else None
        self._progress = run.progress

    def _draw(self, run: Run, r: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Repeat ``r``'s ``X_refᵀ (N_ref, N)`` and ``Y_ref (m, N_ref)`` (Eq. 22)."""
        import torch  # heavy: torch (~1 s); the module imports without it

        base = self.ref_seed(run) * 1_000_003 + r
        idx = torch.randperm(self.pool_n, generator=torch.Generator().manual_seed(base))[:self.n_ref]
        Xt = self._flat[idx].to(dtype=run.dtype, device=run.device)
        with run.stage("reference_light_curves"):
            clean = self._light[:, idx.to(self._light.device)] if self._light is not None else self._meas.matrix() @ Xt.T
            Y_ref = _noisy(self._meas, clean, self._truth, torch.Generator().manual_seed(base + 1))
        return Xt, Y_ref

    def operator(self, run: Run, r: int) -> tuple[Any, dict[str, Any]]:
        from cssat.reference import estimate_sensing_sparse, relative_error  # heavy: cssat.reference imports torch
        from cssat.sparse import DictionarySensing  # heavy: cssat.sparse imports torch

        self._Xt, self._Y = self._draw(run, r)
        with run.stage("estimate"), as_field("reference"):
            phi_dense, info = estimate_sensing_sparse(
                self._Xt.T, self._Y, n_nonzero_coefs=self.estimate[0], tol=self.estimate[1], shape=self._shape,
                normalize=self.normalize, return_info=True, progress=self._progress)
            row = {"phi_relative_error": relative_error(phi_dense, self._meas.matrix()),
                   "estimate_mean_atoms": float(info.n_iter.double().mean())}
        del phi_dense
        return DictionarySensing(info.coefficients, self._shape), row  # Φ̂Ψ = Âᵀ

    def baseline(self, run: Run, r: int, solve: Callable[[Any], Any]) -> dict[str, Any]:
        """The minimum-norm estimate of repeat ``r`` and the PSNR of its reconstruction by
        ``solve`` (while ``r`` < the baseline's repeats)."""
        from cssat.reference import estimate_sensing_min_norm, relative_error  # heavy: cssat.reference imports torch

        Xt, Y, self._Xt, self._Y = self._Xt, self._Y, None, None
        if r >= self.n_baseline:
            return {}
        with run.stage("baseline"):
            phi_mn = estimate_sensing_min_norm(Xt.T, Y)
            return {"phi_relative_error_min_norm": relative_error(phi_mn, self._meas.matrix()),
                    "psnr_min_norm": solve(phi_mn)}

    def finish(self) -> None:
        self._meas = self._flat = self._light = None

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "reference_n": self.n_ref, "reference_pool": self.pool_n, "repeats": self.repeats,
                "baseline_repeats": self.n_baseline, "reference_n_nonzero_coefs": self.estimate[0],
                "reference_tol": self.estimate[1]}


class MinNorm(Sparse):
    """The minimum-norm estimate ``Φ̂ = Y_ref X_ref⁺`` from the draws of :class:`Sparse` (no
    sparse model; the solver gets Φ̂ itself). Takes :class:`Sparse`'s settings; T₀ and ε₀ unused."""

    name = "min_norm"

    def __init__(self, model: Any, **kwargs: Any):
        kwargs.setdefault("baseline", False)
        super().__init__(model, **kwargs)

    def operator(self, run: Run, r: int) -> tuple[Any, dict[str, Any]]:
        from cssat.reference import estimate_sensing_min_norm, relative_error  # heavy: cssat.reference imports torch

        Xt, Y = self._draw(run, r)
        with run.stage("estimate"), as_field("reference"):
            phi_mn = estimate_sensing_min_norm(Xt.T, Y)
        return phi_mn, {"phi_relative_error": relative_error(phi_mn, self._meas.matrix())}

    def baseline(self, run: Run, r: int, solve: Callable[[Any], Any]) -> dict[str, Any]:
        return {}


def _noisy(meas: Any, clean: torch.Tensor, truth: Any, generator: torch.Generator) -> torch.Tensor:
    """``Y_ref (m, N_ref)`` with the measurement's noise: each reference's light curve (a column
    of ``clean``) noised as one light curve, on the target's photometric scale (the flux ``Σ x``
    of the target carries the noise model's magnitude: the references are observed in the same
    units and conditions; a dark reference gets sky and read noise only)."""
    import torch  # heavy: torch (~1 s); the module imports without it

    flux = torch.full((clean.shape[1],), float(truth.sum()), dtype=torch.float64)
    return meas.add_noise(clean.T, generator, flux=flux).T


def _share_light_curves(pool: int, n_ref: int, repeats: int) -> bool:
    """Whether to form the light curves ``Φ x`` of the whole pool once (``m × pool`` values)
    rather than ``Φ X_ref`` in every repeat: when the repeats draw more images in all than the
    pool holds (9 × 3277 > 8000; at 128², 9 × 13107 > 32000 saves ~110 s)."""
    return repeats * n_ref > pool


def _pool_light_curves(phi, flat, block: int = 4096):
    """``Φ x`` for every image of the pool ``flat (pool, N)``: ``(m, pool)``, in blocks of
    images: each column is the product of Φ with that image, so a repeat's columns are
    ``Φ X_ref`` (to round-off; bit for bit with this project's BLAS — BENCHMARKS.md)."""
    import torch  # heavy: torch (~1 s); the module imports without it

    out = torch.empty(phi.shape[0], flat.shape[0], dtype=phi.dtype, device=phi.device)
    for s in range(0, flat.shape[0], block):
        out[:, s : s + block] = phi @ flat[s : s + block].to(dtype=phi.dtype, device=phi.device).T
    return out
