"""The config of the ``forward: observed`` model."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ObservedConfig"]


@dataclass
class ObservedConfig:
    """A measured light curve: nothing simulated — the file's light curve read and cleaned, then its
    verdicts estimated (period, tumbling, spin)
    (:class:`cssat.experiments.forward.observed.Observed`).

    The model's settings are the experiment's ``observations``, ``observed``, ``stages``,
    ``characterise``, ``period``, ``tumbling``, ``scenario`` and ``catalogue`` (each checked, with
    its full key, when the model is planned); its ``forward`` node names the model only."""

    _target_: str = "cssat.experiments.forward.observed.Observed"
