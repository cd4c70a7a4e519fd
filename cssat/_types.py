"""Type aliases of the public API, for annotations only (every module that uses them imports
them under ``TYPE_CHECKING``: nothing here is imported at run time)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Union

if TYPE_CHECKING:
    import numpy as np
    import torch

    from cssat.physics import Measurement
    from cssat.sparse.problem import Problem
    from cssat.sparse.operators import LinearOperator

    #: a numpy array or a tensor (numpy in, numpy out where a function accepts both)
    Array = Union[np.ndarray, torch.Tensor]
    #: a sensing operator Φ (m, N): an operator, or its dense matrix as a tensor or array
    OperatorLike = Union[LinearOperator, torch.Tensor, np.ndarray]
    #: what a solver takes: a Problem, a Measurement, or an operator (with the shape given)
    ProblemLike = Union[Problem, Measurement, LinearOperator, torch.Tensor, np.ndarray]
    #: a torch dtype, or None for the input's / the default
    DTypeLike = Union[torch.dtype, None]
    #: a torch device, its name, or None for the input's / the CPU
    DeviceLike = Union[torch.device, str, None]
    #: unit vectors (T, 3) as a tensor, an array or nested sequences
    Vectors = Union[torch.Tensor, np.ndarray, "list[list[float]]"]
