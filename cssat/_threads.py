"""Fits whose answers do not depend on the thread count: torch on one thread within a block, and
independent fits run side by side on Python threads (a base module below every layer).

A long L-BFGS path amplifies the last bits in which a parallel sum's order (set by torch's thread
count) differs, and can end in another optimum; so a fit is run with each torch operation on one
thread, and the ``threads`` a run was given are spent on running independent fits (multi-starts,
twin descents) at once instead — each fit's arithmetic then the same whatever the count. torch
releases the GIL inside its operations, so the fits overlap where their tensors are large.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator, TypeVar

__all__ = ["one_thread", "thread_map"]

T = TypeVar("T")


@contextmanager
def one_thread() -> Iterator[int]:
    """Within the block, torch on one thread (the run's count put back after); yields the count
    it found (the workers a caller may give :func:`thread_map`)."""
    import torch  # heavy: torch (~1 s); the module imports without it

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield before
    finally:
        torch.set_num_threads(before)


def thread_map(fn: Callable[[Any], T], items: Iterable[Any], workers: int = 1) -> list[T]:
    """``[fn(x) for x in items]``, in order, on up to ``workers`` Python threads at once (one: in
    the caller's thread). Call it within :func:`one_thread` so that each ``fn``'s torch operations
    run on its own thread alone: the results are then those of the serial loop, bit for bit. The
    first exception raised by a call is raised here (the other calls run to their end)."""
    items = list(items)
    workers = min(int(workers), len(items))
    if workers <= 1:
        return [fn(x) for x in items]
    from concurrent.futures import ThreadPoolExecutor  # startup: only for several workers

    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="cssat-fit") as pool:
        return list(pool.map(fn, items))
