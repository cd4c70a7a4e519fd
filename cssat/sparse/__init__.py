"""General batched sparse-coding toolkit: operators (Ψ, Φ, ΦΨ) and batched OMP.

Nothing here knows about satellites: it can be used on its own.
"""

from cssat.sparse.cs import omp_reconstruct, sensing_dictionary
from cssat.sparse.omp import OMPInfo, batch_omp, gram_matrix, omp_path_costs
from cssat.sparse.operators import (
    DCT,
    ComposedOperator,
    GaussianSensing,
    LinearOperator,
    MatrixOperator,
    dct_matrix,
)

__all__ = [
    "DCT",
    "ComposedOperator",
    "GaussianSensing",
    "LinearOperator",
    "MatrixOperator",
    "OMPInfo",
    "batch_omp",
    "dct_matrix",
    "gram_matrix",
    "omp_path_costs",
    "omp_reconstruct",
    "sensing_dictionary",
]
