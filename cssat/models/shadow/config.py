"""The config of the ``forward: shadow`` model and its settings.

The model's ``forward`` node names it only (:class:`ShadowConfig`); its own settings are the
experiment's top-level groups of :data:`ShadowConfig.SETTINGS`, each a typed dataclass here — the
single source of their keys and defaults — stored in Hydra's ConfigStore as the config
``shadow_settings`` (which ``conf/experiment/occultation.yaml`` includes):

=================  ==========================================================================
``star.*``         :class:`StarConfig`: the occulted star (position, magnitude, colour, the
                   true diameter and limb darkening)
``optics.*``       :class:`OpticsConfig`: the band the photons are counted in, the truth's
                   quadrature over it
``event.*``        :class:`EventConfig`: the prediction's errors, the true offsets, the oracle row
``array.*``        :class:`ArrayConfig`: the line of telescopes, the exposure, the noise, the
                   scintillation
``silhouette.*``   :class:`SilhouetteConfig`: the target and the inversion's and truth's grids
``invert.*``       :class:`InvertConfig`: the inversion (TV weight, iterations, the prior, the
                   assumed limb darkening, the star diameter's prior)
=================  ==========================================================================

The model's other groups — ``scenario``, ``model``, ``attitude`` and ``solver`` (the linear
route's) — are built and checked when it is planned, as are the checks that need the event's
geometry (the exposure against the shadow's speed, the memory). A key that is not a field is
refused when the config is composed (and by :func:`~cssat.models.observed.config.typed_group`
for a plain mapping: a :class:`~cssat._checks.FieldError` naming ``<group>.<key>``); each
dataclass checks its values in ``__post_init__`` and raises a :class:`~cssat._checks.FieldError`
naming the full key (``event.time_error_s``); :class:`ShadowSettings` checks what spans two
groups. This module imports no numpy or torch: Hydra imports it whenever it composes a config.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping, Optional

from cssat._checks import FieldError, choice_param, float_param, int_param, opt
from cssat.models.observed.config import settings_nodes, typed_settings

__all__ = ["ShadowConfig", "ShadowSettings", "StarConfig", "OpticsConfig", "EventConfig", "ArrayConfig", "SilhouetteConfig",
           "InvertConfig", "MAX_SILHOUETTE_M", "BANDS"]

#: the widest silhouette grid (m): silhouette.size × silhouette.pixel_m
MAX_SILHOUETTE_M = 1000.0
#: the bands of ``optics.band`` (None: monochromatic at ``optics.wavelength_m``)
BANDS = (None, "V", "R", "g", "r", "i", "clear")
_WHAT = "a setting of the occultation"


@dataclass
class StarConfig:
    """``star.*``: the occulted star."""

    WHAT: ClassVar[str] = _WHAT

    #: right ascension (deg, [0, 360]); null (with dec_deg): a star exactly behind the satellite at start_utc + 1 s
    ra_deg: Optional[float] = None
    #: declination (deg, [-90, 90]); null with ra_deg
    dec_deg: Optional[float] = None
    #: V (the catalogue's; the photon count)
    magnitude: float = 8.0
    #: B − V (the catalogue's, [-0.4, 2.2]): the spectrum's temperature (Ballesteros 2012), the band's weights
    bv: float = 1.1
    #: the TRUE angular diameter (mas; a K giant of V = 8: 0.35–0.8 mas); the inversion is not told
    diameter_mas: float = 0.5
    #: the TRUE linear limb-darkening coefficient u (a K giant in V); the inversion assumes invert.limb_darkening
    limb_darkening: float = 0.7

    def __post_init__(self) -> None:
        self.magnitude = float_param(self.magnitude, "star.magnitude", -30.0, 30.0)
        self.bv = float_param(self.bv, "star.bv", -0.4, 2.2)
        if (self.ra_deg is None) != (self.dec_deg is None):
            missing = "dec_deg" if self.dec_deg is None else "ra_deg"
            raise FieldError(f"star.{missing}", "give both star.ra_deg and star.dec_deg, or neither (a star exactly behind "
                                                "the satellite)")
        if self.ra_deg is not None:
            float_param(self.ra_deg, "star.ra_deg", 0.0, 360.0)
            float_param(self.dec_deg, "star.dec_deg", -90.0, 90.0)
        self.diameter_mas = float_param(self.diameter_mas, "star.diameter_mas", 0.0, 100.0)
        self.limb_darkening = float_param(self.limb_darkening, "star.limb_darkening", 0.0, 1.0)


@dataclass
class OpticsConfig:
    """``optics.*``: the band whose photons are counted and the truth's quadrature over it."""

    WHAT: ClassVar[str] = _WHAT

    #: V | R | g | r | i | clear: the pattern integrated over the band; null: monochromatic at wavelength_m
    band: Optional[str] = "V"
    #: the monochromatic case's wavelength (m; band: null)
    wavelength_m: float = 550e-9
    #: the truth's quadrature nodes over the band × the star's spectrum
    n_wavelengths: int = 8

    def __post_init__(self) -> None:
        choice_param(self.band, "optics.band", BANDS)
        self.wavelength_m = float_param(self.wavelength_m, "optics.wavelength_m", 1e-7, 3e-5)
        self.n_wavelengths = int_param(self.n_wavelengths, "optics.n_wavelengths", 1, 64)


