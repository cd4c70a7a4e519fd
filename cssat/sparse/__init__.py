"""General batched sparse-coding toolkit: operators (Ψ, Φ, ΦΨ), batched OMP, sparse K-SVD and
patch-based denoising.

Nothing here knows about satellites: it can be used on its own.
"""

from cssat.sparse.cs import DictionarySensing, sensing_dictionary
from cssat.sparse.denoise import DEMO_DEFAULTS, DenoiseInfo, estimate_sigma, ksvd_denoise
from cssat.sparse.ksvd import KSVDInfo, SparseDictionary, ksvd, odct_base, sparse_ksvd
from cssat.sparse.omp import OMPInfo, batch_omp, gram_matrix, omp_path_costs
from cssat.sparse.patches import accumulate_patches, extract_patches, fold_patches, patch_positions
from cssat.sparse.operators import ComposedOperator, GaussianSensing, LinearOperator, MatrixOperator, as_operator
from cssat.sparse.transforms import DCT, KroneckerOperator, dct_matrix, odct_matrix

__all__ = [
    "DEMO_DEFAULTS",
    "DenoiseInfo",
    "KSVDInfo",
    "SparseDictionary",
    "accumulate_patches",
    "estimate_sigma",
    "ksvd",
    "ksvd_denoise",
    "odct_base",
    "sparse_ksvd",
    "DCT",
    "DictionarySensing",
    "ComposedOperator",
    "GaussianSensing",
    "KroneckerOperator",
    "LinearOperator",
    "MatrixOperator",
    "as_operator",
    "OMPInfo",
    "batch_omp",
    "dct_matrix",
    "extract_patches",
    "fold_patches",
    "gram_matrix",
    "omp_path_costs",
    "odct_matrix",
    "patch_positions",
    "sensing_dictionary",
]
