"""The forward-model stage: the target's unknown measured as a light curve ``y = noise(Φ x)``.

A forward model (the ``forward`` group) declares the unknown — its truth and its shape — and
measures it through the ``atmosphere`` group's sensing operator, placed by the ``geometry`` group,
with the ``noise`` group's noise; the ``cs`` group says how many samples. Everything after it in
the pipeline (the operator estimate, the solver, the denoiser, the scores) is shared, so another
forward model — reflectance over surface normals, Fresnel shadows — is one class with the same
two methods and one typed config registered as ``forward/<name>`` (:mod:`cssat.models`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from cssat._checks import FieldError, dtype_param, float_param, int_param, opt
from cssat.experiments.context import Run, as_field
from cssat.experiments.forward.base import ForwardModel

if TYPE_CHECKING:
    import torch

    from cssat.physics import Measurement

__all__ = ["Geometry", "PixelSensing", "Measured", "measurements", "phi_stats"]

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


class PixelSensing(ForwardModel):
    """The paper's forward model (Eq. 12–15): the unknown is the target image ``x (n, n)``,
    ``N = n²`` pixels, each pixel's flux scaled per sample by the atmosphere's weights:
    ``y = noise(Φ x)``, ``Φ (m, N)`` drawn from ``seed``, the noise from ``seed + 1``.

    Its stages run the image pipeline (:mod:`cssat.experiments.pipeline`): one image
    (:class:`~cssat.experiments.pipeline.ImageRun`), or, when the config has a ``grid``, the list
    of its cells' configs (:class:`~cssat.experiments.grid.GridRun`); ``measure`` runs the
    operator estimate and the solves of every repeat and cell, each timed by its own stages. The
    sensing itself is :meth:`shape`, :meth:`precision`, :meth:`operator` and :meth:`sense`.

    ``dtype``: the precision of ``Φ``, ``x`` and ``y`` (null: the run's ``dtype``; ``float64``
    keeps the digits of a positive Φ's 1 % fluctuations, the system then centred in float64 and
    handed to the solver in the run's dtype). ``draw_dtype``: the dtype Φ is drawn in, then held
    exactly in ``dtype`` (Simulation 2: Simulation 1's float32 Φ held in float64). An operator
    estimate may ask for both (``reference=full_rank``).
    """

    name = "pixels"
    timed_inside = ("measure", "estimate", "solve")
    #: measure runs the operator estimate and the solves of every repeat (and every cell of a grid)
    needs = {"measure": ("plan",), "score": ("plan", "measure"), "write": ("plan", "measure", "score")}

    def __init__(self, dtype: str | None = None, draw_dtype: str | None = None):
        from cssat.models.pixels.config import PixelsConfig

        self.config = PixelsConfig(dtype=dtype, draw_dtype=draw_dtype)  # checked by its __post_init__
        self._precisions(self.config)

    def _precisions(self, config: Any) -> None:
        """``dtype`` and ``draw_dtype`` of ``config`` (checked) as torch dtypes."""
        self.dtype = opt(config.dtype, dtype_param, "forward.dtype")
        self.draw_dtype = opt(config.draw_dtype, dtype_param, "forward.draw_dtype")

    def shape(self, target: Any) -> tuple[int, int]:
        """The unknown's shape: the target image's ``(n, n)``."""
        return (target.size, target.size)

    def precision(self, run: Run, dtype: torch.dtype | None = None,
                  draw_dtype: torch.dtype | None = None) -> tuple[torch.dtype, torch.dtype | None]:
        """``(dtype, draw_dtype)`` of Φ and y: this model's settings, else an operator estimate's
        (``dtype``, ``draw_dtype``), else the run's dtype."""
        return self.dtype or dtype or run.dtype, self.draw_dtype or draw_dtype

    def operator(self, run: Run, atmosphere: Any, m: int, shape: tuple[int, ...], dtype: torch.dtype,
                 draw: torch.dtype | None = None) -> Any:
        """``Φ (m, N)`` of ``atmosphere`` for the unknown's ``shape``, drawn from the run's seed in
        ``draw`` (default ``dtype``) and held in ``dtype``."""
        from cssat.sparse import MatrixOperator  # heavy: cssat.sparse imports torch

        with as_field("atmosphere"):
            op = atmosphere.operator(m, math.prod(shape), seed=run.seed, dtype=draw or dtype, device=run.device)
        if draw is not None and draw != dtype:
            op = MatrixOperator(op.matrix().to(dtype))
        return op

    def plan(self, cfg: Any, run: Run) -> None:
        """Every stage of ``cfg`` built and checked before any work: one image, or every cell of its ``grid``."""
        from cssat.experiments.grid import GridRun  # heavy: cssat.experiments.grid imports torch and matplotlib
        from cssat.experiments.pipeline import ImageRun  # heavy: cssat.experiments.pipeline imports torch

        self.job = GridRun(cfg, run) if cfg.get("grid") is not None else ImageRun(cfg, run, self)

    def measure(self, run: Run) -> None:  # type: ignore[override]
        """The measurement, the operator estimate and the solves (of every cell of a grid)."""
        self.job.measure(run)

    def estimate(self, run: Run) -> None:
        """Estimated with each repeat's solve in :meth:`measure`."""

    def solve(self, run: Run) -> None:
        """Solved with the repeats of :meth:`measure`."""

    def score(self, run: Run) -> dict[str, Any]:
        return self.job.score(run)

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        self.job.write(run, metrics)

    def headline(self, metrics: dict[str, Any]) -> None:
        return self.job.headline(metrics)

    def sense(self, run: Run, truth: np.ndarray, operator: Any, noise: Any, dtype: torch.dtype) -> Measured:
        """Measure ``truth`` through ``operator`` (from :meth:`operator`) with ``noise``, seeded
        with the run's seed + 1, in ``dtype``."""
        import torch  # heavy: torch (~1 s); the module imports without it

        from cssat.physics import Measurement  # heavy: cssat.physics imports torch

        shape = tuple(truth.shape)
        meas = Measurement(operator, noise, seed=run.seed + 1, x_shape=shape)
        x = torch.as_tensor(truth, dtype=dtype, device=run.device).reshape(-1)
        with as_field("noise"):
            y = meas(x)
            try:
                var = meas.noise.variance(y, flux=x.sum())
            except FieldError:  # a noise model that does not state its variance
                var = None
        return Measured(meas, y, truth, shape, meas.describe(), var)


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
