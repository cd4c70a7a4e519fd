"""Objects from config groups: ``_target_`` nodes built before any work, their errors as
:class:`~cssat._checks.FieldError`\\ s that carry the config field.

:func:`build` calls a node's ``_target_`` with its settings, after building its nested
``_target_`` nodes the same way, each under its own field (PnP's denoiser is
``solver.denoiser``), so an error is placed by the field it was raised for — never by parsing a
message. (Hydra's ``instantiate`` would do the calls, but reports nested errors only in its text.)
"""

from __future__ import annotations

import inspect
from typing import Any

from cssat._checks import FieldError, FieldTypeError

__all__ = ["build", "build_solver", "build_denoiser", "build_model", "settings"]


def settings(node: Any) -> dict:
    """A config group's settings as a plain ``dict`` (interpolations resolved; ``None``: empty)."""
    from omegaconf import OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    return OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else dict(node or {})


def _is_node(node: Any) -> bool:
    from omegaconf import DictConfig  # heavy: omegaconf; library code, importable without Hydra

    return isinstance(node, (dict, DictConfig)) and "_target_" in node


def build(node: Any, field: str, *, optional: dict[str, Any] | None = None, **kwargs: Any) -> Any:
    """Instantiate the config ``node`` (which must have a ``_target_``) as the object of config
    field ``field``; ``kwargs`` are passed to its ``_target_`` besides the node's settings, and
    those of ``optional`` that its signature takes (the geometry an atmosphere of one's own may
    not declare).

    A bad setting is a ``FieldError("<field>.<setting>: …")``: the object's own
    :class:`FieldError` prefixed with ``field``, a ``TypeError`` of its call (an unknown or
    missing setting) as ``field``, any other ``ValueError`` as ``field``.
    """
    from hydra.utils import get_method  # heavy: hydra; library code, importable without Hydra
    from omegaconf import DictConfig, OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    if not _is_node(node):
        raise FieldError(field, f"expected a config with a _target_ (a group option such as {field}=<name>), got {node!r}")
    if isinstance(node, DictConfig):
        node = OmegaConf.to_container(node, resolve=True)
    settings = {k: build(v, f"{field}.{k}") if _is_node(v) else v for k, v in node.items() if k != "_target_"}
    name = node["_target_"]
    try:
        target = get_method(name)
    except Exception as err:
        raise FieldError(f"{field}._target_", f"cannot import {name!r}: {err}") from None
    if optional:
        kwargs.update({k: v for k, v in optional.items() if _takes(target, k) and k not in settings})
    try:
        return target(**settings, **kwargs)
    except FieldError as err:
        raise err.within(field) from err
    except TypeError as err:
        raise FieldTypeError(field, f"{err} (check the settings of its _target_)") from err
    except ValueError as err:
        raise FieldError(field, str(err)) from err


def _takes(target: Any, name: str) -> bool:
    """Whether ``target(**{name: …})`` is a valid call by its signature."""
    try:
        params = inspect.signature(target).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(p.name == name or p.kind is p.VAR_KEYWORD for p in params)


def _callable_with(obj: Any, field: str, signature: str) -> Any:
    if not callable(obj):
        raise FieldTypeError(field, f"{type(obj).__name__} is not callable as {signature}")
    return obj


def build_solver(node: Any, m: int | None, n_pixels: int, field: str = "solver") -> Any:
    """The solver of ``node`` (a ``solver`` group node), its size-dependent settings checked for
    ``m`` samples of ``n_pixels`` unknowns (``m`` None: later, by :func:`validate_solver`)."""
    solver = _callable_with(build(node, field), field, "solver(problem, y) -> (x, info)")
    if m is not None:
        validate_solver(solver, m, n_pixels, field)
    return solver


def validate_solver(solver: Any, m: int, n_pixels: int, field: str = "solver") -> None:
    """The solver's size-dependent settings for ``m`` samples of ``n_pixels`` unknowns."""
    validate = getattr(solver, "validate", None)
    if validate is not None:
        try:
            validate(m, n_pixels)
        except FieldError as err:
            raise err.within(field) from err


def build_denoiser(node: Any, field: str = "denoiser") -> Any:
    """The denoiser of ``node`` (a ``denoiser`` group node); ``None`` means no denoising."""
    if node is None:
        from cssat.recon import NoDenoiser  # heavy: cssat.recon imports torch

        return NoDenoiser()
    return _callable_with(build(node, field), field, "denoiser(image, sigma) -> (image, info)")


def build_model(node: Any, field: str = "model") -> Any:
    """The satellite mesh of a ``model`` group node (``_target_: cssat.scene.get_model``)."""
    return build(node, field)
