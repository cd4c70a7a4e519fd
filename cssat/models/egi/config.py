"""The config of the ``forward: egi`` model and its settings.

The model's ``forward`` node names it only (:class:`EGIConfig`); its own settings are the
experiment's top-level keys of :data:`EGIConfig.SETTINGS` — the single source of their keys and
defaults, stored in Hydra's ConfigStore as the config ``egi_settings`` (which
``conf/experiment/inversion.yaml`` includes):

==================  =========================================================================
``nights.*``        :class:`NightsConfig`: the nights observed, fitted and held out
``inversion.*``     :class:`InversionConfig`: the attitude search, the EGI, the assumed
                    surface, the shape fitted after it (``inversion.parametric.*``:
                    :class:`ParametricConfig`), the tumbling search's options
``shadows``         the simulated truth's self-shadowing by ray casting (true)
``shadow_resolution_m``  rays that far apart on each facet (m; null: one from its centroid)
``observations``    a measured light curve to invert (a path; null: simulate)
``observed.*``      how to read it (:class:`~cssat.models.observed.config.ReadConfig`)
==================  =========================================================================

The model's other groups — ``model``, ``attitude``, ``brdf``, ``noise``, ``solver`` (objects
with a ``_target_``) and ``scenario`` — are built and checked when it is planned. Each dataclass
checks its values in ``__post_init__`` (a :class:`~cssat._checks.FieldError` naming the full
key). This module imports no numpy or torch: Hydra imports it whenever it composes a config.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Dict, Mapping, Optional

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param
from cssat.models.observed.config import ReadConfig, settings_nodes, typed_group, typed_settings

__all__ = ["EGIConfig", "EGISettings", "NightsConfig", "InversionConfig", "ParametricConfig", "SPIN_MODES",
           "SEARCH_KEYS"]

#: ``inversion.spin``: how the attitude is had
SPIN_MODES = ("auto", "search", "tumbling", "known")
#: the spin search's settings (:func:`cssat.inversion.estimate_spin`'s keywords) in ``inversion``
SEARCH_KEYS = ("n_poles", "n_starts", "n_refine", "coarse_normals", "coarse_samples", "max_samples", "min_period_s",
               "max_period_s", "split_nights", "error_grids", "bootstrap", "local_starts")
_SOLVER_HINT = ("the EGI's solve is the solver group's: solver=nnls|nnomp|nnl1|nntv "
                "(e.g. solver=nntv solver.lam=discrepancy)")


@dataclass
class NightsConfig:
    """``nights.*``: the ground station's nights."""

    #: nights observed (a simulation spans nights.n days from scenario.start_utc)
    n: int = 3
    #: the first nights fitted (null: all but the last); the others held out and predicted
    fit: Optional[int] = None
    #: a night: the Sun below this at the station (°; -12: nautical twilight)
    sun_alt_max_deg: float = -12.0
    #: the object above this (°)
    min_elevation_deg: float = 20.0

    def __post_init__(self) -> None:
        self.n = int_param(self.n, "nights.n", 1, 366)
        self.fit = None if self.fit is None else int_param(self.fit, "nights.fit", 1, 366)
        self.sun_alt_max_deg = float_param(self.sun_alt_max_deg, "nights.sun_alt_max_deg", -90.0, 90.0)
        self.min_elevation_deg = float_param(self.min_elevation_deg, "nights.min_elevation_deg", -90.0, 90.0)


def _aspects(v: Any) -> list[float]:
    """``inversion.parametric.aspects``: a non-empty list of wing aspects in (0, 100]."""
    one = isinstance(v, (int, float, str)) and not isinstance(v, bool)
    try:
        out = [float(x) for x in ([v] if one else list(v))]
    except (TypeError, ValueError) as e:
        raise FieldError("inversion.parametric.aspects", f"expected a list of wing aspects (length ÷ width) in "
                                                         f"(0, 100], e.g. [2, 3.75, 6], got {v!r}") from e
    if not out or not all(0.0 < x <= 100.0 for x in out):
        raise FieldError("inversion.parametric.aspects", f"expected a non-empty list of wing aspects (length ÷ width) "
                                                         f"in (0, 100], e.g. [2, 3.75, 6], got {v!r}")
    return out


