"""The image sensing model's parts that the image pipeline shares with it (a module of its own:
the pipeline imports these, :class:`~cssat.experiments.forward.PixelSensing` imports the
pipeline): the object's :class:`Geometry`, the number of :func:`measurements`, the
:class:`Measured` unknown and :func:`phi_stats`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from cssat._checks import FieldError, float_param, int_param, opt

if TYPE_CHECKING:
    import torch

    from cssat.physics import Measurement

__all__ = ["Geometry", "Measured", "measurements", "phi_stats", "ARCSEC", "PHI_STATS_FULL_MAX"]

ARCSEC = math.pi / (180 * 3600)


class Geometry:
    """Where the object is (the ``geometry`` group): its size ``object_size_m`` across the image,
    at ``range_km`` — or at the range that gives ``angular_size_arcsec`` when that is set — and
    ``slew_rad_s``, the line of sight's angular rate while the telescope tracks it (a LEO pass;
    the models with layers, ``phase_screen``, take it). Every atmosphere model takes
    ``object_size_m`` and ``range_km``; those whose weights do not depend on the pixels'
    directions (``gaussian``, ``lognormal``) record them only."""

    def __init__(self, object_size_m: float = 10.0, range_km: float = 35786.0, angular_size_arcsec: float | None = None,
                 slew_rad_s: float = 0.0):
        self.object_size_m = float_param(object_size_m, "object_size_m", 0.0, open_lo=True)
        self.slew_rad_s = float_param(slew_rad_s, "slew_rad_s", 0.0, 1.0)
        self.angular_size_arcsec = opt(angular_size_arcsec, float_param, "angular_size_arcsec", 0.0, open_lo=True)
        if self.angular_size_arcsec is None:
            self.range_km = float_param(range_km, "range_km", 0.0, open_lo=True)
        else:
            self.range_km = self.object_size_m / (self.angular_size_arcsec * ARCSEC) / 1e3

    @property
    def arcsec(self) -> float:
        """The image's angular size (arcsec)."""
        return self.object_size_m / (self.range_km * 1e3) / ARCSEC

    def kwargs(self) -> dict[str, float]:
        """What an atmosphere model is built with (each takes those it has parameters for)."""
        out = {"object_size_m": self.object_size_m, "range_km": self.range_km}
        if self.slew_rad_s:
            out["slew_rad_s"] = self.slew_rad_s
        return out

    def describe(self) -> dict[str, float]:
        return {"geometry_object_size_m": self.object_size_m, "geometry_range_km": self.range_km,
                "geometry_angular_size_arcsec": self.arcsec, "geometry_slew_rad_s": self.slew_rad_s}


def measurements(cs: Mapping[str, Any] | None, N: int) -> int:
    """``m`` from the ``cs`` group: ``cs.m`` when set (``1 ≤ m ≤ N``), else ``round(cs.ratio · N)``
    (``0 < ratio ≤ 1``), so that ``target.size`` can change alone."""
    cs = cs or {}
    if cs.get("ratio") is not None:  # checked also when cs.m wins, so a bad ratio is never ignored
        float_param(cs["ratio"], "cs.ratio", 0.0, 1.0, open_lo=True)
    if cs.get("m") is not None:
        return int_param(cs["m"], "cs.m", 1, N)
    if cs.get("ratio") is None:
        raise FieldError("cs.m", "give the number of samples cs.m or the ratio cs.ratio = m/N")
    ratio = float_param(cs["ratio"], "cs.ratio", 0.0, 1.0, open_lo=True)
    return max(1, round(ratio * N))


@dataclass
class Measured:
    """What the forward stage hands on: the measurement (operator + noise), the light curve ``y``
    in the measurement's precision, the unknown's truth and shape, and its settings for
    ``metrics.json``."""

    measurement: Measurement
    y: torch.Tensor
    truth: np.ndarray
    shape: tuple[int, ...]
    metrics: dict[str, Any]
    noise_var: Any = None  #: the noise variance of each sample of ``y`` (m,), as the noise model states it


#: ``phi_stats: auto`` computes the effective rank and the coherence only while Φ has at most this
#: many entries: their SVD and Gram cost ~m N min(m, N) + N² m — at 32² (~0.8 M entries) a fraction
#: of a second, at 64² (13 M entries) more than the rest of a default Simulation 1 (BENCHMARKS.md)
PHI_STATS_FULL_MAX = 2**20


def phi_stats(mode: Any, phi: Any, shape: tuple[int, ...]) -> dict[str, Any]:
    """:func:`cssat.physics.sensing_stats` of ``phi`` as ``phi_stats`` says: ``true`` (all),
    ``false`` (none), ``auto`` (the mean, std and scintillation index always; the effective rank
    and the coherence of ΦΨ while Φ has at most :data:`PHI_STATS_FULL_MAX` entries)."""
    from cssat.physics import sensing_stats  # heavy: cssat.physics imports torch

    if mode not in (True, False, "auto"):
        raise FieldError("phi_stats", f"expected true, false or auto, got {mode!r}")
    if mode is False:
        return {}
    mat = phi.matrix() if hasattr(phi, "matrix") else phi
    full = mode is True or mat.numel() <= PHI_STATS_FULL_MAX
    return sensing_stats(mat, shape, full=full, max_rows=4096 if full else 1024)
