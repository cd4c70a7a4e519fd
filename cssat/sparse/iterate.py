"""One loop for every iterative algorithm (sigpy's ``Alg``/``App``, pylops' setup/step/run).

An algorithm is an :class:`Iteration`: its state, set up by its constructor, one :meth:`~Iteration.step`
and the :meth:`~Iteration.objective` at the current state. :func:`run_iterations` owns everything
else, written once: the progress bar, the relative-change stop, the objective history, the
timing and the callbacks. A new algorithm is a class with a ``step``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Callable

import torch
from torch import Tensor

from cssat._progress import progress_bar

__all__ = ["Iteration", "RunInfo", "run_iterations", "relative_change"]

log = logging.getLogger("cssat")


class Iteration:
    """An iterative algorithm's state and step. ``label`` names it on the progress bar."""

    label = "iterations"

    def step(self, k: int) -> Tensor | None:  # pragma: no cover - abstract
        """Iteration ``k`` (from 1): update the state; return the relative change of the iterate per
        signal ``(B,)`` (for the stopping rule), or ``None`` when the algorithm has none."""
        raise NotImplementedError

    def objective(self) -> float:  # pragma: no cover - abstract
        """The objective at the current state (summed over the batch)."""
        raise NotImplementedError


@dataclass
class RunInfo:
    """``n_iter`` run, the ``objective`` history (every ``objective_every`` iterations and the
    first), whether the relative-change rule stopped it (``converged``) and ``seconds``."""

    n_iter: int
    objective: list = field(default_factory=list)
    converged: bool = False
    seconds: float = 0.0


def relative_change(new: Tensor, old: Tensor) -> Tensor:
    """``‖new − old‖ / ‖new‖`` per signal (rows of the flattened batch), ``(B,)``."""
    return (new - old).flatten(1).norm(dim=1) / new.flatten(1).norm(dim=1).clamp_min(torch.finfo(new.dtype).tiny)


def run_iterations(alg: Iteration, max_iter: int, *, rtol: float | None = None, progress: bool | None = None,
                   objective_every: int = 10, callback: Callable[[int, Iteration], bool | None] | None = None) -> RunInfo:
    """Run ``alg`` for at most ``max_iter`` iterations.

    After each step the objective is recorded when ``k == 1`` or ``k % objective_every == 0``;
    ``callback(k, alg)`` is called and stops the run when it returns ``True``; the run stops when
    the step's relative change is ``≤ rtol`` for every signal (``converged``). ``progress``: a tqdm
    bar of the iterations (``None``: on a terminal only, after a second).
    """
    t0 = time.perf_counter()
    info = RunInfo(0)
    bar = progress_bar(int(max_iter), alg.label, progress, unit="iter")
    for k in range(1, int(max_iter) + 1):
        bar.update()
        change = alg.step(k)
        info.n_iter = k
        if k % objective_every == 0 or k == 1:
            info.objective.append(alg.objective())
        if callback is not None and callback(k, alg):
            break
        if rtol is not None and change is not None and bool((change <= rtol).all()):
            info.converged = True
            break
    bar.close()
    info.seconds = time.perf_counter() - t0
    log.debug("%s: %d iterations, converged=%s, %.2f s", alg.label, info.n_iter, info.converged, info.seconds)
    return info
