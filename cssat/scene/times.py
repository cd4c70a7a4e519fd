"""UTC instants: the forms a scenario's start and its time stamps take (ISO strings, datetimes,
numpy ``datetime64``, skyfield and astropy times), read as checked ``datetime64[us]`` UTC.
"""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from typing import Any

import numpy as np

from cssat._checks import FieldError, FieldTypeError

__all__ = ["START_FORMS", "TIMES_FORMS", "utc_times"]


START_FORMS = "an ISO string, a datetime (naive = UTC), a numpy.datetime64 or a skyfield Time"


def start_datetime(start_utc: Any, field: str = "scenario.start_utc") -> datetime:
    """A naive UTC ``datetime`` of any of :data:`START_FORMS` (a scalar)."""
    if isinstance(start_utc, str):
        try:
            start = datetime.fromisoformat(start_utc.strip().replace("Z", "+00:00"))
        except ValueError:
            raise FieldError(field, f"not an ISO date-time: {start_utc!r}") from None
    elif isinstance(start_utc, datetime):  # also pandas.Timestamp
        start = start_utc
    elif isinstance(start_utc, np.datetime64):
        if np.isnat(start_utc):
            raise FieldError(field, "NaT is not a time")
        us = start_utc.astype("datetime64[us]").astype(np.int64)
        start = datetime(1970, 1, 1) + timedelta(microseconds=int(us))
    elif type(start_utc).__module__.startswith("skyfield") and hasattr(start_utc, "utc_datetime"):
        if np.ndim(start_utc.tt) != 0:
            raise FieldError(field, f"expected one time, got a skyfield Time of shape {np.shape(start_utc.tt)}")
        start = start_utc.utc_datetime()
    else:
        raise FieldTypeError(field, f"expected {START_FORMS}; got {type(start_utc).__name__}")
    if start.tzinfo is not None:
        start = start.astimezone(timezone.utc).replace(tzinfo=None)
    return start


#: what ``make_scenario(times=...)`` takes
TIMES_FORMS = ("a skyfield Time array", "an astropy Time array", "numpy datetime64 values",
               "datetime objects", "ISO 8601 strings (UTC unless they carry an offset)")


def utc_times(times: Any, field: str = "scenario.times") -> np.ndarray:
    """UTC instants of any of :data:`TIMES_FORMS` as a 1-D ``datetime64[us]`` array, checked:
    at least one, no NaT, strictly increasing (the error names the first offending index)."""
    mod = type(times).__module__
    if mod.startswith("skyfield") and hasattr(times, "utc_datetime"):
        times = [times.utc_datetime()] if np.ndim(times.tt) == 0 else list(times.utc_datetime())
    elif mod.startswith("astropy") and hasattr(times, "utc"):
        times = np.atleast_1d(times.utc.to_value("datetime64"))
    if isinstance(times, (str, bytes, datetime, np.datetime64)):
        times = [times]
    arr = np.asarray(times) if not isinstance(times, np.ndarray) else times
    if arr.ndim != 1 or arr.size == 0:
        raise FieldError(field, f"expected a 1-D sequence of at least one time ({', '.join(TIMES_FORMS)}), got shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.datetime64):
        out = arr.astype("datetime64[us]")
        nat = np.flatnonzero(np.isnat(out))
        if nat.size:
            raise FieldError(f"{field}[{nat[0]}]", "NaT is not a time")
    else:
        out = np.array([np.datetime64(start_datetime(t, f"{field}[{i}]"), "us") for i, t in enumerate(arr.tolist())])
    step = np.diff(out).astype(np.int64)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise FieldError(f"{field}[{i}]", f"times must increase: {out[i]} does not come after {out[i - 1]}")
    return out
