"""Objects from config groups: ``_target_`` nodes built by ``hydra.utils.instantiate``, with
errors turned into :class:`ConfigError`\\ s that name the field, before any work starts."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

from cssat.experiments.common import ConfigError

if TYPE_CHECKING:
    import torch

    from cssat.physics import Measurement


__all__ = ["build", "build_solver", "build_denoiser", "build_measurement", "build_atmosphere", "build_model"]


def build(node: Any, field: str, **kwargs: Any) -> Any:
    """Instantiate the config ``node`` (which must have a ``_target_``) as the object of config
    field ``field``; any error in its settings is a ``ConfigError("<field>.<setting>: …")``."""
    from hydra.errors import InstantiationException
    from hydra.utils import instantiate

    if node is None or "_target_" not in node:
        raise ConfigError(f"{field}: expected a config with a _target_ (a group option such as {field}=<name>), got {node!r}")
    try:
        return instantiate(node, _convert_="all", **kwargs)
    except InstantiationException as err:
        cause, where = err, field
        while isinstance(cause, InstantiationException):
            nested = re.search(r"full_key: (\S+)", str(cause))
            if nested:  # the node's own key, or a nested object's (PnP's denoiser: solver.denoiser)
                key = nested.group(1)
                where = key if key == field or key.startswith(field + ".") else f"{field}.{key}"
            if cause.__cause__ is None:
                break
            cause = cause.__cause__
        if isinstance(cause, TypeError) and "argument" in str(cause):
            raise ConfigError(f"{where}: {cause} (check the settings of its _target_)") from err
        if isinstance(cause, ValueError):
            msg, last = str(cause), where.rsplit(".", 1)[-1]
            if msg.startswith(last + "."):  # e.g. get_model's "model.cd: ..." under reference.model
                msg = msg[len(last) + 1:]
            raise ConfigError(f"{where}.{msg}") from err
        raise ConfigError(f"{where}: {cause}") from err


def _callable_with(obj: Any, field: str, signature: str) -> Any:
    if not callable(obj):
        raise ConfigError(f"{field}: {type(obj).__name__} is not callable as {signature}")
    return obj


def build_solver(cfg: Any, m: int, n_pixels: int, field: str = "solver") -> Any:
    """The solver of config ``cfg`` (a ``solver`` group node), its size-dependent settings
    checked for ``m`` samples of ``n_pixels`` pixels."""
    solver = _callable_with(build(cfg, field), field, "solver(phi, y, shape) -> (x, info)")
    validate = getattr(solver, "validate", None)
    if validate is not None:
        try:
            validate(m, n_pixels)
        except ValueError as err:
            raise ConfigError(f"{field}.{err}") from err
    return solver


def build_denoiser(cfg: Any, field: str = "denoiser") -> Any:
    """The denoiser of config ``cfg`` (a ``denoiser`` group node); ``None`` means no denoising."""
    if cfg is None:
        from cssat.recon import NoDenoiser

        return NoDenoiser()
    return _callable_with(build(cfg, field), field, "denoiser(image, sigma) -> (image, info)")


def build_atmosphere(cfg: Any, emitters: str = "pixels", experiment: str = "") -> Any:
    """The atmosphere model of ``cfg.atmosphere``, checked to weight ``emitters``."""
    atm = build(cfg.get("atmosphere"), "atmosphere")
    if getattr(atm, "emitters", "pixels") != emitters:
        raise ConfigError(
            f"atmosphere.emitters: expected {emitters!r} ({experiment or 'this experiment'} measures an image's "
            f"{emitters}), got {atm.emitters!r}: use atmosphere=gaussian")
    return atm


def build_measurement(cfg: Any, m: int, n_pixels: int, seed: int, dtype: torch.dtype, device: torch.device | str, *,
                      atmosphere: Any = None, sensing_dtype: torch.dtype | None = None, experiment: str = "") -> Measurement:
    """The :class:`cssat.physics.Measurement` of an image experiment: ``Φ (m, n_pixels)`` drawn by
    the ``atmosphere`` group from ``seed``, and the ``noise`` group seeded with ``seed + 1``.
    ``sensing_dtype`` draws Φ in another dtype than ``dtype`` (it is then cast to ``dtype``)."""
    from cssat.physics import Measurement
    from cssat.sparse import MatrixOperator

    atm = atmosphere if atmosphere is not None else build_atmosphere(cfg, "pixels", experiment)
    noise = build(cfg.get("noise"), "noise")
    op = atm.operator(m, n_pixels, seed=seed, dtype=sensing_dtype or dtype, device=device)
    if sensing_dtype is not None and sensing_dtype != dtype:
        op = MatrixOperator(op.matrix().to(dtype))
    return Measurement(op, noise, seed=seed + 1), atm


def build_model(cfg: Any, field: str = "model") -> Any:
    """The satellite mesh of a ``model`` group node (``_target_: cssat.scene.get_model``)."""
    return build(cfg, field)
