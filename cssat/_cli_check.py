"""Command-line mistakes caught before Hydra runs: one line that names the key and what is allowed.

Hydra reports a bad override (an unknown key, an unknown or null group option, bad syntax) with
its own multi-line text and exit status 1. :func:`check` composes the command line's overrides
the way Hydra will, through Hydra's own parser and config loader, and returns one line for the
first mistake, or ``None``; the console script then exits 2, as for every other bad input. A
sweep's overrides are checked value by value (every option of a group sweep, the first value of
the rest); interval sweeps (Optuna's) are checked for their key only.
"""

from __future__ import annotations

from typing import Any, Sequence

__all__ = ["check", "check_catalogue", "overrides_of"]

#: options after which the argument list is not overrides, or Hydra's own help and completion
_SKIP_FLAGS = {"--help", "-h", "--hydra-help", "--info", "-i", "--shell-completion", "-sc", "--config-path", "-cp",
               "--config-name", "-cn", "--config-dir", "-cd", "--version", "-V", "--experimental-rerun"}
_VALUE_FLAGS = {"--cfg", "-c", "--package", "-p"}  # flags that take the next argument
_MISSING = object()


def overrides_of(argv: Sequence[str]) -> list[str] | None:
    """The overrides of a ``cssat`` command line, or ``None`` when it is not a plain run or sweep."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        if a in _SKIP_FLAGS or a.split("=", 1)[0] in _SKIP_FLAGS:
            return None
        if a in _VALUE_FLAGS:
            skip = True
        elif a in ("-m", "--multirun", "--resolve") or a.startswith("--cfg=") or a.startswith("--package="):
            continue
        elif a.startswith("-") and "=" not in a:
            return None  # an option this check does not know: leave it to Hydra
        else:
            out.append(a)
    return out


def _values(o: Any) -> list[Any] | None:
    """The values an override takes (a discrete sweep's each), or ``None`` for an interval sweep."""
    if not o.is_sweep_override():
        return [o.value()]
    if o.is_discrete_sweep():
        from hydra.errors import HydraException  # startup: hydra; this module imports without it

        try:
            return list(o.sweep_iterator())
        except HydraException:  # glob(...): its values need Hydra's config loader; Hydra expands them
            return None
    return None


def _text(o: Any, value: Any) -> str:
    """The override with one value, as Hydra reads it."""
    from hydra.core.override_parser.types import Override  # startup: hydra; this module imports without it

    prefix = {"ADD": "+", "FORCE_ADD": "++", "DEL": "~"}.get(o.type.name, "")
    key = o.get_key_element().lstrip("+~")
    if o.is_delete():
        return f"~{key}" + (f"={Override._get_value_element_as_str(value)}" if value is not None else "")
    return f"{prefix}{key}={Override._get_value_element_as_str(value)}"


def _parent_keys(cfg: Any, key: str) -> str:
    from omegaconf import OmegaConf  # startup: omegaconf; this module imports without it

    parent, _, _ = key.rpartition(".")
    node = OmegaConf.select(cfg, parent, default=None) if parent else cfg
    if not OmegaConf.is_dict(node):
        return ""
    keys = [k for k in node.keys() if k != "hydra"]
    return f"; {parent or 'the config'} has: {', '.join(map(str, keys))}" if keys else ""


def _typed_refusal(cfg: Any, key: str) -> str | None:
    """Why ``key`` cannot be set when its parent node is a typed config (a dataclass: a forward
    model's ``forward`` node, the characterise groups) that has no such field — not even with
    ``+`` —, or ``None``."""
    import dataclasses  # startup: stdlib

    from omegaconf import OmegaConf  # startup: omegaconf; this module imports without it

    parent, _, leaf = key.rpartition(".")
    node = OmegaConf.select(cfg, parent, default=None) if parent else None
    if not OmegaConf.is_dict(node):
        return None
    typ = OmegaConf.get_type(node)
    if not (isinstance(typ, type) and dataclasses.is_dataclass(typ)):
        return None
    names = [f.name for f in dataclasses.fields(typ)]
    if leaf in names:
        return None
    moved = getattr(typ, "MOVED", {}).get(leaf)
    if moved:  # a key that moved to another group: where it went
        return f"{key}: no such key; {moved}"
    return (f"{key}: no such key; {parent} is a typed config ({typ.__module__}.{typ.__qualname__}) that takes only: "
            f"{', '.join(names)}")


def _bool_refusal(cfg: Any, key: str, values: list[Any] | None) -> str | None:
    """Why a typed boolean field ``key`` (a dataclass's ``bool``) cannot take ``values``: anything
    but ``true`` / ``false`` — OmegaConf would read ``2``, ``'yes'`` or ``'on'`` as true —, or ``None``."""
    from omegaconf import BooleanNode, OmegaConf  # startup: omegaconf; this module imports without it

    parent, _, leaf = key.rpartition(".")
    node = OmegaConf.select(cfg, parent, default=None) if parent else cfg
    if not OmegaConf.is_dict(node) or leaf not in node or not isinstance(node._get_node(leaf), BooleanNode):
        return None
    bad = [v for v in values or [] if not isinstance(v, bool)]
    return f"{key}: expected true or false, got {bad[0]!r}" if bad else None


def _bad_option(compose, config_name, paths, o, group, value, loader) -> str | None:
    """Why ``group=value`` is not an option (Hydra's own list of the options, which includes the
    command line's ``hydra.searchpath``), or ``None``."""
    from hydra.errors import MissingConfigException  # startup: hydra; this module imports without it

    key = o.get_key_element().lstrip("+~")
    if not isinstance(value, str):
        what = "null" if value is None else repr(value)
        return f"{key}: a config group takes one of its options, got {what}; allowed: {', '.join(loader.get_group_options(group))}"
    try:
        compose(config_name, overrides=[*paths, _text(o, value)], return_hydra_config=True)
    except MissingConfigException as err:
        options = getattr(err, "options", None) or loader.get_group_options(group)
        return f"{key}: no option {value!r} in the config group {group!r}; allowed: {', '.join(options)}"
    except Exception:  # another problem of this option: the full composition below names it
        return None
    return None


def check(overrides: Sequence[str], config_module: str = "cssat.conf", config_name: str = "config") -> str | None:
    """The first mistake in ``overrides`` as ``"<key>: <what is wrong>; <what is allowed>"``, or ``None``."""
    from hydra import compose, initialize_config_module  # startup: hydra; this module imports without it
    from hydra.core.global_hydra import GlobalHydra  # startup: hydra; this module imports without it
    from hydra.core.override_parser.overrides_parser import OverridesParser  # startup: hydra; this module imports without it
    from hydra.errors import HydraException, OverrideParseException  # startup: hydra; this module imports without it
    from omegaconf import OmegaConf  # startup: omegaconf; this module imports without it

    parser = OverridesParser.create()
    parsed = []
    for text in overrides:
        try:
            parsed.append(parser.parse_overrides([text])[0])
        except OverrideParseException as err:
            key = text.split("=", 1)[0].lstrip("+~") or text
            return f"{key}: cannot parse the override {text!r} ({str(err).splitlines()[0]}); e.g. {key}=value, {key}=1,2,3 or '{key}=[1,2]'"
    GlobalHydra.instance().clear()
    try:
        with initialize_config_module(config_module=config_module, version_base="1.3"):
            loader = GlobalHydra.instance().config_loader()
            paths = [o.input_line for o in parsed if o.key_or_group == "hydra.searchpath"]
            groups, rest = [], []
            for o in parsed:
                group = o.key_or_group
                if o.key_or_group != "hydra.searchpath" and loader.repository.group_exists(group) and not o.is_delete():
                    values = _values(o)
                    known = loader.get_group_options(group)
                    for v in values or []:
                        why = None if v in known else _bad_option(compose, config_name, paths, o, group, v, loader)
                        if why:
                            return why
                    if values:
                        groups.append(_text(o, values[0]))
                else:
                    rest.append(o)
            groups = [*paths, *groups]
            rest = [o for o in rest if o.key_or_group != "hydra.searchpath"]
            firsts = [_text(o, _values(o)[0]) if _values(o) else o.input_line for o in rest if _values(o) is not None]
            try:  # the usual case: everything composes, one composition
                cfg = compose(config_name, overrides=[*groups, *firsts], return_hydra_config=True)
            except (HydraException, ValueError):
                pass
            else:  # a key added with + to a typed config composes, and its dataclass refuses it later
                for o in rest:
                    why = _typed_refusal(cfg, o.key_or_group) if o.is_add() or o.is_force_add() else None
                    why = why or _bool_refusal(cfg, o.key_or_group, None if o.is_delete() else _values(o))
                    if why:
                        return why
                return None
            try:
                base = compose(config_name, overrides=groups, return_hydra_config=True)
            except HydraException as err:  # e.g. an option whose own defaults fail
                return f"{', '.join(groups) or 'the config'}: {str(err).splitlines()[0]}"
            plain = []
            for o in rest:
                key = o.key_or_group
                values = _values(o)
                typed = _typed_refusal(base, key) or _bool_refusal(base, key, None if o.is_delete() else values)
                if typed and not key.startswith("hydra."):
                    return typed
                if not (o.is_add() or o.is_force_add() or key.startswith("hydra.")) and \
                        OmegaConf.select(base, key, default=_MISSING, throw_on_missing=False) is _MISSING:
                    return f"{key}: no such key{_parent_keys(base, key)} (add a new one with +{key}=...)"
                if values is None:
                    continue
                one = _text(o, values[0]) if values else o.input_line
                try:
                    compose(config_name, overrides=[*groups, one], return_hydra_config=True)
                except (HydraException, ValueError) as err:
                    cause = err.__cause__ or err
                    return f"{key}: cannot set it to {values[0]!r} ({str(cause).splitlines()[0]})"
                plain.append(one)
            try:
                compose(config_name, overrides=[*groups, *plain], return_hydra_config=True)
            except (HydraException, ValueError) as err:
                cause = err.__cause__ or err
                return f"overrides: {str(cause).splitlines()[0]}"
    finally:
        GlobalHydra.instance().clear()
    return None


def check_catalogue(overrides: Sequence[str], config_module: str = "cssat.conf", config_name: str = "config") -> str | None:
    """A catalogue sweep's settings — ``catalogue.*`` and the characterise groups its rows use
    (``period.*``, ``observed.*``, ``characterise.*``, ``stages.*``, ``tumbling.*``) — checked
    once, as every shard will check them (:func:`cssat.catalogue_shards.check_config`), before any job
    runs: the first mistake as ``"<key>: <what is wrong>"``, or ``None``. The overrides compose
    with each sweep's first value (the check of :func:`check` passed already)."""
    from hydra import compose, initialize_config_module  # startup: hydra; this module imports without it
    from hydra.core.global_hydra import GlobalHydra  # startup: hydra; this module imports without it
    from hydra.core.override_parser.overrides_parser import OverridesParser  # startup: hydra; this module imports without it

    from cssat._checks import FieldError  # startup: light
    from cssat.catalogue_shards import check_config  # startup: light (its check imports torch when it runs)

    firsts = []
    for o in OverridesParser.create().parse_overrides(list(overrides)):
        values = _values(o)
        if values is None:
            continue  # an interval sweep: a sweeper's values, checked by its jobs
        firsts.append(_text(o, values[0]) if o.is_sweep_override() else o.input_line)
    GlobalHydra.instance().clear()
    try:
        with initialize_config_module(config_module=config_module, version_base="1.3"):
            cfg = compose(config_name, overrides=firsts)
        check_config(cfg)
    except FieldError as err:
        return str(err)
    finally:
        GlobalHydra.instance().clear()
    return None
