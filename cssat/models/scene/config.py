"""The config of the ``forward: scene`` model."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SceneConfig"]


@dataclass
class SceneConfig:
    """A mesh in a scenario, measured as its light curve and through the atmosphere over its facets and
    its rendered pixels (paper Fig. 4–5) (:class:`cssat.experiments.forward.scene.SceneLightCurve`).

    The model's settings are the experiment's ``model``, ``scenario``, ``render``, ``shadows``,
    ``earthshine``, ``magnitudes``, ``attitude``, ``brdf``, ``geometry``, ``atmosphere``, ``noise``,
    ``observations`` and ``observed`` (each checked, with its full key, when the model is planned);
    its ``forward`` node names the model only."""

    _target_: str = "cssat.experiments.forward.scene.SceneLightCurve"
