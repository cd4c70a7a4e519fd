"""General batched sparse-coding toolkit: operators (Ψ, Φ, ΦΨ) and batched OMP.

Nothing here knows about satellites: it can be used on its own.
"""

from cssat.sparse.cs import omp_reconstruct, sensing_dictionary
from cssat.sparse.omp import OMPInfo, batch_omp, gram_matrix, omp_path_costs
from cssat.sparse.patches import extract_patches, fold_patches, patch_positions
from cssat.sparse.operators import (
    DCT,
    ComposedOperator,
    GaussianSensing,
    KroneckerOperator,
    LinearOperator,
    MatrixOperator,
    dct_matrix,
    odct_matrix,
)

__all__ = [
    "DCT",
    "ComposedOperator",
    "GaussianSensing",
    "KroneckerOperator",
    "LinearOperator",
    "MatrixOperator",
    "OMPInfo",
    "batch_omp",
    "dct_matrix",
    "extract_patches",
    "fold_patches",
    "gram_matrix",
    "omp_path_costs",
    "odct_matrix",
    "omp_reconstruct",
    "patch_positions",
    "sensing_dictionary",
]
