"""Reconstruction: solvers (OMP, ℓ1, TV, plug-and-play) and denoisers (sparse K-SVD, TV, wavelet,
NLM, none) as objects with one call signature each, built from ``_target_`` configs.

* solver: ``x, info = solver(problem, y)`` (:class:`Solver`; ``problem``: a :class:`Problem`, a
  :class:`cssat.physics.Measurement`, or an operator with ``shape=``);
* denoiser: ``image, info = denoiser(image, sigma=None)`` (:class:`Denoiser`).

A class of your own with the same call plugs in anywhere: point the config's ``_target_`` at it.
"""

from cssat.recon.denoisers import Denoiser, NLMDenoiser, NoDenoiser, SparseKSVD, TVDenoiser, WaveletDenoiser
from cssat.recon.problem import Problem
from cssat.recon.nonneg import NNL1, NNLS, NNOMP, NNTV
from cssat.recon.solvers import L1, OMP, TV, FluxOnly, Landweber, PnP, Solver, default_sparsity, tv_default_lam

__all__ = [
    "Problem", "Solver", "OMP", "L1", "TV", "FluxOnly", "NNLS", "NNOMP", "NNL1", "NNTV", "PnP", "Landweber", "default_sparsity", "tv_default_lam",
    "Denoiser", "SparseKSVD", "TVDenoiser", "WaveletDenoiser", "NLMDenoiser", "NoDenoiser",
]