@dataclass
class ParametricConfig:
    """``inversion.parametric.*``: the box-wing fitted after the EGI for ``inversion.shape:
    parametric`` (:func:`cssat.inversion.parametric_fit.fit_box_wing`) and, with parts asked for
    (``dishes``, ``wing_panels``, ``booms``, ``deck``), the finer family from it
    (:func:`cssat.inversion.parametric_parts.fit_parts`)."""

    WHAT: ClassVar[str] = "a setting of the box-wing fit"

    #: 1 | 2: one panel at +y or a mirror pair at ±y
    panels: int = 2
    #: sub-facets a side per face, each with its own ray-cast visibility (1–16)
    divisions: int = 4
    #: visibility recasts (each followed by L-BFGS steps with it fixed)
    outer: int = 6
    #: L-BFGS iterations per recast
    inner: int = 40
    #: soft-L1 scale of the noise-normalised residuals (glints beyond it count linearly)
    huber: float = 3.0
    #: the albedo prior the start's sizes use (flux ∝ albedo × area: an assumption, 0.1–0.8)
    cd0: float = 0.3
    #: cast (Embree visibility held fixed in each L-BFGS run) | soft (differentiable shadows, annealed)
    visibility: str = "cast"
    #: with visibility soft: the shadows' first edge softness, × the start's mean bus half-size
    softness: float = 0.1
    #: the box-wing's turn about the body z axis: auto (from the EGI when the spin was searched, else none) | egi | none
    yaw: str = "auto"
    #: with several turns: each candidate's start fitted for this many L-BFGS steps and the turns told apart by
    #: that brief fit's loss (0: by the start's own misfit, which can take a quarter turn on a bus heavier than
    #: its panels)
    yaw_brief: int = 10
    #: the plain box-wing's starts: its wings' aspects (length ÷ width; each with every turn of `yaw`), told apart
    #: by the brief fit of yaw_brief steps (the wings' aspect is not in the convex EGI)
    aspects: Any = field(default_factory=lambda: [3.75])
    #: the best plain_keep starts fitted in full, the lowest loss kept (a multi-start: 1, the best start only)
    plain_keep: int = 1
    #: with a searched spin: refine the pole, phase and period through the fitted box-wing's soft-shadowed light curve
    #: jointly with its shape (cssat.inversion.parametric_spin.refine_spin; the held-out nights give its verdict)
    refine_spin: bool = False
    #: with refine_spin: the spin refined from the family's twin too (the same object turned 180° about the pole,
    #: cssat.inversion.parametric.box_wing_twin; panels 2), the lower fitted loss kept (the model's shadows differ
    #: between the twins, so the two descents can end in different minima)
    spin_twin: bool = True
    #: fit (by gradient, with the geometry) | profile (solved by least squares at every evaluation: the light curve
    #: is linear in them)
    albedos: str = "fit"
    #: hold the bus albedo at cd0: the absolute size then comes from that prior (scaling every length by s and every
    #: albedo by 1/s² gives the same light curve, shadows included)
    albedo_prior: bool = False
    #: the finer family (cssat.inversion.parametric_parts.fit_parts, after the plain box-wing): reflector dishes
    #: 0 | 1 | 2 on the bus (a topology given, not searched)
    dishes: int = 0
    #: with 2 dishes: mirror (mirror images through the y-z plane) | free (the second dish its own place and size)
    dish_pair: str = "mirror"
    #: panels a wing (1-32; more than one: separated by a fitted gap)
    wing_panels: int = 1
    #: a square boom from the bus to each wing's root
    booms: bool = False
    #: an Earth-deck box on the bus's +z face
    deck: bool = False
    #: the finer family's starts fitted in full after their brief fits, the lowest loss kept (a multi-start; 1: the
    #: best brief only — the brief fits' ranking can miss the basin: BENCHMARKS.md "An oracle start")
    parts_keep: int = 1
    #: with dish_pair free: the two dishes started at every pairing of the generic placements (3 x 3 starts) instead
    #: of as mirror images (3)
    parts_pairs: bool = False
    #: where the finer family's parts are started: fit (on the plain box-wing's fit) | start (on its start from the
    #: EGI, unfitted) | both (each base's best parts_keep briefs fitted in full, the lowest loss kept). The plain
    #: fit has no dishes and bends its bus and wings to carry their light, and the parts' fit can stay in that basin
    #: (BENCHMARKS.md "The parts started from the EGI's box-wing")
    parts_from: str = "both"
    #: a dish's cells: rings x segments (the benchmarks' 4 x 16; each cell has its own ray-cast visibility)
    dish_rings: int = 4
    dish_segments: int = 16
    #: the model's shadows resolved below a sub-facet (m; null: one ray a sub-facet): after the fit, a polish of
    #: `resolved_outer` recasts with each sub-facet's lit fraction from rays this far apart, which the scored and
    #: predicted light curve then uses (with refine_spin, its defect correction and verdict too)
    shadow_resolution_m: Optional[float] = None
    #: the polish's recasts (with shadow_resolution_m)
    resolved_outer: int = 3
    #: with shadow_resolution_m: every stage's scored model resolved too (the plain fit, the parts' brief and full
    #: fits), not only the polish — dearer
    resolved_search: bool = False

    def __post_init__(self) -> None:
        self.panels = int_param(self.panels, "inversion.parametric.panels", 1, 2)
        self.divisions = int_param(self.divisions, "inversion.parametric.divisions", 1, 16)
        self.outer = int_param(self.outer, "inversion.parametric.outer", 1, 50)
        self.inner = int_param(self.inner, "inversion.parametric.inner", 1, 500)
        self.huber = float_param(self.huber, "inversion.parametric.huber", 0.0, open_lo=True)
        self.cd0 = float_param(self.cd0, "inversion.parametric.cd0", 0.0, 1.0, open_lo=True)
        self.visibility = choice_param(self.visibility, "inversion.parametric.visibility", ("cast", "soft"))
        self.softness = float_param(self.softness, "inversion.parametric.softness", 0.0, open_lo=True)
        self.yaw = choice_param(self.yaw, "inversion.parametric.yaw", ("auto", "egi", "none"))
        self.yaw_brief = int_param(self.yaw_brief, "inversion.parametric.yaw_brief", 0, 500)
        self.aspects = _aspects(self.aspects)
        self.plain_keep = int_param(self.plain_keep, "inversion.parametric.plain_keep", 1, 64)
        self.albedos = choice_param(self.albedos, "inversion.parametric.albedos", ("fit", "profile"))
        self.albedo_prior = bool_param(self.albedo_prior, "inversion.parametric.albedo_prior")
        self.refine_spin = bool_param(self.refine_spin, "inversion.parametric.refine_spin")
        self.spin_twin = bool_param(self.spin_twin, "inversion.parametric.spin_twin")
        self.dishes = int_param(self.dishes, "inversion.parametric.dishes", 0, 2)
        self.dish_pair = choice_param(self.dish_pair, "inversion.parametric.dish_pair", ("mirror", "free"))
        if self.dish_pair == "free" and self.dishes != 2:
            raise FieldError("inversion.parametric.dish_pair", f"'free' needs inversion.parametric.dishes=2, got {self.dishes}")
        self.wing_panels = int_param(self.wing_panels, "inversion.parametric.wing_panels", 1, 32)
        self.booms = bool_param(self.booms, "inversion.parametric.booms")
        self.deck = bool_param(self.deck, "inversion.parametric.deck")
        self.parts_keep = int_param(self.parts_keep, "inversion.parametric.parts_keep", 1, 64)
        self.parts_pairs = bool_param(self.parts_pairs, "inversion.parametric.parts_pairs")
        if self.parts_pairs and (self.dishes != 2 or self.dish_pair != "free"):
            raise FieldError("inversion.parametric.parts_pairs", "needs inversion.parametric.dishes=2 and dish_pair=free "
                             f"(got dishes={self.dishes}, dish_pair={self.dish_pair})")
        self.parts_from = choice_param(self.parts_from, "inversion.parametric.parts_from", ("fit", "start", "both"))
        self.dish_rings = int_param(self.dish_rings, "inversion.parametric.dish_rings", 1, 64)
        self.dish_segments = int_param(self.dish_segments, "inversion.parametric.dish_segments", 3, 256)
        if self.shadow_resolution_m is not None:
            self.shadow_resolution_m = float_param(self.shadow_resolution_m, "inversion.parametric.shadow_resolution_m",
                                                   0.0, open_lo=True)
        self.resolved_outer = int_param(self.resolved_outer, "inversion.parametric.resolved_outer", 1, 50)
        self.resolved_search = bool_param(self.resolved_search, "inversion.parametric.resolved_search")
        if self.resolved_search and self.shadow_resolution_m is None:
            raise FieldError("inversion.parametric.resolved_search", "needs inversion.parametric.shadow_resolution_m")

    def parts(self) -> dict[str, Any]:
        """The finer family's parts asked for (:func:`~cssat.inversion.parametric.param_names`'
        keywords), only those away from the plain box-wing: ``{}`` for the plain one."""
        out: dict[str, Any] = {}
        if self.dishes:
            out.update(dishes=self.dishes, **({"dish_pair": "free"} if self.dish_pair == "free" else {}))
        if self.wing_panels > 1:
            out["wing_panels"] = self.wing_panels
        out.update({k: True for k in ("booms", "deck") if getattr(self, k)})
        return out

    def family(self) -> dict[str, Any]:
        """The keywords of the family's functions (``box_wing_*``, ``fit_box_wing``, ``refine_spin``):
        ``panels``, ``divisions``, the parts and, with dishes, their cells."""
        cells = dict(dish_rings=self.dish_rings, dish_segments=self.dish_segments) if self.dishes else {}
        return dict(panels=self.panels, divisions=self.divisions, **self.parts(), **cells)


