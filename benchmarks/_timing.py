"""Shared timing helper of the benchmark scripts (run them from the repository root)."""

from __future__ import annotations

import statistics
import time


def median_time(fn, repeats: int):
    """Run ``fn`` ``repeats`` times: ``(median seconds, all seconds, last result)``."""
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), times, out
