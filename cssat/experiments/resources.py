"""Memory: the estimate every experiment makes before it allocates anything large, and the peak it
reached (``peak_rss_gb`` in ``metrics.json``)."""

from __future__ import annotations

import os
from typing import Any

from cssat.experiments.common import ConfigError, require_float

__all__ = ["available_memory_bytes", "peak_rss_bytes", "check_memory"]

GB = 2**30


def available_memory_bytes() -> int:
    """Memory available to this process now (``MemAvailable``; else total physical memory)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def peak_rss_bytes() -> int:
    """Peak resident memory of this process so far, bytes (Linux ``ru_maxrss`` is in KiB; it is
    already the running maximum)."""
    import resource

    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def check_memory(parts: dict[str, int], cfg: Any, hint: str, *, peak: int | None = None, margin: float = 1.2) -> int:
    """Stop with a ``memory:`` ConfigError when the estimated peak exceeds the limit
    (``memory_limit_gb``, default: the memory available now); return the estimate in bytes.

    ``parts`` are the large arrays of the run (bytes); the peak is ``margin ×`` their sum, or
    ``margin × peak`` when the caller knows which of them live together.
    """
    estimate = int(margin * (peak if peak is not None else sum(parts.values())))
    limit_gb = cfg.get("memory_limit_gb")
    limit = int(require_float(limit_gb, "memory_limit_gb", lo=0.0) * GB) if limit_gb is not None else available_memory_bytes()
    if estimate > limit:
        detail = ", ".join(f"{k} {v / GB:.2f}" for k, v in parts.items())
        raise ConfigError(
            f"memory: this run needs about {estimate / GB:.1f} GB at its peak ({detail} GB) but "
            f"{limit / GB:.1f} GB are available; {hint}"
        )
    return estimate
