"""The problem a solver is handed: the forward operator, the unknown's shape and the noise level.

Every solver is called as ``x, info = solver(problem, y)``. ``problem`` is a :class:`Problem`, or
anything :meth:`Problem.of` turns into one: a :class:`cssat.physics.Measurement` (deepinv style:
its operator, its ``x_shape`` and its noise model), a :class:`~cssat.sparse.LinearOperator` or a
dense ``(m, N)`` tensor with ``shape=`` given. Centring a positive system
(:class:`cssat.physics.Centered`) is a wrapper of the operator, so it is a problem like any other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

from cssat._checks import FieldError, FieldTypeError

if TYPE_CHECKING:
    from torch import Tensor

    from cssat.sparse.operators import LinearOperator

__all__ = ["Problem"]


@dataclass
class Problem:
    """``y = A x + noise`` with ``A (m, N)`` a :class:`~cssat.sparse.LinearOperator`, the unknown
    ``x`` of ``x_shape`` (``prod(x_shape) = N``; an image ``(H, W)``) and the noise's standard
    deviation ``noise_sigma`` in ``y``'s units (a scalar, or ``(m,)`` one per sample; ``None``:
    unknown), or the variance of each sample
    ``noise_var (m,)`` (a heteroscedastic noise: photon counts) — what the discrepancy principle
    (TV's ``lam: discrepancy``, OMP's ``epsilon: discrepancy``) fits the data to."""

    operator: LinearOperator
    x_shape: tuple[int, ...]
    noise_sigma: Any = None
    noise_var: Any = None

    def variance(self) -> Tensor:
        """The noise variance of each sample ``(m,)`` float64: ``noise_var``, else ``noise_sigma²``."""
        import torch  # heavy: torch (~1 s); the module imports without it

        if self.noise_var is not None:
            v = torch.as_tensor(self.noise_var, dtype=torch.float64).reshape(-1)
            if v.numel() not in (1, self.m):
                raise FieldError("noise_var", f"expected {self.m} variances (one per sample), got {v.numel()}")
            return v.expand(self.m)
        if self.noise_sigma is not None:
            return self.sigma() ** 2
        raise FieldError("noise", "the discrepancy principle needs the noise level: give the problem noise_sigma or "
                                  "noise_var (the pipeline takes it from the noise model)")

    def sigma(self) -> Tensor:
        """The noise's standard deviation of each sample ``(m,)`` float64: ``noise_sigma`` (a scalar
        or one per sample) as given, else ``√noise_var``."""
        import torch  # heavy: torch (~1 s); the module imports without it

        if self.noise_sigma is None:
            return self.variance().sqrt()
        s = torch.as_tensor(self.noise_sigma, dtype=torch.float64).reshape(-1)
        if s.numel() not in (1, self.m):
            raise FieldError("noise_sigma", f"expected a scalar or {self.m} values (one per sample), got {s.numel()}")
        return s.expand(self.m)

    def __post_init__(self) -> None:
        self.x_shape = tuple(int(s) for s in self.x_shape)
        if math.prod(self.x_shape) != self.operator.n_in:
            raise FieldError("shape", f"{self.x_shape} has {math.prod(self.x_shape)} values but the operator has "
                                      f"{self.operator.n_in} columns")

    @property
    def m(self) -> int:
        """The number of samples (rows of the operator)."""
        return int(self.operator.n_out)

    @property
    def n(self) -> int:
        """The number of unknowns (columns of the operator)."""
        return int(self.operator.n_in)

    def check(self, y: Tensor) -> None:
        """``y (m,)`` or ``(B, m)`` must match the operator's rows."""
        if y.shape[-1] != self.m:
            raise FieldError("y", f"last dimension {y.shape[-1]} does not match the operator's {self.m} rows")

    @classmethod
    def of(cls, problem: Any, shape: Sequence[int] | None = None) -> Problem:
        """``problem`` as a :class:`Problem`: itself; a ``Measurement`` (its operator, its
        ``x_shape`` unless ``shape`` is given, its noise's ``sigma``); an operator or a dense
        ``(m, N)`` matrix with ``shape`` (or the operator's own ``in_shape``)."""
        from torch import Tensor  # heavy: torch (~1 s); the module imports without it

        from cssat.sparse.operators import LinearOperator, MatrixOperator  # heavy: cssat.sparse.operators imports torch

        if isinstance(problem, Problem):
            return problem if shape is None else cls(problem.operator, shape, problem.noise_sigma, problem.noise_var)
        op, sigma, own = problem, None, None
        if hasattr(problem, "operator") and isinstance(problem.operator, LinearOperator):  # a Measurement
            op, own = problem.operator, getattr(problem, "x_shape", None)
            sigma = getattr(getattr(problem, "noise", None), "sigma", None)
            sigma = float(sigma) if isinstance(sigma, (int, float)) and not isinstance(sigma, bool) else None
        if isinstance(op, Tensor) and op.ndim == 2:
            op = MatrixOperator(op)
        if not isinstance(op, LinearOperator):
            raise FieldTypeError("problem", "expected a Problem, a Measurement, a LinearOperator or an (m, N) tensor, "
                                            f"got {type(problem).__name__}")
        shape = shape if shape is not None else own if own is not None else op.in_shape
        if shape is None:
            raise FieldError("shape", f"the operator has {op.n_in} columns but no shape: give the unknown's shape")
        return cls(op, tuple(shape), sigma)
