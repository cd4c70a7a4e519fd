"""One measurement model: ``y = noise(Φ x)`` (paper Eq. 15 with sensor noise)."""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor, nn

from cssat._checks import FieldError, FieldTypeError
from cssat.physics.noise import NoiseModel, NoNoise
from cssat.sparse._io import numpy_io
from cssat.sparse.operators import LinearOperator, MatrixOperator

__all__ = ["Measurement", "centered", "Centered"]


class Measurement(nn.Module):
    """A light-curve measurement: a sensing operator ``Φ (m, N)`` followed by a noise model.

    In deepinv's ``LinearPhysics`` shape: :meth:`A` is the noiseless ``Φx``, :meth:`A_adjoint`
    its transpose ``Φᵀy``, :meth:`A_dagger` the least-squares ``Φ⁺y``, and
    ``forward(x) = noise(A(x))``. Batch-first: ``x (B, N)``, ``(N,)``, or images
    ``(B, C, H, W)``, ``(B, H, W)``, ``(H, W)`` with ``C H W = N``; ``y (B, m)`` or ``(m,)``.
    Everything follows the input's device and dtype.

    The noise is seeded: ``forward(x)`` draws it from a generator seeded with ``seed``
    (the same ``x`` and seed give the same ``y`` on every call); pass ``generator`` to draw
    from a stream of your own instead. With ``resample=True`` every call draws fresh noise
    (what training on noisy measurements needs, as deepinv's physics do): call ``k`` of the
    measurement uses a generator seeded with ``(seed, k)``, so a run is still reproducible —
    the same sequence of calls gives the same sequence of ``y`` — and :meth:`reset` starts the
    sequence again.

    Parameters
    ----------
    operator : LinearOperator or (m, N) tensor
        The sensing matrix (e.g. from :meth:`cssat.physics.Atmosphere.operator`).
    noise : NoiseModel, optional
        Default: :class:`~cssat.physics.NoNoise`.
    seed : int
        Seed of the noise.
    x_shape : sequence of int, optional
        The unknown's shape (an image ``(H, W)``), so that a solver takes the measurement as its
        problem: ``solver(measurement, y)``. Default: the operator's ``in_shape``.
    resample : bool
        Fresh noise on every call (default ``False``: the same noise every call).
    """

    def __init__(self, operator: LinearOperator | Tensor, noise: NoiseModel | None = None, seed: int = 0, *,
                 x_shape: Sequence[int] | None = None, resample: bool = False):
        super().__init__()
        if isinstance(operator, Tensor):
            operator = MatrixOperator(operator)
        if not isinstance(operator, LinearOperator):
            raise FieldTypeError("operator", f"expected a LinearOperator or a 2-D tensor, got {type(operator).__name__}")
        self.operator = operator
        self.noise = noise if noise is not None else NoNoise()
        self.seed = int(seed)
        self.x_shape = tuple(int(v) for v in x_shape) if x_shape is not None else operator.in_shape
        if not isinstance(resample, bool):
            raise FieldError("resample", f"expected true or false, got {resample!r}")
        self.resample, self.calls = resample, 0

    def reset(self) -> None:
        """Start the sequence of fresh noise draws (``resample=True``) again from call 0."""
        self.calls = 0

    @property
    def shape(self) -> tuple[int, int]:
        """``(m, N)``."""
        return self.operator.shape

    def _flat(self, x: Tensor) -> Tensor:
        return self.operator.flatten_input(x)

    @numpy_io
    def A(self, x: Tensor) -> Tensor:
        """The noiseless light curve ``Φx``: ``(B, m)`` or ``(m,)``."""
        return self.operator(self._flat(x))

    @numpy_io
    def A_adjoint(self, y: Tensor) -> Tensor:
        """``Φᵀy``: ``(B, N)`` or ``(N,)``."""
        return self.operator.adjoint(y)

    @numpy_io
    def A_dagger(self, y: Tensor) -> Tensor:
        """The minimum-norm least-squares ``Φ⁺y`` (:meth:`LinearOperator.A_dagger`)."""
        return self.operator.A_dagger(y)

    @numpy_io
    def forward(self, x: Tensor, generator: torch.Generator | None = None) -> Tensor:
        """The measured light curve ``noise(Φx)``; refuses a non-finite result."""
        y = self.add_noise(self.A(x), generator, flux=self._flat(x).sum(-1))
        if not bool(torch.isfinite(y).all()):
            raise FieldError("y", "the light curve contains NaN or Inf")
        return y

    def add_noise(self, y: Tensor, generator: torch.Generator | None = None, *, flux: Tensor | None = None) -> Tensor:
        """``noise(y)`` with the measurement's seeded generator (or ``generator``); ``y`` itself
        when the model is :class:`~cssat.physics.NoNoise`. ``flux``: the scene's atmosphere-free
        flux per light curve (the photometric model's scale)."""
        if isinstance(self.noise, NoNoise):
            return y
        if generator is None:
            generator = torch.Generator(device="cpu").manual_seed(self._call_seed())
        return self.noise(y, generator, flux=flux)

    def _call_seed(self) -> int:
        """``seed``, or with ``resample`` a seed of ``(seed, call number)`` (numpy's SeedSequence)."""
        if not self.resample:
            return self.seed

        k, self.calls = self.calls, self.calls + 1
        return int(np.random.SeedSequence([self.seed & (2**63 - 1), k]).generate_state(1, dtype=np.uint64)[0] >> 1)

    @numpy_io
    def frames(self, x_t: Tensor, generator: torch.Generator | None = None) -> Tensor:
        """The light curve of a changing scene: ``y_t = Σⱼ Φ[t, j] x_t[j]`` (Eq. 11, 12).

        ``x_t (m, N)`` (or ``(m, H, W)``): the scene at sample ``t`` — facet fluxes or rendered
        images. Returns ``(m,)``, noise added.
        """
        flat = self._flat(x_t)
        if flat.ndim != 2 or flat.shape[0] != self.operator.n_out:
            raise FieldError("x_t", f"expected {self.operator.n_out} frames, got shape {tuple(x_t.shape)}")
        w = self.operator.matrix(dtype=flat.dtype, device=flat.device)
        y = self.add_noise((w * flat).sum(-1), generator, flux=flat.sum(-1).mean())
        if not bool(torch.isfinite(y).all()):
            raise FieldError("x_t", "the light curve contains NaN or Inf")
        return y

    def matrix(self) -> Tensor:
        """The dense sensing matrix ``Φ (m, N)``."""
        return self.operator.matrix()

    def describe(self) -> dict[str, Any]:
        """Flat settings of the noise model for ``metrics.json``."""
        return self.noise.describe()

    def extra_repr(self) -> str:
        m, n = self.shape
        return f"m={m}, N={n}, noise={self.noise!r}, seed={self.seed}" + (", resample=True" if self.resample else "")


