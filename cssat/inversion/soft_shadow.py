"""Soft, differentiable self-shadowing of the parametric box-wing (:mod:`cssat.inversion.parametric`).

:func:`~cssat.inversion.parametric.box_wing_visibility` casts Embree rays: its visibility is a
step in the parameters, so a gradient held at a fixed visibility does not see a shadow move
(∂y/∂gap = 0). Here each sub-facet's visibility is a smooth function of the parameters: a ray from
its centroid towards the Sun (and one towards the observer) meets each *other* part of the
family — the bus box, each wing, each boom, the deck, each dish — with a soft probability, a logistic function of
how far inside that part's outline the ray passes (metres, over the softness ``tau``):

* the bus (an axis-aligned box of half-sizes ``a, b, c``), and each boom and the deck box: the
  slab test, ``σ((t_far − t_near)/τ) σ(t_far/τ)`` — the chord the ray cuts through the box, and
  the box ahead of the centroid;
* a panel (the rectangle ``o + s u + t w``, ``s, t ∈ [0, 1]``): where the ray crosses its plane
  ahead of the centroid, ``σ(m/τ)``, ``m`` the crossing's distance inside the nearest edge; a
  wing of several panels (``wing_panels``) is hit where any of its panels is, ``1 − Π(1 − hit)``;
* a dish: its aperture disk (centre ``vertex + depth · axis``, radius ``dish_radius``),
  ``σ((R − ρ)/τ)``, ``ρ`` the crossing's distance from the centre.

A sub-facet is lit and seen with ``v = Π_parts (1 − hit_sun) Π_parts (1 − hit_obs)``; as ``τ →
0`` ``v`` tends to the ray cast's 0/1 at the centroid (a dish as its disk).

ASSUMPTIONS: a part does not shadow itself (the bus is convex and the panels flat; a dish's own
rim on its bowl is not modelled; a wing's panels, in one plane, do not shadow each other), a dish casts the shadow of its aperture disk (its depth is not
in its outline: near edge-on, a deep dish's shadow is thinner here than cast), the two-sided
panels' receivers sit on the plate's plane (their own plate is excluded, not cast).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor

from cssat._checks import FieldError, float_param
from cssat.inversion.parametric import _assemble
from cssat.optics.photometry import check_unit

__all__ = ["soft_visibility"]


def _ray_plane(P: Tensor, D: Tensor, o: Tensor, n: Tensor) -> tuple[Tensor, Tensor]:
    """Rays ``P (F, 3) + t D (T, 3)`` against the plane through ``o`` of normal ``n``: the
    distance ``t (T, F)`` (m; huge where the ray runs along the plane) and the crossing ``(T, F, 3)``."""
    den = D @ n
    den = torch.where(den.abs() < 1e-9, torch.full_like(den, 1e-9), den)
    t = ((o - P) @ n)[None, :] / den[:, None]
    return t, P[None] + t[..., None] * D[:, None]


def _soft_hit(P: Tensor, D: Tensor, occluder: tuple, tau: Tensor) -> Tensor:
    """One occluder's soft hit ``(T, F)`` along rays from ``P (F, 3)`` in directions ``D (T, 3)``
    (module docstring); ``occluder`` as :func:`cssat.inversion.parametric._assemble` gives it."""
    sig = torch.sigmoid
    kind = occluder[0]
    if kind == "box":  # the slab test: the chord through the box, and the box ahead of the point
        _, centre, half = occluder
        Q = P - centre
        Dj = torch.where(D.abs() < 1e-12, torch.full_like(D, 1e-12), D)
        t1 = (-half[None, None] - Q[None]) / Dj[:, None]  # (T, F, 3)
        t2 = (half[None, None] - Q[None]) / Dj[:, None]
        near = torch.minimum(t1, t2).amax(-1)
        far = torch.maximum(t1, t2).amin(-1)
        return sig((far - near) / tau) * sig(far / tau)
    if kind == "panels":  # a wing: each panel's crossing inside its nearest edge; the wing hit if any panel is
        miss = None
        for o, u, w, L, W in occluder[1]:
            n = torch.linalg.cross(u, w)
            t, h = _ray_plane(P, D, o, n / torch.linalg.vector_norm(n))
            s = ((h - o) @ u) / (L * L)
            r = ((h - o) @ w) / (W * W)
            m = torch.minimum(torch.minimum(s, 1 - s) * L, torch.minimum(r, 1 - r) * W)
            hit = sig(m / tau) * sig(t / tau)
            miss = 1 - hit if miss is None else miss * (1 - hit)
        return 1 - miss
    _, centre, axis, radius = occluder  # a dish: its aperture disk
    t, h = _ray_plane(P, D, centre, axis)
    rho = torch.linalg.vector_norm(h - centre, dim=-1)
    return sig((radius - rho) / tau) * sig(t / tau)


def soft_visibility(p: Any, sun: Any, observer: Any, *, tau: float, panels: int = 2, divisions: int = 4,
                    dishes: int = 0, dish_rings: int = 12, dish_segments: int = 40, **parts: Any) -> Tensor:
    """``(T, F)`` in [0, 1]: each of :func:`~cssat.inversion.parametric.box_wing`'s sub-facets
    lit and seen (module docstring), differentiable in ``p`` (``(9,)``, ``(17,)`` with ``dishes``,
    more with ``parts``: :func:`~cssat.inversion.parametric.param_names`); ``sun, observer (T, 3)``
    body-frame unit vectors from the object; ``tau`` the shadows' edge softness (m, > 0; a few per
    cent of the bus's size). ``parts``: ``dish_pair``, ``wing_panels``, ``booms``, ``deck``
    (:func:`~cssat.inversion.parametric.box_wing`). Follows ``p``'s dtype and device."""
    tau = float_param(tau, "tau", 0.0, open_lo=True)
    v, f, _, _, inst, occluders = _assemble(p, panels, divisions, dishes, dish_rings, dish_segments, **parts)
    S = check_unit(sun, "sun").to(device=v.device, dtype=v.dtype)
    V = check_unit(observer, "observer").to(device=v.device, dtype=v.dtype)
    if S.shape != V.shape:
        raise FieldError("observer", f"{V.shape[0]} directions for {S.shape[0]} Sun directions")
    P = v[torch.as_tensor(f, device=v.device)].mean(1)  # (F, 3) centroids
    lab = torch.as_tensor(inst, device=v.device)
    tau_t = torch.as_tensor(tau, dtype=v.dtype, device=v.device)
    vis = torch.ones((S.shape[0], len(f)), dtype=v.dtype, device=v.device)
    for D in (S, V):
        for k, occ in enumerate(occluders):
            hit = _soft_hit(P, D, occ, tau_t)
            vis = vis * torch.where(lab[None, :] == k, torch.ones_like(hit), 1 - hit)  # a part does not shadow itself
    return vis
