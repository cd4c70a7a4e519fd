"""Shared plumbing of cssat's optional numba kernels: a base module below every layer, used by the
sparse kernels and the optics renderer alike (neither imports the other)."""

from __future__ import annotations

import functools
from typing import Callable

KERNELS: dict = {}


def available() -> bool:
    """Whether numba can be imported."""
    try:
        import numba  # heavy: numba (~0.3 s), only probed here  # noqa: F401
    except ImportError:
        return False
    return True


def kernel(build: Callable[[bool], Callable], threads: int, parallel: bool | None = None, *,
           pool: bool = False) -> Callable:
    """The kernel ``build(parallel)`` compiles, built once per (``build``, ``parallel``).

    With one thread the serial variant is returned. numba's pool is then set to one thread when
    it runs — already started, or started by the kernel anyway: ``pool=True`` says its serial
    variant calls a parallel helper (the OMP kernel's one-signal update), which would otherwise
    start a pool of one thread per core at ``threads=1``. A serial kernel that calls none leaves
    the pool unstarted (in a DataLoader worker, a forked child of a process that uses OpenMP, it
    must not start). With more threads, numba's pool is set to ``threads``.
    """
    import numba  # heavy: numba, only for kernel()
    from numba.np.ufunc import parallel as _pool  # heavy: numba, only for kernel()

    parallel = threads > 1 if parallel is None else bool(parallel) and threads > 1
    key = (build, parallel)
    if key not in KERNELS:
        KERNELS[key] = build(parallel)
    if threads > 1 or pool or _pool._is_initialized:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    return functools.partial(_run_keeping_threads, KERNELS[key], threads)


def _run_keeping_threads(fn: Callable, threads: int, *args):
    """``fn(*args)``, then torch's thread count put back to ``threads``: numba's OpenMP layer sets
    the process's OpenMP thread count to one per core when its first parallel kernel loads, and
    torch reads its own count from OpenMP — at ``threads=1`` every later torch operation and
    numba kernel would run on every core (measured: a 32² sparse-KSVD denoise on a busy 2-core
    machine 2.8–23.8 s instead of 0.3–0.44 s)."""
    import torch  # heavy: torch (~1 s); the module imports without it

    out = fn(*args)
    if torch.get_num_threads() != threads:
        torch.set_num_threads(threads)
    return out
