"""What a ground station observes of a scenario, and what a light-curve inversion needs of it:
the night's samples, the nights themselves, and the checks made before any work — the spin
search's settings, the simulated scenario's size against the cadence and the memory, a measured
file's samples and nights."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError, bool_param, float_param, int_param
from cssat.experiments.resources import check_memory

__all__ = ["night_mask", "night_index", "check_search", "span_seconds", "check_size", "check_constrained", "MAX_STEPS",
           "MIN_OBSERVED_SAMPLES", "MIN_OBSERVED_NIGHTS"]

#: the most time steps a simulated scenario may hold (nights.n × 86400 / scenario.step_s)
MAX_STEPS = 2_000_000
#: a measured light curve's least for an inversion: samples, nights (one pass holds one geometry)
MIN_OBSERVED_SAMPLES = 50
MIN_OBSERVED_NIGHTS = 2


def night_mask(scenario: Any, sun_alt_max_deg: float, min_elevation_deg: float) -> np.ndarray:
    """``(T,)`` the samples of a night's observation: the Sun below ``sun_alt_max_deg`` at the
    station (the geocentric vertical: within 0.2° of the geodetic one), the object above
    ``min_elevation_deg`` and wholly sunlit."""
    up = scenario.r_obs / np.linalg.norm(scenario.r_obs, axis=1, keepdims=True)
    d = scenario.r_sun - scenario.r_obs
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sun_alt = np.degrees(np.arcsin(np.clip((d * up).sum(1), -1, 1)))
    return (sun_alt < sun_alt_max_deg) & (scenario.elevation_deg > min_elevation_deg) & (scenario.sunlit >= 1)


def night_index(seconds: np.ndarray, gap_s: float = 6 * 3600.0) -> np.ndarray:
    """``(T,)`` the night of each sample: a new night after a gap longer than ``gap_s``."""
    return np.concatenate([[0], np.cumsum(np.diff(seconds) > gap_s)]).astype(int)


def check_search(search: dict[str, Any], span_s: float | None = None) -> None:
    """The spin search's settings (``inversion.*``), each in its range; the longest period
    searched at most ``span_s``, the time the light curve spans (a longer one is not determined)."""
    for key, lo in (("n_poles", 1), ("n_starts", 1), ("n_refine", 1), ("coarse_normals", 16), ("coarse_samples", 16),
                    ("max_samples", 16)):
        if key in search:
            int_param(search[key], f"inversion.{key}", lo, 10**6)
    if "split_nights" in search:
        search["split_nights"] = bool_param(search["split_nights"], "inversion.split_nights")
    lo = float_param(search.get("min_period_s", 60.0), "inversion.min_period_s", 0.0, open_lo=True)
    hi = float_param(search.get("max_period_s", 86400.0), "inversion.max_period_s", lo, open_lo=True)
    if span_s is not None and hi > span_s:
        raise FieldError("inversion.max_period_s", f"{hi:g} s is longer than the {span_s:g} s the light curve spans: "
                                                   "a period is determined only within the span")


def span_seconds(observed: Any, n_nights: int) -> float:
    """The time a light curve spans: a measured file's first to last stamp, or ``nights.n`` days."""
    if observed is not None:
        t = observed.times_utc
        return float((t[-1] - t[0]) / np.timedelta64(1, "s")) if len(t) > 1 else 0.0
    return n_nights * 86400.0


def check_size(step_s: Any, n_nights: int, n_faces: int, searched: Any = None, n_normals: int = 0,
               memory_limit_gb: float | None = None) -> None:
    """A simulated scenario's steps (``scenario.step_s`` over ``n_nights``) against the periods
    searched (the shortest at least two cadences: Nyquist) and the memory of its light curve
    (facet brightness and visibility per step) and of the EGI operator on ``n_normals`` normals
    (``G (T, K)`` and its weighted copy; every step counted: an upper bound), before any is
    computed; ``searched``: the :class:`~cssat.models.egi.config.InversionConfig` whose periods
    are searched (``None``: the spin given)."""
    step = float_param(step_s, "scenario.step_s", 0.0, open_lo=True)
    if searched is not None:
        for key, lo in (("inversion.min_period_s", searched.min_period_s),
                        ("inversion.tumbling.min_period_s", searched.tumbling.get("min_period_s"))):
            if lo is not None and float(lo) < 2 * step:
                raise FieldError(key, f"{float(lo):g} s is under two cadences (scenario.step_s = {step:g} s): a shorter "
                                      f"period is aliased; raise it to {2 * step:g} s or more, or shorten the cadence")
    n_steps = int(n_nights * 86400.0 / step) + 1
    if n_steps > MAX_STEPS:
        raise FieldError("scenario.step_s", f"{step:g} s over {n_nights} nights is {n_steps:.3g} steps, more than "
                                            f"{MAX_STEPS:.0e}: lengthen the cadence")
    parts = {"scenario (T, ~20 values)": n_steps * 20 * 8, "facet brightness and visibility (T, F)": n_steps * max(n_faces, 1) * 8 * 4,
             "EGI operator and its weighted copy (T, K)": n_steps * n_normals * 8 * 2}
    check_memory(parts, None if memory_limit_gb is None else float(memory_limit_gb),
                 "lengthen scenario.step_s or lower nights.n or inversion.n_normals")


def check_constrained(observed: Any, t: np.ndarray, night: np.ndarray) -> None:
    """Refuse a measured light curve the inversion cannot constrain: too few usable samples, or
    one night (a pass holds one Sun–observer geometry: the pole and the shape are then not
    determined), naming what is missing."""
    n_nights = int(night.max() + 1) if len(night) else 0
    missing = []
    if len(t) < MIN_OBSERVED_SAMPLES:
        missing.append(f"at least {MIN_OBSERVED_SAMPLES} sunlit samples (the file gives {len(t)})")
    if n_nights < MIN_OBSERVED_NIGHTS:
        missing.append(f"at least {MIN_OBSERVED_NIGHTS} nights (the file holds {n_nights}: one pass does not constrain a "
                       "pole or a shape)")
    if missing:
        raise FieldError("observations", f"{Path(observed.source).name or 'the light curve'} cannot constrain an "
                                         f"inversion: it needs {' and '.join(missing)}; experiment=characterise "
                                         "gives what it does hold")

