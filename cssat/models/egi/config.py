"""The config of the ``forward: egi`` model."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["EGIConfig"]


@dataclass
class EGIConfig:
    """The extended Gaussian image (areas over surface normals) through a scene and an attitude: a
    satellite's light curve, ``y_t = Σ_k G(t, k) a_k``
    (:class:`cssat.experiments.forward.egi.EGILightCurve`).

    The model's settings are the experiment's ``nights``, ``inversion``, ``model``, ``attitude``,
    ``brdf``, ``shadows``, ``noise``, ``scenario``, ``observations`` and ``observed`` (each checked,
    with its full key, when the model is planned); its ``forward`` node names the model only."""

    _target_: str = "cssat.experiments.forward.egi.EGILightCurve"
