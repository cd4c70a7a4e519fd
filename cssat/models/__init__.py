"""The typed configs of the forward models: one dataclass per model, the single source of its
``forward`` node's keys and defaults.

Each forward model's config is a dataclass (:class:`~cssat.models.pixels.config.PixelsConfig`,
:class:`~cssat.models.moving.config.MovingConfig`, :class:`~cssat.models.egi.config.EGIConfig`,
:class:`~cssat.models.scene.config.SceneConfig`, :class:`~cssat.models.shadow.config.ShadowConfig`,
:class:`~cssat.models.observed.config.ObservedConfig`) registered in Hydra's ConfigStore as the
option ``forward/<name>`` (:func:`register_configs`, called when Hydra reads ``cssat.conf``): ``cssat
forward=<name>`` and an experiment's ``override /forward: <name>`` pick it, ``forward.<key>=…``
overrides one of its fields, and a key that is not a field is refused when the config is composed.
Each dataclass checks its values in ``__post_init__`` and raises a
:class:`~cssat._checks.FieldError` naming the full key (``forward.dtype``), so the model built
from it gets values already checked.

A model whose settings are top-level groups (the observed model's ``observations``, ``period``,
``stages``, …) names their dataclasses in a ``SETTINGS`` class variable of its config: they are
stored as the config ``<name>_settings`` (those keys at the root), which its experiments include
in their defaults list (``- /<name>_settings``), so those groups are typed too.

A forward model of one's own registers its config here with :func:`register` (its module, imported
before Hydra composes: e.g. from a ``conf`` package's ``__init__``), or ships a YAML in a
``forward/`` group on Hydra's search path. This package imports no numpy or torch: Hydra imports
it whenever it composes a config.
"""

from __future__ import annotations

from dataclasses import fields, is_dataclass
__all__ = ["FORWARD_CONFIGS", "register", "unregister", "register_configs", "config_class"]

#: the forward models' configs: option name → dataclass (filled by :func:`register`)
FORWARD_CONFIGS: dict[str, type] = {}


def register(name: str, cls: type) -> type:
    """Add ``cls`` (a dataclass with a ``_target_`` field) as the forward model ``name``; it is
    stored in Hydra's ConfigStore as ``forward/<name>`` by :func:`register_configs` (at once when
    that has run). Returns ``cls`` (usable as a decorator's body)."""
    if not is_dataclass(cls) or "_target_" not in {f.name for f in fields(cls)}:
        raise TypeError(f"{cls!r}: a forward model's config is a dataclass with a _target_ field")
    FORWARD_CONFIGS[name] = cls
    if _STORED:
        _store(name, cls)
    return cls


def unregister(name: str) -> None:
    """Remove the forward model ``name`` (from :data:`FORWARD_CONFIGS` and Hydra's ConfigStore)."""
    FORWARD_CONFIGS.pop(name, None)
    if _STORED:
        from hydra.core.config_store import ConfigStore  # heavy: hydra, only where a config is composed

        ConfigStore.instance().repo.get("forward", {}).pop(f"{name}.yaml", None)
        ConfigStore.instance().repo.pop(f"{name}_settings.yaml", None)


_STORED: list[bool] = []


def _store(name: str, cls: type) -> None:
    from hydra.core.config_store import ConfigStore  # heavy: hydra, only where a config is composed

    ConfigStore.instance().store(group="forward", name=name, node=cls)
    groups = getattr(cls, "SETTINGS", None)
    if groups:  # the top-level groups the model reads, typed: the config <name>_settings at the root
        ConfigStore.instance().store(name=f"{name}_settings", node=dict(groups),
                                     package="_global_")


def _builtin() -> None:
    from cssat.models.egi.config import EGIConfig  # local: each model's config module registers it; loaded on first use
    from cssat.models.moving.config import MovingConfig  # local: each model's config module registers it; loaded on first use
    from cssat.models.observed.config import ObservedConfig  # local: each model's config module registers it; loaded on first use
    from cssat.models.pixels.config import PixelsConfig  # local: each model's config module registers it; loaded on first use
    from cssat.models.scene.config import SceneConfig  # local: each model's config module registers it; loaded on first use
    from cssat.models.shadow.config import ShadowConfig  # local: each model's config module registers it; loaded on first use

    for name, cls in (("pixels", PixelsConfig), ("moving", MovingConfig), ("egi", EGIConfig), ("scene", SceneConfig),
                      ("shadow", ShadowConfig), ("observed", ObservedConfig)):
        FORWARD_CONFIGS.setdefault(name, cls)


def register_configs() -> None:
    """Store every forward model's config in Hydra's ConfigStore as ``forward/<name>`` (once)."""
    _builtin()
    if not _STORED:
        for name, cls in FORWARD_CONFIGS.items():
            _store(name, cls)
        _STORED.append(True)


def config_class(target: str) -> type | None:
    """The registered config dataclass whose ``_target_`` default is ``target`` (None: none)."""
    _builtin()
    for cls in FORWARD_CONFIGS.values():
        if cls.__dataclass_fields__["_target_"].default == target:
            return cls
    return None

