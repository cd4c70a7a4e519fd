"""Attenuated noisy light-curve models (paper Eq. 11 and Eq. 12).

The atmosphere scales each light flux by a random factor before the sensor sums them.
"""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["attenuated_facetwise", "attenuated_pixelwise", "atmosphere_weights"]


def atmosphere_weights(shape, seed: int, mean: float = 0.0, std: float | None = None, dtype=torch.float64) -> Tensor:
    """i.i.d. Gaussian weights ``ξ`` or ``φ`` of ``shape``: ``N(mean, std²)``, ``std = 1/√n``
    by default with ``n`` the last dimension (the paper's zero-mean, 1/N-variance sensing rows).
    Drawn from a generator seeded with ``seed`` (same seed ⇒ same weights)."""
    n = shape[-1]
    std = (1.0 / n) ** 0.5 if std is None else float(std)
    if std < 0:
        raise ValueError(f"std: must be >= 0, got {std}")
    g = torch.Generator().manual_seed(int(seed))
    return mean + std * torch.randn(*shape, generator=g, dtype=dtype)


def attenuated_facetwise(facet_flux: Tensor, seed: int, **weight_kwargs) -> Tensor:
    """Eq. 11: ``I(t) = Σᵢ ξᵢ(t) ρᵢ(t)`` for facet fluxes ``ρ (T, F)``, a fresh Gaussian vector
    ``ξ(t)`` per step; returns ``(T,)``."""
    rho = torch.as_tensor(facet_flux)
    xi = atmosphere_weights(tuple(rho.shape), seed, dtype=rho.dtype, **weight_kwargs).to(rho.device)
    return (xi * rho).sum(-1)


def attenuated_pixelwise(images: Tensor, seed: int, **weight_kwargs) -> Tensor:
    """Eq. 12: ``I(t) = Σᵢ φᵢ(t) xᵢ(t)`` for images ``x (T, n, n)`` (or ``(T, N)``), a fresh
    Gaussian vector ``φ(t)`` per step — one row of a Gaussian sensing matrix; returns ``(T,)``."""
    x = torch.as_tensor(images)
    flat = x.reshape(x.shape[0], -1)
    phi = atmosphere_weights(tuple(flat.shape), seed, dtype=flat.dtype, **weight_kwargs).to(flat.device)
    return (phi * flat).sum(-1)
