"""A scene that moves during the observation: each sample sees the satellite as it is
at its own time.

:class:`MovingScene` is the paper's pixel sensing with the image changing per sample: the mesh
(``model``: the TESS-like spacecraft) over a real scenario (SGP4 orbit, Sun, observer, the
nadir-pointing attitude) is rendered at every sample's time, ``x_t``, and measured as
``y_t = Σⱼ Φ[t, j] x_t[j]`` (paper Eq. 12 with a changing scene). The truth a solver is scored
against is the time-mean image ``x̄`` (the static image it can at best return). What the motion
alone costs is reported beside the score: ``motion_to_noise = ‖(Φ ⊙ (X − 𝟙x̄ᵀ))𝟙‖ / √Σσᵢ²`` —
the data-space size of the scene's change against the noise (> 1: the motion, not the noise,
limits a static reconstruction) —, ``motion_flux_change`` (the frames' flux range over its
mean) and ``motion_phase_change_deg`` (the phase angle's range).

Assumptions: the attitude is the paper's nadir pointing; the frames are rendered at
``render_size = target.size`` with the mesh's default field of view and scaled together so that
``max x̄ = 1``; the time step is the detector's cadence (the noise model's exposure plus its
readout, or ``step_s``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, int_param
from cssat.experiments.context import Run, as_field
from cssat.experiments.forward import Measured, PixelSensing
from cssat.scene import ASTRA_1KR_SYNTHETIC_TLE, make_scenario, tess_like

__all__ = ["MovingScene", "scene_frames"]

_FRAMES: dict = {}  # the last frames rendered: a grid's cells share them (one entry)


def scene_frames(m: int, size: int, *, start_utc: str, step_s: float, tle: Any = None, lat_deg: float = 51.17,
                 lon_deg: float = 10.45, alt_m: float = 0.0, shadows: bool = True) -> tuple[np.ndarray, dict[str, Any]]:
    """``(frames (m, size, size) float64 in W/m², geometry)`` of the TESS-like mesh over ``m``
    samples ``step_s`` apart from ``start_utc`` (the synthetic Astra 1KR TLE when ``tle`` is
    null); geometry: ``phase_angle_deg (m,)``, ``elevation_deg (m,)``, ``sunlit (m,)``."""
    key = (m, size, start_utc, step_s, str(tle), lat_deg, lon_deg, alt_m, shadows)
    if key in _FRAMES:
        return _FRAMES[key]
    import torch  # heavy: torch (~1 s); the module imports without it

    from cssat.optics import default_fov, render, simulate_light_curve  # heavy: cssat.optics imports torch

    mesh = tess_like(material="uniform")  # the paper's single material, as its target image
    sc = make_scenario(tle=ASTRA_1KR_SYNTHETIC_TLE if tle is None else tle, start_utc=start_utc, n_steps=m, step_s=step_s,
                       lat_deg=lat_deg, lon_deg=lon_deg, alt_m=alt_m)
    lc = simulate_light_curve(mesh, sc, shadows=shadows)
    frames = render(mesh, lc.sun, lc.observer, size, fov_m=default_fov(mesh), brightness=lc.facets, dtype=torch.float64)
    cos = np.clip((lc.sun * lc.observer).sum(1), -1, 1)
    geo = {"phase_angle_deg": np.degrees(np.arccos(cos)), "elevation_deg": np.asarray(sc.elevation_deg),
           "sunlit": np.asarray(sc.sunlit, dtype=float)}
    _FRAMES.clear()
    _FRAMES[key] = (frames.numpy(), geo)
    return _FRAMES[key]


class MovingScene(PixelSensing):
    """Pixel sensing of a scene rendered at every sample's time (module docstring):
    ``start_utc``; ``step_s`` (null: the noise model's cadence, exposure + readout, else 1 s);
    ``tle`` (null: Astra 1KR, synthetic); the observer's ``lat_deg``/``lon_deg``/``alt_m``;
    ``shadows``; ``dtype``/``draw_dtype`` as :class:`PixelSensing`. The target group sets only the
    image size."""

    name = "moving"

    def __init__(self, start_utc: str = "2020-04-01T21:00:00", step_s: float | None = None, tle: Any = None,
                 lat_deg: float = 51.17, lon_deg: float = 10.45, alt_m: float = 0.0, shadows: bool = True,
                 dtype: str | None = None, draw_dtype: str | None = None):
        from cssat.models.moving.config import MovingConfig  # local: the typed configs' package, only to build one

        c = self.config = MovingConfig(start_utc=start_utc, step_s=step_s, tle=tle, lat_deg=lat_deg, lon_deg=lon_deg,
                                       alt_m=alt_m, shadows=shadows, dtype=dtype, draw_dtype=draw_dtype)  # checked
        self._precisions(c)
        self.start_utc, self.step_s, self.tle, self.shadows = c.start_utc, c.step_s, c.tle, c.shadows
        self.lat_deg, self.lon_deg, self.alt_m = c.lat_deg, c.lon_deg, c.alt_m

    def frames(self, m: int, size: int, step_s: float | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        """``(x_t (m, size²), x̄ (size, size), geometry)`` scaled so that ``max x̄ = 1``, samples
        ``step_s`` apart (default this model's, else 1 s)."""
        step = step_s or self.step_s or 1.0
        with as_field("forward"):
            frames, geo = scene_frames(int_param(m, "m", 1), size, start_utc=self.start_utc, step_s=step,
                                       tle=self.tle, lat_deg=self.lat_deg, lon_deg=self.lon_deg, alt_m=self.alt_m,
                                       shadows=self.shadows)
        mean = frames.mean(0)
        if not mean.max() > 0:
            raise FieldError("forward.start_utc", "the satellite is dark (eclipsed or below the horizon) for the whole "
                                                  "observation: choose another start_utc")
        s = 1.0 / mean.max()
        return frames.reshape(len(frames), -1) * s, mean * s, geo

    def sense(self, run: Run, truth: np.ndarray, operator: Any, noise: Any, dtype: Any) -> Measured:
        """Measure the moving scene through ``operator`` with ``noise`` (seed + 1); the truth is
        the time-mean image, ``truth`` (the target's) only sets the size."""
        import torch  # heavy: torch (~1 s); the module imports without it

        from cssat.physics import Measurement  # heavy: cssat.physics imports torch

        n = truth.shape[0]
        m = operator.n_out
        step = self.step_s or getattr(noise, "cadence_s", None) or 1.0  # the detector's cadence when not given
        X, mean, geo = self.frames(m, n, step)
        Xt = torch.as_tensor(X, dtype=dtype, device=run.device)
        meas = Measurement(operator, noise, seed=run.seed + 1, x_shape=(n, n))
        with as_field("noise"):
            y = meas.frames(Xt)
            var = noise.variance(y, flux=Xt.sum(1).mean())
        phi = operator.matrix().to(Xt)
        xbar = torch.as_tensor(mean, dtype=dtype, device=run.device).reshape(-1)
        motion = (phi * (Xt - xbar)).sum(1)
        flux = X.sum(1)
        metrics = {**meas.describe(), "motion_to_noise": float(motion.norm() / var.sum().sqrt()),
                   "motion_flux_change": float(np.ptp(flux) / flux.mean()),
                   "motion_phase_change_deg": float(np.ptp(geo["phase_angle_deg"])),
                   "motion_duration_s": m * step}
        return Measured(meas, y, mean, (n, n), metrics, var)