@dataclass
class InversionConfig:
    """``inversion.*``: the attitude, the EGI and the shape. The search's keys
    (:data:`SEARCH_KEYS`) are :func:`~cssat.inversion.estimate_spin`'s; ``tumbling`` holds
    :func:`~cssat.inversion.estimate_tumbling`'s options (checked by it when planned)."""

    WHAT: ClassVar[str] = "a setting of the inversion"
    #: keys that moved to another group: key → where
    MOVED: ClassVar[Dict[str, str]] = {k: _SOLVER_HINT for k in ("method", "lam", "n_nonzero", "tv_neighbours")}

    #: auto (search a spin attitude or a file as a spin, a tumbling attitude's torque-free state) |
    #: search | tumbling | known (the true attitude: an oracle)
    spin: str = "auto"
    #: the EGI's Fibonacci grid (the final fit)
    n_normals: int = 2000
    #: the spin search's fine stage
    search_normals: int = 1000
    #: the surface assumed: lambert | lobes (an EGI per scattering lobe) | simulated (the brdf group's: an oracle)
    brdf: str = "lambert"
    #: for brdf: lobes, the specular lobes' Blinn–Phong exponents (100: ~7° half width)
    lobes: Any = field(default_factory=lambda: [100])
    #: weight of Σ a n = 0 (given to the solver)
    closure: float = 1.0
    #: the spin search (cssat.inversion.estimate_spin)
    n_poles: int = 60
    n_starts: int = 6
    n_refine: int = 2
    coarse_normals: int = 200
    coarse_samples: int = 400
    max_samples: int = 1200
    #: the period search's range (s; keep min above 4 × the cadence)
    min_period_s: float = 120.0
    max_period_s: float = 3000.0
    #: a diagnostic: the spin also searched on each night alone, the spread of their poles reported
    split_nights: bool = False
    #: grids of normals turned at random (refined, with the bootstrap) whose RMS shift of the solution is the EGI grid's bias in the
    #: pole's 1σ (one refinement each; one shift alone is a single draw, often far below the spread)
    error_grids: int = 1
    #: parametric-bootstrap refits for the noise's part of the pole's 1σ when reliable (0: the profile region's)
    bootstrap: int = 0
    #: refinements of the solution (and of each bootstrap refit) from poles 2 and 4° about it, the lowest kept (0: one)
    local_starts: int = 0
    #: the shape fitted after the EGI: convex (the EGI's Minkowski polytope) | parametric (a shadowed box-wing)
    shape: str = "convex"
    parametric: ParametricConfig = field(default_factory=ParametricConfig)
    #: options of cssat.inversion.estimate_tumbling (e.g. arc_s, n_poles, inertia_grid): its defaults for the rest
    tumbling: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.spin = choice_param(self.spin, "inversion.spin", SPIN_MODES)
        self.n_normals = int_param(self.n_normals, "inversion.n_normals", 16, 20000)
        self.search_normals = int_param(self.search_normals, "inversion.search_normals", 16, 20000)
        self.brdf = choice_param(self.brdf, "inversion.brdf", ["lambert", "lobes", "simulated"])
        self.closure = float_param(self.closure, "inversion.closure", 0.0)
        self.error_grids = int_param(self.error_grids, "inversion.error_grids", 1, 64)
        self.bootstrap = int_param(self.bootstrap, "inversion.bootstrap", 0, 1000)
        self.local_starts = int_param(self.local_starts, "inversion.local_starts", 0, 8)
        self.shape = choice_param(self.shape, "inversion.shape", ("convex", "parametric"))
        self.parametric = typed_group(ParametricConfig, self.parametric, "inversion.parametric")
        if self.parametric.refine_spin and (self.shape != "parametric" or self.spin in ("known", "tumbling")):
            raise FieldError("inversion.parametric.refine_spin", "refines a searched spin through the fitted box-wing: "
                                                                 "needs inversion.shape=parametric and inversion.spin "
                                                                 f"search or auto, got shape={self.shape}, spin={self.spin}")
        if self.shape != "parametric":  # a setting of a fit that will not run would be ignored without a word
            default = ParametricConfig()
            for f in fields(ParametricConfig):
                if getattr(self.parametric, f.name) != getattr(default, f.name):
                    raise FieldError(f"inversion.parametric.{f.name}", "a setting of the parametric shape fit, which runs "
                                                                       "only with inversion.shape=parametric, got "
                                                                       f"shape={self.shape}")
        self.tumbling = dict(self.tumbling or {})

    def search(self) -> dict[str, Any]:
        """The spin search's keywords (:data:`SEARCH_KEYS`; a null one left to its default)."""
        return {k: getattr(self, k) for k in SEARCH_KEYS if getattr(self, k) is not None}

    def tumbling_options(self) -> dict[str, Any]:
        """The tumbling search's keywords given (a null one left to its default)."""
        return {k: v for k, v in self.tumbling.items() if v is not None}


