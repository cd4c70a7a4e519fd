"""Memory: the estimate every experiment makes before it allocates anything large, and the peak it
reached (``peak_rss_gb`` in ``metrics.json``)."""

from __future__ import annotations

import resource

from cssat._checks import FieldError

__all__ = ["available_memory_bytes", "peak_rss_bytes", "check_memory"]

GB = 2**30


def available_memory_bytes() -> int:
    """Memory available to this process now, bytes (``psutil.virtual_memory().available``: what
    can be allocated without swapping, page cache included)."""
    import psutil  # heavy: psutil, only for available_memory_bytes()

    return int(psutil.virtual_memory().available)


def peak_rss_bytes() -> int:
    """Peak resident memory of this process so far, bytes: ``getrusage``'s running maximum
    (Linux reports KiB; psutil has no peak on Linux, so the standard library gives it)."""
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def check_memory(parts: dict[str, int], limit_gb: float | None, hint: str, *, peak: int | None = None, margin: float = 1.2) -> int:
    """Stop with a ``memory:`` FieldError when the estimated peak exceeds the limit ``limit_gb``
    (the config's ``memory_limit_gb``; ``None``: the memory available now); return the estimate
    in bytes.

    ``parts`` are the large arrays of the run (bytes); the peak is ``margin ×`` their sum, or
    ``margin × peak`` when the caller knows which of them live together.
    """
    estimate = int(margin * (peak if peak is not None else sum(parts.values())))
    limit = int(limit_gb * GB) if limit_gb is not None else available_memory_bytes()
    if estimate > limit:
        detail = ", ".join(f"{k} {v / GB:.2f}" for k, v in parts.items())
        raise FieldError(
            "memory", f"this run needs about {estimate / GB:.1f} GB at its peak ({detail} GB) but "
            f"{limit / GB:.1f} GB are available; {hint}"
        )
    return estimate