@dataclass
class EventConfig:
    """``event.*``: the prediction's errors and the event's true nuisances."""

    WHAT: ClassVar[str] = _WHAT

    #: the predicted time's accuracy (s): the true offset drawn uniform within ± this
    time_error_s: float = 0.01
    #: the true time offset (s, [-1, 1]); null: drawn
    time_offset_s: Optional[float] = None
    #: the true cross-track offset of the path (m); null: drawn where the array still spans the silhouette
    path_offset_m: Optional[float] = None
    #: an element set's cross-track accuracy (m, 1σ; reported: the chance that the array catches the shadow)
    path_error_m: float = 1000.0
    #: the predicted shadow speed's relative error (1σ)
    speed_error: float = 1e-3
    #: true: every nuisance handed to the inversion (the labelled oracle row); false (checked when built: true | false)
    oracle: Any = False

    def __post_init__(self) -> None:
        self.time_error_s = float_param(self.time_error_s, "event.time_error_s", 0.0, 1.0)
        self.time_offset_s = opt(self.time_offset_s, float_param, "event.time_offset_s", -1.0, 1.0)
        self.path_offset_m = opt(self.path_offset_m, float_param, "event.path_offset_m", -1e4, 1e4)
        self.path_error_m = float_param(self.path_error_m, "event.path_error_m", 0.0, 1e7, open_lo=True)
        self.speed_error = float_param(self.speed_error, "event.speed_error", 0.0, 0.1)
        choice_param(self.oracle, "event.oracle", (False, True))


@dataclass
class ArrayConfig:
    """``array.*``: the line of telescopes on the ground and what each records."""

    WHAT: ClassVar[str] = _WHAT

    #: each telescope's aperture (m)
    aperture_m: float = 0.5
    #: ground metres between slots along the line; null: one aperture in the plane (≥ one on the ground)
    spacing_m: Optional[float] = None
    #: the slots along the line; null: as many as span the silhouette's grid
    n_slots: Optional[int] = None
    #: the share of slots with a telescope (random, seeded)
    fill: float = 0.25
    #: one exposure (s)
    exposure_s: float = 2e-4
    #: the share of the star's photons counted, (0, 1]
    throughput: float = 0.5
    #: the read noise (electrons per exposure)
    read_noise_e: float = 1.0
    #: frozen: a gain per telescope from the turbulence model + the white rest; white: per exposure only; none
    #: (true: frozen, false: none)
    scintillation: Any = "frozen"

    def __post_init__(self) -> None:
        self.aperture_m = D = float_param(self.aperture_m, "array.aperture_m", 0.0, open_lo=True)
        self.spacing_m = opt(self.spacing_m, float_param, "array.spacing_m", 0.0, open_lo=True)
        if self.spacing_m is not None and self.spacing_m < D:
            raise FieldError("array.spacing_m", f"{self.spacing_m:g} m on the ground is less than one aperture ({D:g} m): "
                                                "the telescopes would stand inside each other")
        self.fill = float_param(self.fill, "array.fill", 0.0, 1.0, open_lo=True)
        self.exposure_s = float_param(self.exposure_s, "array.exposure_s", 0.0, open_lo=True)
        self.throughput = float_param(self.throughput, "array.throughput", 0.0, 1.0, open_lo=True)
        self.read_noise_e = float_param(self.read_noise_e, "array.read_noise_e", 0.0, 1e6)
        scint = self.scintillation
        scint = {True: "frozen", False: "none"}.get(scint, scint) if isinstance(scint, bool) else scint
        self.scintillation = choice_param(scint, "array.scintillation", ("frozen", "white", "none"))
        self.n_slots = opt(self.n_slots, int_param, "array.n_slots", 1, 100000)


