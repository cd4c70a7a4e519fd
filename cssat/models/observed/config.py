"""The config of the ``forward: observed`` model and its settings.

The model's ``forward`` node names it only (:class:`ObservedConfig`); what it reads are the
experiment's top-level groups, each a typed dataclass here — the single source of its keys and
defaults — stored in Hydra's ConfigStore with the model (:data:`ObservedConfig.SETTINGS`: the
config ``observed_settings``, which ``conf/experiment/characterise.yaml`` includes):

========================  ==========================================================================
``observations``          the light-curve file (a path; required)
``observed.*``            :class:`ReadConfig`: how to read it (:func:`cssat.data.read_light_curve`)
``stages.*``              :class:`StagesConfig`: ``auto`` | ``on`` | ``off`` for each verdict stage
``characterise.*``        :class:`CharacteriseConfig`: tracks, cleaning, the spin stage's limits
``period.*``              :class:`PeriodConfig`: the period method and its options
``tumbling.*``            :class:`TumblingConfig`: :func:`cssat.inversion.estimate_tumbling_periods`'s
``catalogue.*``           :class:`CatalogueConfig`: a multirun over many files (:mod:`cssat.catalogue`)
========================  ==========================================================================

A key that is not a field is refused when the config is composed (and by :func:`typed_group`
for a plain mapping); each dataclass checks its values in ``__post_init__`` and raises a
:class:`~cssat._checks.FieldError` naming the full key (``characterise.min_samples``). A null
option of ``period`` or ``tumbling`` is the estimator's own default. This module imports no
numpy or torch: Hydra imports it whenever it composes a config.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields
from typing import Any, ClassVar, Mapping, Optional

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param

__all__ = ["ObservedConfig", "ObservedSettings", "ReadConfig", "StagesConfig", "CharacteriseConfig", "PeriodConfig",
           "TumblingConfig", "CatalogueConfig", "STAGE_MODES", "VERDICT_STAGES", "typed_group",
           "typed_settings", "settings_nodes"]

#: the modes of each stage of ``stages``
STAGE_MODES = ("auto", "on", "off")
#: the stages of the verdict (each a key of the ``stages`` group and a ``seconds_<stage>`` timing)
VERDICT_STAGES = ("period", "tumbling", "spin")


def _optional(value: Any, check: Any, *args: Any, **kwargs: Any) -> Any:
    """``check(value, *args)`` unless ``value`` is None."""
    return None if value is None else check(value, *args, **kwargs)


@dataclass
class ReadConfig:
    """``observed.*``: how the file is read — :func:`cssat.data.read_light_curve`'s arguments
    (its own checks name them: ``observed.format``, ``observed.kind``)."""

    WHAT: ClassVar[str] = "an option of read_light_curve"

    #: null: by content; mmt | score | alcdef | ecsv | fits | csv
    format: Optional[str] = None
    #: CSV: the time column (null: time_utc); a pair [date, time] is joined
    time_col: Any = None
    #: null: the format's own (MMT: Mag; StdMag is range- and phase-normalised)
    value_col: Optional[str] = None
    error_col: Optional[str] = None
    #: magnitude | flux
    kind: str = "magnitude"
    #: the magnitudes' band (flux<->magnitude): null = V with the Sun at -26.74; V | R | g | r | i | clear |
    #: file (the file's filter column) | a filter file (lambda_nm T)
    band: Optional[str] = None
    #: Vega | AB
    band_system: str = "Vega"
    #: CSV: iso | jd | mjd | unix
    time_format: str = "iso"
    #: CSV: utc | tt | tdb | tai (converted to UTC by astropy)
    time_scale: str = "utc"
    #: a file of several objects (SCORE): the NORAD id or name to keep
    object: Any = None
    #: equal time stamps: refuse | merge (averaged)
    duplicates: str = "refuse"
    #: CSV: the columns of each sample's filter, observer and track (null: none)
    filter_col: Optional[str] = "filter"
    observer_col: Optional[str] = "observer"
    track_col: Optional[str] = "track"


@dataclass
class StagesConfig:
    """``stages.*``: ``auto`` runs a verdict stage where the data allow (else it is recorded as
    skipped, with why), ``on`` requires it, ``off`` skips it."""

    period: str = "auto"
    #: auto: only where the period stage asks (no period whose model fits, the curve over 2x its noise)
    tumbling: str = "auto"
    spin: str = "auto"

    def __post_init__(self) -> None:
        for k in VERDICT_STAGES:
            choice_param(getattr(self, k), f"stages.{k}", STAGE_MODES)
        if self.spin == "on" and self.period == "off":  # known before the file is read
            raise FieldError("stages.spin", "the spin stage needs the period stage's periodic verdict, and "
                                            "stages.period is off")


@dataclass
class CharacteriseConfig:
    """``characterise.*``: which tracks, how the curve is cleaned, the spin stage's limits."""

    #: keep only these track ids (null: all)
    tracks: Any = None
    #: fewer usable samples: refused
    min_samples: int = 20
    #: MMT's penumbra-flagged samples (partly shadowed) dropped
    drop_penumbra: bool = True
    #: apparent magnitudes reduced to 1000 km where the file gives ranges
    normalise_range: bool = True
    #: the spin stage's minimum number of nights
    min_nights: int = 2
    #: the element set's epoch within this of the observations, days
    max_epoch_days: float = 14.0
    #: the characterise figure (false: faster catalogues)
    figures: bool = True

    def __post_init__(self) -> None:
        int_param(self.min_samples, "characterise.min_samples", 12)
        bool_param(self.drop_penumbra, "characterise.drop_penumbra")
        bool_param(self.normalise_range, "characterise.normalise_range")
        int_param(self.min_nights, "characterise.min_nights", 1)
        self.max_epoch_days = float_param(self.max_epoch_days, "characterise.max_epoch_days", 0.0, open_lo=True)
        bool_param(self.figures, "characterise.figures")

    def track_list(self) -> list[Any] | None:
        """``tracks`` as a list (one id given alone: a list of it); None: all."""
        if self.tracks is None:
            return None
        return [self.tracks] if isinstance(self.tracks, (str, int)) else list(self.tracks)