@dataclass
class EGISettings:
    """Every setting of the ``egi`` model's own keys, typed (:meth:`from_config`)."""

    nights: NightsConfig = field(default_factory=NightsConfig)
    inversion: InversionConfig = field(default_factory=InversionConfig)
    #: the simulated truth's self- and observer-shadowing (ray cast)
    shadows: bool = True
    #: the truth's shadows resolved below a facet: rays from points this far apart (m) on each
    #: (cssat.optics.shadow_sampling); null: one ray from its centroid, a facet wholly lit or dark
    shadow_resolution_m: Optional[float] = None
    #: a measured light curve (a path): invert it (scenario.tle must be the object's)
    observations: Any = None
    #: how to read it (cssat.data.read_light_curve)
    observed: ReadConfig = field(default_factory=ReadConfig)

    def __post_init__(self) -> None:
        bool_param(self.shadows, "shadows")
        if self.shadow_resolution_m is not None:
            float_param(self.shadow_resolution_m, "shadow_resolution_m", 0.0, open_lo=True)
            if not self.shadows:
                raise FieldError("shadow_resolution_m", "resolves the truth's cast shadows: it needs shadows=true")
        fit, n = self.nights.fit, self.nights.n
        if fit is not None and fit > n and not self.observations:
            raise FieldError("nights.fit", f"{fit} nights fitted of the {n} observed (nights.n): at most {n}")

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "EGISettings":
        """The settings of ``cfg`` (a composed config or a plain mapping), each group built and
        checked (a :class:`FieldError` naming its full key); a key left out takes its default."""
        return typed_settings(cls, cfg)


@dataclass
class EGIConfig:
    """The extended Gaussian image (areas over surface normals) through a scene and an attitude: a
    satellite's light curve, ``y_t = Σ_k G(t, k) a_k``
    (:class:`cssat.experiments.forward.egi.EGILightCurve`).

    The ``forward`` node names the model only; its settings are the experiment's top-level keys
    of :data:`SETTINGS` (:class:`EGISettings`) and its ``model``, ``attitude``, ``brdf``,
    ``noise``, ``solver`` and ``scenario`` groups."""

    _target_: str = "cssat.experiments.forward.egi.EGILightCurve"
    #: the top-level keys the model reads: key → its typed config (a dataclass) or its default
    #: (:class:`EGISettings`' fields: one set of defaults)
    SETTINGS: ClassVar[dict[str, Any]] = settings_nodes(EGISettings)
