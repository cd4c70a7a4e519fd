"""The config of the ``forward: shadow`` model."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ShadowConfig"]


@dataclass
class ShadowConfig:
    """A silhouette through Fresnel diffraction onto a line of telescopes: a star's occultation by a
    satellite, ``y`` = the recorded series (:class:`cssat.experiments.forward.shadow.Shadow`).

    The model's settings are the experiment's ``star``, ``optics``, ``event``, ``array``,
    ``silhouette``, ``invert``, ``scenario``, ``model`` and ``attitude``, and the ``solver`` group's
    solver for the linearised model (each checked, with its full key, when the model is planned);
    its ``forward`` node names the model only."""

    _target_: str = "cssat.experiments.forward.shadow.Shadow"