@dataclass
class PeriodConfig:
    """``period.*``: the period method (null: :func:`cssat.inversion.estimate_period`; else a
    name of :func:`cssat.inversion.period_methods`) and its options, each null for the method's
    own default (the data's, for the search's range)."""

    WHAT: ClassVar[str] = "an option of estimate_period"

    method: Optional[str] = None
    min_period_s: Optional[float] = None
    max_period_s: Optional[float] = None
    n_harmonics: Optional[int] = None
    max_harmonics: Optional[int] = None
    n_peaks: Optional[int] = None
    samples_per_peak: Optional[int] = None
    #: the verdict: FAP (from surrogates of the track's own noise) below this (1e-3) ...
    fap_max: Optional[float] = None
    #: ... over at least this many cycles of the longest stretch (3); fewer: undetermined
    min_cycles: Optional[float] = None
    #: optional: the even cycles must predict the odd ones this well (null: not required)
    min_repeat: Optional[float] = None
    #: each track's polynomial: 0 offset, 1 slope, 2 quadratic (default, as MMT's pipeline)
    detrend: Optional[int] = None
    #: photometric | double_peaked (the full turn); null: double_peaked for rocket bodies (R/B)
    convention: Optional[str] = None
    #: the null's surrogates (24)
    n_surrogates: Optional[int] = None
    #: their seed (0): same file, same numbers
    seed: Optional[int] = None

    def __post_init__(self) -> None:
        if self.method is not None:
            from cssat.inversion.period_methods import period_method  # heavy: the registry's module, only when named

            period_method(self.method, field="period.method")

    def options(self) -> dict[str, Any]:
        """The options given (not null), ``method`` left out: the method's keyword arguments."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if f.name != "method" and getattr(self, f.name) is not None}


@dataclass
class TumblingConfig:
    """``tumbling.*``: :func:`cssat.inversion.estimate_tumbling_periods`'s options, each null for
    its own default."""

    WHAT: ClassVar[str] = "an option of estimate_tumbling_periods"
    min_period_s: Optional[float] = None
    max_period_s: Optional[float] = None
    #: the 2-D Fourier series' order (3)
    order: Optional[int] = None
    n_peaks: Optional[int] = None
    samples_per_peak: Optional[int] = None
    #: tumbling when no single period folds more than this fraction of the signal (0.05), in (0, 1]
    aperiodic_threshold: Optional[float] = None
    #: the fold test's window, s (5400; at least twice max_period_s)
    window_s: Optional[float] = None

    def __post_init__(self) -> None:
        _optional(self.aperiodic_threshold, float_param, "tumbling.aperiodic_threshold", 0.0, 1.0, open_lo=True)
        for key in ("window_s", "min_period_s", "max_period_s"):
            _optional(getattr(self, key), float_param, f"tumbling.{key}", 0.0, open_lo=True)
        _optional(self.order, int_param, "tumbling.order", 1, 10)
        _optional(self.n_peaks, int_param, "tumbling.n_peaks", 2, 50)
        _optional(self.samples_per_peak, int_param, "tumbling.samples_per_peak", 1)

    def options(self) -> dict[str, Any]:
        """The options given (not null): the estimator's keyword arguments."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