@dataclass
class SilhouetteConfig:
    """``silhouette.*``: the target and the grids of the truth and of the inversion."""

    WHAT: ClassVar[str] = _WHAT

    #: model: the model's silhouette in its attitude; bars: a resolution target (bar_m bars and gaps)
    target: str = "model"
    #: the bars' and gaps' width (m; target: bars)
    bar_m: float = 0.5
    #: the inversion's pixels a side
    size: int = 128
    #: the inversion's pixel (m); size × pixel_m ≤ 1000 m
    pixel_m: float = 0.2
    #: the truth on a grid this much finer (0.05 m): no shared pixel basis
    truth_oversample: int = 4
    #: the shadow's grid as a multiple of the silhouette's, centred on it
    ground: float = 1.25

    def __post_init__(self) -> None:
        self.size = size = int_param(self.size, "silhouette.size", 8, 4096)
        self.pixel_m = pixel = float_param(self.pixel_m, "silhouette.pixel_m", 0.0, open_lo=True)
        self.truth_oversample = int_param(self.truth_oversample, "silhouette.truth_oversample", 1, 16)
        self.ground = float_param(self.ground, "silhouette.ground", 1.0, 8.0)
        self.bar_m = float_param(self.bar_m, "silhouette.bar_m", 0.0, open_lo=True)
        choice_param(self.target, "silhouette.target", ("model", "bars"))
        if size * pixel > MAX_SILHOUETTE_M:
            raise FieldError("silhouette.pixel_m", f"{pixel:g} m × {size} pixels is a {size * pixel:.3g} m silhouette, more than "
                                                   f"{MAX_SILHOUETTE_M:g} m: a satellite is metres to tens of metres across")

    @property
    def width_m(self) -> float:
        """The silhouette's grid (m): ``size × pixel_m``."""
        return self.size * self.pixel_m


@dataclass
class InvertConfig:
    """``invert.*``: the inversion of the recorded series (:func:`cssat.occultation.invert_event`)."""

    WHAT: ClassVar[str] = _WHAT

    #: linear: the solver group's solver on the linearised model first; empty: from the empty mask
    init: str = "linear"
    #: the non-linear fit's TV weight (per √pixels, the data term per sample)
    tv: float = 0.3
    #: the non-linear fit's iterations
    iters: int = 300
    #: silhouette ↔ nuisances rounds
    rounds: int = 2
    #: the inversion's quadrature nodes over the band (the truth's: optics.n_wavelengths)
    n_wavelengths: int = 4
    #: the inversion's assumed limb-darkening coefficient u (not fitted)
    limb_darkening: float = 0.6
    #: the star's diameter: a uniform prior on [0, this] (mas), fixed at its mean (red giants reach 2 mas;
    #: not measured: docs/guides/occultation.md)
    diameter_max_mas: float = 3.0
    #: the diagnostic χ² profile's grid over that prior
    n_diameters: int = 7
    #: auto: pixels (TV) or a union of superellipses, the one held-out telescopes prefer; pixels; shapes
    prior: str = "auto"
    #: the shape prior's iterations
    shape_iters: int = 200
    #: the inversion's grid: the silhouette's and this margin (m) each side (the offset is not known)
    margin_m: float = 1.6
    #: the feature size (m) whose contrast is scored (thin_contrast, gap_contrast); null: bar_m for bars, else 0.5
    feature_m: Optional[float] = None

    def __post_init__(self) -> None:
        self.n_wavelengths = int_param(self.n_wavelengths, "invert.n_wavelengths", 1, 64)
        self.limb_darkening = float_param(self.limb_darkening, "invert.limb_darkening", 0.0, 1.0)
        self.diameter_max_mas = float_param(self.diameter_max_mas, "invert.diameter_max_mas", 0.0, 100.0)
        self.n_diameters = int_param(self.n_diameters, "invert.n_diameters", 1, 200)
        choice_param(self.init, "invert.init", ("linear", "empty"))
        choice_param(self.prior, "invert.prior", ("auto", "pixels", "shapes"))
        self.tv = float_param(self.tv, "invert.tv", 0.0)
        self.iters = int_param(self.iters, "invert.iters", 1, 10**6)
        self.rounds = int_param(self.rounds, "invert.rounds", 1, 20)
        self.margin_m = float_param(self.margin_m, "invert.margin_m", 0.0, 100.0)
        self.shape_iters = int_param(self.shape_iters, "invert.shape_iters", 1, 10**6)
        self.feature_m = opt(self.feature_m, float_param, "invert.feature_m", 0.0, open_lo=True)


