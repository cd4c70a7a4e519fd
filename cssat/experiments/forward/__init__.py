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
from typing import TYPE_CHECKING, Any

import numpy as np

from cssat._checks import FieldError, dtype_param, opt
from cssat.experiments.context import Run, as_field
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.sensing import (ARCSEC, PHI_STATS_FULL_MAX, Geometry, Measured,  # noqa: F401  (re-exported)
                                               measurements, phi_stats)

if TYPE_CHECKING:
    import torch


__all__ = ["Geometry", "PixelSensing", "Measured", "measurements", "phi_stats"]


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
        from cssat.models.pixels.config import PixelsConfig  # local: the typed configs' package, only to build one

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

    def plan(self, cfg: Any, run: Run) -> Any:
        """Every stage of ``cfg`` built and checked before any work: one image
        (:class:`~cssat.experiments.pipeline.ImageRun`) or every cell of its ``grid``
        (:class:`~cssat.experiments.grid.GridRun`) — the job the later stages run."""
        from cssat.experiments.grid import GridRun  # heavy: cssat.experiments.grid imports torch and matplotlib
        from cssat.experiments.pipeline import ImageRun  # heavy: cssat.experiments.pipeline imports torch

        return GridRun(cfg, run) if cfg.get("grid") is not None else ImageRun(cfg, run, self)

    def measure(self, run: Run) -> Any:  # type: ignore[override]
        """The measurement, the operator estimate and the solves (of every cell of a grid)."""
        return run.result("plan").measure(run)

    def estimate(self, run: Run) -> None:
        """Estimated with each repeat's solve in :meth:`measure`."""

    def solve(self, run: Run) -> None:
        """Solved with the repeats of :meth:`measure`."""

    def score(self, run: Run) -> dict[str, Any]:
        return run.result("plan").score(run, run.result("measure"))

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        run.result("plan").write(run, run.result("measure"), metrics)

    def headline(self, metrics: dict[str, Any], run: Run) -> None:
        return run.result("plan").headline(metrics)

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


