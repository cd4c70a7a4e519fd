"""The config of pixel sensing of a moving scene (``forward: moving``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

from cssat._checks import FieldError, bool_param, float_param
from cssat.models.pixels.config import check_dtype

__all__ = ["MovingConfig"]


@dataclass
class MovingConfig:
    """The pixel sensing of a scene that moves: the TESS-like mesh rendered at every sample's time
    over a real scenario (SGP4, Sun, observer, nadir pointing), ``y_t = Σ Φ[t, j] x_t[j]``; scored
    against the time-mean image, with the motion's own cost (``motion_to_noise``):
    :class:`cssat.experiments.motion.MovingScene`."""

    _target_: str = "cssat.experiments.motion.MovingScene"
    #: the first sample (UTC): evening at the default observer, Astra 1KR sunlit, 31° up
    start_utc: str = "2020-04-01T21:00:00"
    #: seconds between samples; null: the noise model's cadence (exposure_s + readout_s), else 1 s
    step_s: Optional[float] = None
    #: the element set; null: Astra 1KR (synthetic TLE, GEO)
    tle: Any = None
    lat_deg: float = 51.17
    lon_deg: float = 10.45
    alt_m: float = 0.0
    #: self-shadowing of the rendered frames (ray cast)
    shadows: bool = True
    #: as :class:`~cssat.models.pixels.config.PixelsConfig`
    dtype: Optional[str] = None
    draw_dtype: Optional[str] = None

    def __post_init__(self) -> None:
        self.start_utc = str(self.start_utc)
        if self.step_s is not None:
            self.step_s = float_param(self.step_s, "forward.step_s", 0.0, open_lo=True)
        for key in ("lat_deg", "lon_deg", "alt_m"):
            value = getattr(self, key)
            try:
                value = float(value)
            except (TypeError, ValueError):
                value = math.nan
            if not math.isfinite(value):
                raise FieldError(f"forward.{key}", f"expected a finite number, got {getattr(self, key)!r}")
            setattr(self, key, value)
        bool_param(self.shadows, "forward.shadows")
        check_dtype(self.dtype, "forward.dtype")
        check_dtype(self.draw_dtype, "forward.draw_dtype")