@dataclass
class ShadowSettings:
    """Every setting of the ``shadow`` model's own groups, typed (:meth:`from_config`), and the
    checks that span two of them."""

    star: StarConfig = field(default_factory=StarConfig)
    optics: OpticsConfig = field(default_factory=OpticsConfig)
    event: EventConfig = field(default_factory=EventConfig)
    array: ArrayConfig = field(default_factory=ArrayConfig)
    silhouette: SilhouetteConfig = field(default_factory=SilhouetteConfig)
    invert: InvertConfig = field(default_factory=InvertConfig)

    def __post_init__(self) -> None:
        D, sil = self.array.aperture_m, self.silhouette
        if D > sil.width_m * sil.ground:
            raise FieldError("array.aperture_m", f"{D:g} m is wider than the ground grid ({sil.width_m * sil.ground:g} m: "
                                                 "silhouette.size × pixel_m × ground): the aperture would average the whole shadow away")

    @property
    def size_inv(self) -> int:
        """The inversion's grid (pixels a side): the silhouette's and ``invert.margin_m`` each side."""
        return self.silhouette.size + 2 * int(round(self.invert.margin_m / self.silhouette.pixel_m))

    @property
    def feature_m(self) -> float:
        """The feature size scored: ``invert.feature_m``, else the bars' width for a bar target, else 0.5 m."""
        if self.invert.feature_m is not None:
            return self.invert.feature_m
        return self.silhouette.bar_m if self.silhouette.target == "bars" else 0.5

    @property
    def row(self) -> str:
        """The row's label: what is idealised (``realistic``: nothing)."""
        idealised = [k for k, on in (("oracle", self.event.oracle), ("monochromatic", self.optics.band is None),
                                     ("white scintillation", self.array.scintillation == "white"),
                                     ("no scintillation", self.array.scintillation == "none")) if on]
        return " + ".join(idealised) or "realistic"

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "ShadowSettings":
        """The settings of ``cfg`` (a composed config or a plain mapping of the groups), each group
        built and checked (a :class:`FieldError` naming its full key; a key that is not a setting:
        ``<group>.<key>``); a group or key left out takes its default."""
        return typed_settings(cls, cfg)


@dataclass
class ShadowConfig:
    """A silhouette through Fresnel diffraction onto a line of telescopes: a star's occultation by a
    satellite, ``y`` = the recorded series (:class:`cssat.experiments.forward.shadow.Shadow`).

    The ``forward`` node names the model only; its settings are the experiment's top-level groups
    of :data:`SETTINGS` (``star``, ``optics``, ``event``, ``array``, ``silhouette``, ``invert``:
    :class:`ShadowSettings`, typed and checked with their full keys) and its ``scenario``,
    ``model`` and ``attitude`` groups and the ``solver`` group's solver for the linearised model
    (checked when the model is planned)."""

    _target_: str = "cssat.experiments.forward.shadow.Shadow"
    #: the top-level groups the model reads: key → its typed config (:class:`ShadowSettings`' fields: one set of defaults)
    SETTINGS: ClassVar[dict[str, Any]] = settings_nodes(ShadowSettings)