@dataclass
class CatalogueConfig:
    """``catalogue.*``: a multirun over a directory or glob (:mod:`cssat.catalogue`), one row per
    file in catalogue.csv."""

    #: files a job (each job one process: no start-up per file)
    shard_size: int = 500
    #: set by cssat -m: catalogue.shard=range(0,K); a job's slice of the sorted files
    shard: Optional[int] = None
    #: true: the tumbling stage too (stages.tumbling's mode; slower)
    tumbling: bool = False
    #: set by cssat -m: the sweep's file count and list hash, checked by every shard
    n_files: Optional[int] = None
    listing_sha: Optional[str] = None

    def __post_init__(self) -> None:
        _optional(self.shard, int_param, "catalogue.shard", 0)
        int_param(self.shard_size, "catalogue.shard_size", 1)
        bool_param(self.tumbling, "catalogue.tumbling")
        _optional(self.n_files, int_param, "catalogue.n_files", 1)
        if self.listing_sha is not None:
            self.listing_sha = str(self.listing_sha)


def typed_group(cls: type, values: Any, key: str) -> Any:
    """``cls`` built from ``values`` (a mapping, an OmegaConf node or None: the defaults); a key
    that is not a field is a :class:`FieldError` naming ``<key>.<name>`` and the fields (or, for
    a key in the class's ``MOVED`` mapping, where it went)."""
    if values is None:
        return cls()
    if hasattr(values, "_get_node"):  # an OmegaConf node: its values, resolved
        from omegaconf import OmegaConf  # heavy: omegaconf; only for a composed config

        values = OmegaConf.to_container(values, resolve=True)
    if isinstance(values, cls):
        return values
    names = [f.name for f in fields(cls)]
    for k in values:
        moved = getattr(cls, "MOVED", {}).get(k)
        if moved and k not in names:  # a key that moved to another group: say where
            raise FieldError(f"{key}.{k}", moved)
        if k not in names:
            what = getattr(cls, "WHAT", f"a setting of {key}")
            raise FieldError(f"{key}.{k}", f"not {what}; its settings: {', '.join(names)}")
    return cls(**values)


def typed_settings(cls: type, cfg: Mapping[str, Any]) -> Any:
    """A model's settings dataclass ``cls`` built from ``cfg`` (a composed config or a plain
    mapping): each group field (a dataclass with a ``default_factory``) by :func:`typed_group`, each
    scalar field read with its default; a :class:`FieldError` names the full key of a bad one."""
    out = {}
    for f in fields(cls):
        if f.default is MISSING:  # a group: its dataclass
            out[f.name] = typed_group(f.default_factory, cfg.get(f.name), f.name)  # type: ignore[misc]
        else:
            out[f.name] = cfg.get(f.name, f.default)
    return cls(**out)


def settings_nodes(cls: type) -> dict[str, Any]:
    """The top-level keys of the settings dataclass ``cls`` for Hydra's ConfigStore: key → its
    group's dataclass, or its scalar default (a config's ``SETTINGS``)."""
    return {f.name: f.default_factory if f.default is MISSING else f.default for f in fields(cls)}


@dataclass
class ObservedSettings:
    """Every setting of the ``observed`` model, typed (:meth:`from_config`)."""

    observations: Any = None
    observed: ReadConfig = field(default_factory=ReadConfig)
    stages: StagesConfig = field(default_factory=StagesConfig)
    characterise: CharacteriseConfig = field(default_factory=CharacteriseConfig)
    period: PeriodConfig = field(default_factory=PeriodConfig)
    tumbling: TumblingConfig = field(default_factory=TumblingConfig)
    #: the ``scenario`` node (the spin stage's geometry; ``scenario.tle`` its element set)
    scenario: Any = None

    @property
    def tle(self) -> Any:
        """The element set given (``scenario.tle``; None: none)."""
        return (self.scenario or {}).get("tle")

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "ObservedSettings":
        """The settings of ``cfg`` (a composed config or a plain mapping of the groups), each
        group built and checked (a :class:`FieldError` naming its full key)."""
        if not cfg.get("observations"):
            raise FieldError("observations", "characterise needs a light-curve file: observations=<path>")
        groups = {k: typed_group(t, cfg.get(k), k) for k, t in ObservedConfig.SETTINGS.items()
                  if isinstance(t, type) and k != "catalogue"}
        return cls(observations=cfg.get("observations"), scenario=cfg.get("scenario"), **groups)


@dataclass
class ObservedConfig:
    """A measured light curve: nothing simulated — the file's light curve read and cleaned, then its
    verdicts estimated (period, tumbling, spin)
    (:class:`cssat.experiments.forward.observed.Observed`).

    The ``forward`` node names the model only; its settings are the experiment's top-level groups
    of :data:`SETTINGS` (``observations`` a path; ``scenario.tle`` the spin stage's element set)."""

    _target_: str = "cssat.experiments.forward.observed.Observed"
    #: the top-level keys the model reads: key → its typed config (a dataclass) or its default
    SETTINGS: ClassVar[dict[str, Any]] = {"observations": None, "observed": ReadConfig, "stages": StagesConfig,
                                           "characterise": CharacteriseConfig, "period": PeriodConfig,
                                           "tumbling": TumblingConfig, "catalogue": CatalogueConfig}
