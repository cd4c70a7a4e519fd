"""Compiled CPU kernel for the Gram path of :func:`cssat.sparse.batch_omp` (optional, numba).

One signal at a time per thread, so each signal's working set — the ``K`` Gram rows it has selected,
``K × n`` values — stays in the core's cache (fewer signals than threads: one signal at a time,
its correlation updates split among the threads); the torch path runs signals in lockstep and is
bound by cache bandwidth and per-operation overhead on a CPU. The arithmetic, the stopping rules
and the output are those of the torch path (``_omp_torch.omp_chunk``), and the tests compare the two.
"""

from __future__ import annotations

import threading

import numpy as np

from cssat.sparse._numba import available, kernel

__all__ = ["available", "sparse_gram"]


def _build(parallel: bool):
    from cssat.sparse import _omp_kernels  # heavy: cssat.sparse._omp_kernels imports numba

    return _omp_kernels.build(parallel)


def omp_gram(G: np.ndarray, A0: np.ndarray, ynorm2: np.ndarray, K: int, tol, out, n_iter, res, threads: int,
             cap0: int = 64, bar=None):
    """Run the kernel in place on numpy arrays (all C-contiguous, one float dtype). ``bar``: a
    tqdm bar of atoms selected, advanced from a watcher thread while the kernel (which releases
    the GIL) runs."""
    use_tol = tol is not None
    dt = A0.dtype.type
    # fewer signals than threads: one signal at a time, its updates split among the threads
    spread = 1 < threads and A0.shape[0] < threads
    n_blocks = 1 if spread else max(1, min(A0.shape[0], 8 * threads))
    steps = np.zeros(n_blocks, np.int64)
    fn = kernel(_build, threads, parallel=not spread, pool=True)  # the serial variant calls _update_spread
    run = lambda: fn(G, A0, ynorm2, K, dt(tol if use_tol else 0.0), use_tol, out, n_iter, res,  # noqa: E731
                     n_blocks, min(K, cap0), steps, spread)
    if bar is None or bar.disable:
        run()
        return

    stop, shown = threading.Event(), [0]

    def show():
        now = int(steps.sum())
        bar.update(now - shown[0])
        shown[0] = now

    def watch():
        while not stop.wait(0.2):
            show()

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        run()
    finally:
        stop.set()
        watcher.join()
        show()


def _build_sparse_gram(parallel: bool):
    from cssat.sparse import _omp_kernels  # heavy: cssat.sparse._omp_kernels imports numba

    return _omp_kernels.build_sparse_gram(parallel)


def sparse_gram(crow: np.ndarray, col: np.ndarray, val: np.ndarray, n: int, threads: int) -> np.ndarray:
    """``DᵀD`` of a CSR matrix with ``n`` columns (``_omp_kernels.build_sparse_gram``) on ``threads`` threads."""
    return kernel(_build_sparse_gram, threads)(crow, col, val, n, max(1, 16 * threads))
