"""Shared plumbing of cssat's optional numba kernels (part of the sparse layer, which stands alone; the
optics renderer uses it too)."""

from __future__ import annotations

from typing import Callable

_KERNELS: dict = {}


def available() -> bool:
    """Whether numba can be imported."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def kernel(build: Callable[[bool], Callable], threads: int, parallel: bool | None = None) -> Callable:
    """The kernel ``build(parallel)`` compiles, built once per (``build``, ``parallel``).

    With one thread (e.g. in a DataLoader worker, where torch sets one) the serial variant is
    returned: numba's thread pool must not start in a forked child of a process that uses OpenMP.
    Otherwise numba's pool is set to ``threads``, also for a serial variant asked for by
    ``parallel=False`` (a serial loop that calls parallel helpers).
    """
    import numba

    parallel = threads > 1 if parallel is None else bool(parallel) and threads > 1
    key = (build, parallel)
    if key not in _KERNELS:
        _KERNELS[key] = build(parallel)
    if threads > 1:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    return _KERNELS[key]