def centered(phi: Tensor, y: Tensor, *, flux_weight: float | None = None) -> tuple[Tensor, Tensor]:
    """The system ``y = Φx`` rewritten around its common term, for a mean-1 (positive) ``Φ``.

    With ``φ̄`` the mean row of ``Φ (m, N)``, ``ȳ`` the mean of ``y (m,)`` or ``(B, m)`` and
    ``s`` the rms of the fluctuations ``Φ − 𝟙φ̄ᵀ``:

        ``[(Φ − 𝟙φ̄ᵀ)/s ; c φ̄ᵀ] x = [(y − ȳ𝟙)/s ; c ȳ]``,   ``c = w √N / ‖φ̄‖``

    — the fluctuations of the atmosphere, which alone depend on where the light comes from,
    scaled to unit rms like the paper's Gaussian rows, and one row for the total (weighted) flux
    with the norm of an average row times ``w = flux_weight`` (default 1). Why: with 1 %
    fluctuations the common term holds 99.99 % of ``‖y‖²``, so every scale-relative setting of the
    solvers (ℓ1/TV's λ relative to ‖Aᵀy‖∞, OMP's round-off floor) would see only the flux, and a
    float32 Φ keeps only ~5 digits of the part that depends on the image. This is a re-weighting,
    not an isometry: the total flux counts as one sample. Formed in float64; returns
    ``(A (m + 1, N), b)`` in float64.
    """
    A, rhs = _centering(phi, flux_weight)
    return A, rhs(y)


def _centering(phi: Tensor, flux_weight: float | None):
    """``(A, y ↦ b)`` of :func:`centered`, in float64."""
    p = phi.double()
    N = p.shape[1]
    mean_row = p.mean(0, keepdim=True)
    fluct = p - mean_row
    s = float(fluct.pow(2).mean().sqrt())
    if not s > 0:
        raise FieldError("phi", "its rows are all equal (rank 1): only the total flux is measured")
    c = (1.0 if flux_weight is None else float(flux_weight)) * math.sqrt(N) / float(mean_row.norm())
    A = torch.cat([fluct / s, c * mean_row])

    def rhs(y: Tensor) -> Tensor:
        yy = y.double()
        ybar = yy.mean(-1, keepdim=True)
        return torch.cat([(yy - ybar) / s, c * ybar], -1)

    rhs.s, rhs.c = s, c
    return A, rhs


class Centered(MatrixOperator):
    """The operator of :func:`centered`: ``A = [(Φ − 𝟙φ̄ᵀ)/s ; c φ̄ᵀ] (m + 1, N)`` as a
    :class:`~cssat.sparse.MatrixOperator` in ``dtype`` (default ``Φ``'s), formed in float64;
    :meth:`data` maps a light curve ``y`` of ``Φ`` to the right-hand side ``b`` of ``A``. A wrapper
    of the operator: a solver takes ``Problem(Centered(Φ), shape)`` and ``data(y)`` like any other."""

    def __init__(self, phi: LinearOperator | Tensor, *, flux_weight: float | None = None, dtype: torch.dtype | None = None):
        mat = phi.matrix() if isinstance(phi, LinearOperator) else phi
        A, self._ybar = _centering(mat, flux_weight)
        super().__init__(A.to(dtype or mat.dtype))
        self._s, self._c = self._ybar.s, self._ybar.c
        #: the fluctuation rows: relative weights (λ = lam ‖Aᵀb‖∞) are measured on them, not on the flux row
        self.scale_rows = slice(0, mat.shape[0])

    def data(self, y: Tensor, dtype: torch.dtype | None = None) -> Tensor:
        """``b = [(y − ȳ𝟙)/s ; c ȳ]`` for ``y (m,)`` or ``(B, m)``, in ``dtype`` (default ``y``'s)."""
        return self._ybar(y).to(dtype or y.dtype)

    def data_variance(self, var: Tensor) -> Tensor:
        """The noise variance of each row of :meth:`data`'s ``b`` from that of each sample of ``y``
        ``(m,)`` (independent samples): ``σᵢ²/s²`` on the fluctuation rows (the mean's share,
        ``O(1/m)``, neglected), ``c² Σσᵢ²/m²`` on the flux row; ``(m + 1,)`` float64."""
        v = torch.as_tensor(var, dtype=torch.float64).reshape(-1)
        m = self.scale_rows.stop
        v = v.expand(m) if v.numel() == 1 else v
        return torch.cat([v / self._s ** 2, (self._c ** 2 * v.sum() / m ** 2).reshape(1)])
