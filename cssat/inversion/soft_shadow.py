"""Soft, differentiable self-shadowing of the parametric box-wing (:mod:`cssat.inversion.parametric`).

:func:`~cssat.inversion.parametric.box_wing_visibility` casts Embree rays: its visibility is a
step in the parameters, so a gradient held at a fixed visibility does not see a shadow move
(∂y/∂gap = 0). Here each sub-facet's visibility is a smooth function of the parameters: a ray from
its centroid towards the Sun (and one towards the observer) meets each *other* part of the
family — the bus box, each wing, each boom, the deck, each dish — with a soft probability, a
logistic function of how far inside that part's outline the ray passes (metres, over the
softness ``tau``):

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

A dish's own rim shadows its bowl: the space inside a paraboloid bowl up to its aperture is
convex, so a ray from a point in it — a cell on the dish's concave side, or a cell of another part
that the bowl holds (a bus face where a dish is set into it) — leaves it through the aperture disk
(lit) or through the bowl's wall (shadowed): there the dish's factor is the soft hit of its disk,
not one minus it. (Without this, on the finer family at the Astra-like's own geometry the soft
light curve at τ = 0.1 mm was 0.75σ rms from the ray cast's at 16 cells; with it 0.07σ.)

ASSUMPTIONS: no other part shadows itself (the bus is convex and the panels flat; a wing's panels,
in one plane, do not shadow each other; the dish's convex back faces away from the bowl), a dish
casts the shadow of its aperture disk (its depth is not in its outline: near edge-on, a deep
dish's shadow is thinner here than cast), the two-sided panels' receivers sit on the plate's plane
(their own plate is excluded, not cast).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor

from cssat._checks import FieldError, bool_param, float_param
from cssat.inversion.parametric import _assemble, _geometry
from cssat.optics.photometry import check_unit

__all__ = ["HIT_FLOOR", "soft_visibility"]

HIT_FLOOR = 1e-12
"""A ray whose soft hit of an occluder is at most this is taken as missing it
(:func:`soft_visibility`'s ``hit_floor``)."""


def _ray_plane(P: Tensor, D: Tensor, o: Tensor, n: Tensor) -> tuple[Tensor, Tensor]:
    """Rays ``P + t D`` (``P, D (..., 3)``, broadcast together) against the plane through ``o (3,)``
    of normal ``n (3,)``: the distance ``t (...)`` (m; huge where the ray runs along the plane) and
    the crossing ``(..., 3)``."""
    den = D @ n  # dot products as matrix–vector products: a sum over a last axis of 3 is slow in torch
    den = torch.where(den.abs() < 1e-9, torch.full_like(den, 1e-9), den)
    t = (o @ n - P @ n) / den
    return t, P + t[..., None] * D


def _soft_hit(P: Tensor, D: Tensor, occluder: tuple, tau: Tensor) -> Tensor:
    """One occluder's soft hit ``(...)`` along rays from ``P (..., 3)`` in directions ``D (..., 3)``
    (broadcast together; module docstring); ``occluder`` as
    :func:`cssat.inversion.parametric._assemble` gives it."""
    sig = torch.sigmoid
    kind = occluder[0]
    if kind == "box":  # the slab test: the chord through the box, and the box ahead of the point
        _, centre, half = occluder
        Dj = torch.where(D.abs() < 1e-12, torch.full_like(D, 1e-12), D)
        t1 = (-half - (P - centre)) / Dj
        t2 = (half - (P - centre)) / Dj
        lo, hi = torch.minimum(t1, t2), torch.maximum(t1, t2)
        near = torch.maximum(torch.maximum(lo[..., 0], lo[..., 1]), lo[..., 2])  # not amax(-1): slow over 3
        far = torch.minimum(torch.minimum(hi[..., 0], hi[..., 1]), hi[..., 2])
        return sig((far - near) / tau) * sig(far / tau)
    if kind == "panels":  # a wing: each panel's crossing inside its nearest edge; the wing hit if any panel is
        o0, u0, w0 = occluder[1][0][:3]
        n = torch.linalg.cross(u0, w0)
        t, h = _ray_plane(P, D, o0, n / torch.linalg.vector_norm(n))  # one plane: a wing's panels share it
        ahead = sig(t / tau)
        miss = None
        for o, u, w, L, W in occluder[1]:
            s = (h @ u - o @ u) / (L * L)
            r = (h @ w - o @ w) / (W * W)
            m = torch.minimum(torch.minimum(s, 1 - s) * L, torch.minimum(r, 1 - r) * W)
            miss = 1 - sig(m / tau) * ahead if miss is None else miss * (1 - sig(m / tau) * ahead)
        return 1 - miss
    centre, axis, radius = occluder[1:4]  # a dish: its aperture disk
    t, h = _ray_plane(P, D, centre, axis)
    rho = torch.linalg.vector_norm(h - centre, dim=-1)
    return sig((radius - rho) / tau) * sig(t / tau)


def _in_bowl(P: Tensor, disk: tuple, N: Tensor, own: Tensor) -> Tensor:
    """``(F,)`` bool: the sub-facets whose centroid ``P (F, 3)`` lies in the space the dish of
    ``disk = ("disk", aperture centre, unit axis, radius, depth)`` encloses (its paraboloid bowl up
    to the aperture plane) — of the dish's own sub-facets (``own``), those on its concave side
    (normal ``N`` along the axis); of the other parts', those the bowl holds (a bus face inside a
    dish set into it)."""
    centre, axis, radius, depth = (x.detach() for x in disk[1:5])
    rel = P - centre
    h = (rel * axis).sum(-1)  # from the aperture plane, ≤ 0 below it
    r = torch.linalg.vector_norm(rel - h[:, None] * axis, dim=-1)
    held = (r < radius) & (h < 0) & (h > depth * ((r / radius) ** 2 - 1))
    return torch.where(own, (N @ axis) > 0, held)


def soft_visibility(p: Any, sun: Any, observer: Any, *, tau: float, panels: int = 2, divisions: int = 4,
                    dishes: int = 0, dish_rings: int = 12, dish_segments: int = 40, front_only: bool = False,
                    hit_floor: float | None = HIT_FLOOR, **parts: Any) -> Tensor:
    """``(T, F)`` in [0, 1]: each of :func:`~cssat.inversion.parametric.box_wing`'s sub-facets
    lit and seen (module docstring), differentiable in ``p`` (``(9,)``, ``(17,)`` with ``dishes``,
    more with ``parts``: :func:`~cssat.inversion.parametric.param_names`); ``sun, observer (T, 3)``
    body-frame unit vectors from the object; ``tau`` the shadows' edge softness (m, > 0; a few per
    cent of the bus's size). ``parts``: ``dish_pair``, ``wing_panels``, ``booms``, ``deck``
    (:func:`~cssat.inversion.parametric.box_wing`). ``front_only``: computed only where the
    sub-facet faces both the Sun and the observer, 0 elsewhere (where the light curve's
    ``(S·N)₊ (V·N)₊`` is 0 anyway: the same light curve and gradient, 1.6–2.1× faster:
    ``benchmarks/bench_soft_front.py``).

    ``hit_floor`` (in [0, 0.5], or None): a ray whose soft hit of an occluder is at most this
    (computed first without a gradient) is taken as missing it — its factor 1 exactly, so neither
    it nor its gradient is built; each such factor is then off by at most ``hit_floor``, its
    derivative by ``hit_floor``/τ × the margin's. Most rays pass far outside most occluders (at τ
    of a few cm ~85–90 % of the pairs, at 0.1 × the bus ~70 %): 2–3× faster at the default 1e-12
    (``benchmarks/bench_soft_front.py``); 0 leaves out only the hits that are exactly 0; None
    computes every pair (the reference). Follows ``p``'s dtype and device."""
    tau = float_param(tau, "tau", 0.0, open_lo=True)
    hit_floor = None if hit_floor is None else float_param(hit_floor, "hit_floor", 0.0, 0.5)
    bool_param(front_only, "front_only")
    v, f, _, _, inst, occluders = _assemble(p, panels, divisions, dishes, dish_rings, dish_segments, **parts)
    S = check_unit(sun, "sun").to(device=v.device, dtype=v.dtype)
    V = check_unit(observer, "observer").to(device=v.device, dtype=v.dtype)
    if S.shape != V.shape:
        raise FieldError("observer", f"{V.shape[0]} directions for {S.shape[0]} Sun directions")
    fi = torch.as_tensor(f, device=v.device)
    P = v[fi].mean(1)  # (F, 3) centroids
    lab = torch.as_tensor(inst, device=v.device)
    tau_t = torch.as_tensor(tau, dtype=v.dtype, device=v.device)
    with torch.no_grad():  # which sub-facets face the Sun and observer, which lie in a dish's bowl (module docstring)
        N, _ = _geometry(v.detach(), f)
        inside = {k: _in_bowl(P.detach(), occ, N, lab == k) for k, occ in enumerate(occluders) if occ[0] == "disk"}
        pairs = ((S @ N.T) > 0) & ((V @ N.T) > 0) if front_only else torch.ones(len(S), len(f), dtype=torch.bool,
                                                                                    device=v.device)
        ti, ci = pairs.nonzero(as_tuple=True)  # the (sample, sub-facet) pairs computed, (K,) each
    Pk, lk = P[ci], lab[ci]
    held_in = {k: b[ci] for k, b in inside.items()}  # (K,) each: the rays starting in that dish's bowl
    vis = torch.ones(len(ci), dtype=v.dtype, device=v.device)
    for D in (S[ti], V[ti]):
        for k, occ in enumerate(occluders):
            held = held_in.get(k)
            with torch.no_grad():  # the pairs whose factor is not 1: the ray meets the occluder, or starts in its bowl
                need = lk != k  # no other part shadows itself: its own part's factor is 1
                if hit_floor is not None:
                    need &= _soft_hit(Pk, D, occ, tau_t) > hit_floor
                if held is not None:
                    need |= held
                idx = need.nonzero(as_tuple=True)[0]
            if len(idx) == 0:
                continue
            hit = _soft_hit(Pk[idx], D[idx], occ, tau_t)
            # inside a bowl a ray leaves through the aperture (lit) or the bowl's wall (shadowed); of the other
            # pairs only other parts' are in idx
            fac = 1 - hit if held is None else torch.where(held[idx], hit, 1 - hit)
            vis = vis.index_put((idx,), vis[idx] * fac)
    return torch.zeros((S.shape[0], len(f)), dtype=v.dtype, device=v.device).index_put((ti, ci), vis)
