"""Compiled CPU kernel for the Gram path of :func:`cssat.sparse.batch_omp` (optional, numba).

One signal at a time per thread, so each signal's working set — the ``K`` Gram rows it has selected,
``K × n`` values — stays in the core's L2 cache; the torch path runs signals in lockstep and is
bound by cache bandwidth and per-operation overhead on a CPU. The arithmetic, the stopping rules
and the output are those of the torch path (``_omp_torch.omp_chunk``), and the tests compare the two.
"""

from __future__ import annotations

import numpy as np

from cssat.sparse._numba import available, kernel

__all__ = ["available"]


def _build(parallel: bool):
    from cssat.sparse import _omp_kernels

    return _omp_kernels.build(parallel)


def omp_gram(G: np.ndarray, A0: np.ndarray, ynorm2: np.ndarray, K: int, tol, out, n_iter, res, threads: int, cap0: int = 64):
    """Run the kernel in place on numpy arrays (all C-contiguous, one float dtype)."""
    use_tol = tol is not None
    dt = A0.dtype.type
    n_blocks = max(1, min(A0.shape[0], 8 * threads))
    kernel(_build, threads)(G, A0, ynorm2, K, dt(tol if use_tol else 0.0), use_tol, out, n_iter, res, n_blocks, min(K, cap0))
