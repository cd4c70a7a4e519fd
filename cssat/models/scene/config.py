"""The config of the ``forward: scene`` model and its settings.

The model's ``forward`` node names it only (:class:`SceneConfig`); its own settings are the
experiment's top-level keys of :data:`SceneConfig.SETTINGS` — the single source of their keys
and defaults, stored in Hydra's ConfigStore as the config ``scene_settings`` (which
``conf/experiment/lightcurve.yaml`` includes):

==================  =========================================================================
``render.*``        :class:`RenderConfig`: the renders' size, field of view, marked images
``shadows``         self- and observer-shadowing by ray casting (true)
``earthshine``      the sunlight the Earth reflects onto the facets: ``auto`` (on below
                    20,000 km) | true | false
``earth_albedo``    the Earth's Lambertian albedo for earthshine, in [0, 1] (0.3)
``magnitudes.*``    :class:`MagnitudesConfig`: the band of the simulated magnitudes
``observations``    a measured light curve to simulate on (a path; null: none)
``observed.*``      how to read it (:class:`~cssat.models.observed.config.ReadConfig`)
==================  =========================================================================

The model's other groups — ``model``, ``attitude``, ``brdf``, ``geometry``, ``atmosphere``,
``noise`` (objects with a ``_target_``) and ``scenario`` (shared with the inversion
experiments) — are built and checked when it is planned. :class:`SceneSettings` checks the
top-level scalars in ``__post_init__`` (a :class:`~cssat._checks.FieldError` naming the key).
This module imports no numpy or torch: Hydra imports it whenever it composes a config.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping, Optional

from cssat._checks import bool_param, choice_param, float_param, int_param
from cssat.models.observed.config import ReadConfig, settings_nodes, typed_settings

__all__ = ["SceneConfig", "SceneSettings", "RenderConfig", "MagnitudesConfig"]


@dataclass
class RenderConfig:
    """``render.*``: the images rendered of the mesh."""

    #: pixels per side
    size: int = 128
    #: field of view (m); null = the model's bounding sphere
    fov_m: Optional[float] = None
    #: rendered images marked on the light curve
    n_images: int = 5

    def __post_init__(self) -> None:
        int_param(self.size, "render.size", 1, 4096)
        if self.fov_m is not None:
            float_param(self.fov_m, "render.fov_m", 0.0, open_lo=True)
        int_param(self.n_images, "render.n_images", 1, 20)


@dataclass
class MagnitudesConfig:
    """``magnitudes.*``: the band of the simulated magnitudes (lightcurve.csv, figures); the band
    itself is checked when the model is planned (:func:`cssat.optics.passbands.resolve_band`)."""

    #: null: V with the Sun at -26.74; V | R | g | r | i | clear | a filter file (lambda_nm T)
    band: Optional[str] = None
    #: Vega | AB (clear and filter files: AB)
    system: str = "Vega"


@dataclass
class SceneSettings:
    """Every setting of the ``scene`` model's own keys, typed (:meth:`from_config`)."""

    render: RenderConfig = field(default_factory=RenderConfig)
    #: self- and observer-shadowing by ray casting
    shadows: bool = True
    #: the sunlight the Earth reflects onto the facets: auto (on below 20,000 km; at GEO ~5e-5 of the flux) | true | false
    earthshine: Any = "auto"
    #: the Earth's Lambertian albedo for earthshine, in [0, 1]
    earth_albedo: float = 0.3
    magnitudes: MagnitudesConfig = field(default_factory=MagnitudesConfig)
    #: a measured light curve (a path): simulate on its time stamps, plot it beside the simulation
    observations: Any = None
    #: how to read it (cssat.data.read_light_curve)
    observed: ReadConfig = field(default_factory=ReadConfig)

    def __post_init__(self) -> None:
        bool_param(self.shadows, "shadows")
        choice_param(self.earthshine, "earthshine", [True, False, "auto"])
        self.earth_albedo = float_param(self.earth_albedo, "earth_albedo", 0.0, 1.0)

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "SceneSettings":
        """The settings of ``cfg`` (a composed config or a plain mapping), each group built and
        checked (a :class:`FieldError` naming its full key); a key left out takes its default."""
        return typed_settings(cls, cfg)


@dataclass
class SceneConfig:
    """A mesh in a scenario, measured as its light curve and through the atmosphere over its facets and
    its rendered pixels (paper Fig. 4–5) (:class:`cssat.experiments.forward.scene.SceneLightCurve`).

    The ``forward`` node names the model only; its settings are the experiment's top-level keys
    of :data:`SETTINGS` and its ``model``, ``attitude``, ``brdf``, ``geometry``, ``atmosphere``,
    ``noise`` and ``scenario`` groups."""

    _target_: str = "cssat.experiments.forward.scene.SceneLightCurve"
    #: the top-level keys the model reads: key → its typed config (a dataclass) or its default
    #: (:class:`SceneSettings`' fields: one set of defaults)
    SETTINGS: ClassVar[dict[str, Any]] = settings_nodes(SceneSettings)
