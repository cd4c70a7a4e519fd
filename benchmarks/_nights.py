"""Shared set-up of the benchmark scripts on the inversion experiment's geometry (run them from the
repository root): the night samples of its scenario."""

from __future__ import annotations

import numpy as np


def night_scenario(overrides: list[str], nights: float, step_s: float):
    """``(cfg, scenario of the night samples only, n steps simulated)`` for the configuration
    ``overrides`` (e.g. ``["experiment=inversion", ...]``): ``nights`` days from its
    ``scenario.start_utc`` at ``step_s``, kept where the Sun is below ``nights.sun_alt_max_deg`` and
    the object above ``nights.min_elevation_deg`` (cssat.experiments.forward.nights.night_mask)."""
    from hydra import compose, initialize_config_module  # heavy: hydra, to read the shipped configs

    from cssat.experiments.forward.nights import night_mask  # heavy: the inversion's nights
    from cssat.experiments.scene import build_scenario  # heavy: skyfield scenarios

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose("config", overrides=overrides)
    start = np.datetime64(str(cfg.scenario.start_utc))
    n = int(nights * 86400 / step_s)
    times = start + (np.arange(n) * step_s * 1e6).astype("timedelta64[us]")
    sc = build_scenario(cfg, times)
    keep = night_mask(sc, float(cfg.nights.sun_alt_max_deg), float(cfg.nights.min_elevation_deg))
    sc = type(sc)(**{k: (getattr(sc, k)[keep] if k != "name" else sc.name) for k in sc.__dataclass_fields__})
    return cfg, sc, n
