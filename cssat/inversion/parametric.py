"""A parametric box-wing satellite and its differentiable, self-shadowed light curve.

Beyond the convex EGI: a bus box and one or two flat solar panels, whose facets' normals and areas
are torch functions of nine parameters, so a light curve can be fitted by gradient descent.

Parameters ``p (9,)`` (:data:`PARAM_NAMES`), metres, radians and albedos:

* ``a, b, c``: the bus's half-sizes along the body x, y and z axes (the bus centred on the origin);
* ``length, width``: each panel's size along y (its axis) and across it;
* ``hinge``: the panel's angle about the y axis: its in-plane width vector is
  ``width (sin hinge, 0, cos hinge)``, so ``hinge = 0`` puts its normals along ±x;
* ``gap``: the panel's inner edge is at ``|y| = b + gap`` (a yoke's length; the yoke itself is
  not modelled);
* ``cd_bus, cd_panel``: each part's diffuse albedo ``C_d`` (the paper's Eq. 8 diffuse term).

``panels=2`` puts a mirror pair of panels at ±y (a symmetric box-wing such as :func:`astra_like`),
``panels=1`` one panel at +y.

**Reflector dishes** (``dishes=1`` or ``2``; default 0: the box-wing alone, as before): eight more
parameters (:data:`DISH_PARAM_NAMES`) after the nine, ``p (17,)``:

* ``dish_x, dish_y, dish_z``: the dish's vertex (m, body frame);
* ``dish_tilt, dish_azimuth``: its axis (the concave side's direction), ``(sin t cos φ, sin t
  sin φ, cos t)`` (rad);
* ``dish_radius, dish_depth``: the aperture radius and depth of the paraboloid (m), as
  :func:`cssat.scene.models.dish` builds it (``dish_rings × dish_segments`` cells, the same
  triangles, two-sided);
* ``cd_dish``: its diffuse albedo (both sides).

``dishes=2`` mirrors the dish through the y–z plane (vertex ``(−x, y, z)``, axis ``(−a_x, a_y,
a_z)``), the pair on the ±x faces of :func:`cssat.scene.models.astra_like`; with
``dish_pair="free"`` the second dish has its own place, axis and size instead
(:data:`DISH2_PARAM_NAMES`, seven more; its albedo is ``cd_dish``): two unequal reflectors. The
dishes cast and take shadows like every other facet. Their specular part is not in the family
(Lambertian, as the rest).

**Other parts** (each off by default; :func:`param_names` gives the order, after the dishes'):

* ``wing_panels=n`` (> 1): each wing is ``n`` panels of ``length × width`` in a row along y with
  ``panel_gap`` (m) between them (a real array's hinged panels), the first at ``|y| = b + gap``;
  each panel ``ceil(divisions / n) × divisions`` cells (the wing about as finely cut as one panel);
* ``booms=True``: a square boom (yoke) of side ``boom_width`` (m) along y from the bus's ±y face
  to each wing's root (length ``gap``), albedo ``cd_bus``, one cell a face (it is thin);
* ``deck=True``: a box centred on the +z (Earth) deck, half-sizes ``deck_a, deck_b`` along x, y
  and height ``deck_h`` (m), albedo ``cd_bus`` (an antenna tower or a payload module).

ASSUMPTIONS: Lambertian parts (no specular lobe: glints in the data are outliers the fit must
down-weight); the panels are two-sided zero-thickness plates centred on the bus's mid-plane
``z = 0``; the bus is an axis-aligned box in the body frame (the body frame is the attitude's: a
fit must have the spin axis and phase from :func:`cssat.inversion.estimate_spin` or an oracle).

Light curve (Eq. 8 diffuse, Eq. 10):

.. math::
    y_t = \\frac{I_0}{\\pi r^2} \\sum_i A_i(p)\\, C_{d,i}(p)\\, (S_t\\cdot N_i(p))_+ (V_t\\cdot N_i(p))_+\\, v_{ti}

``v_ti ∈ {0, 1}`` is facet ``i``'s visibility (neither self- nor observer-shadowed), cast by Embree
rays from its centroid (:func:`cssat.optics.photometry.shadow_mask`) on the sub-tessellation
(``divisions`` cells a side per face) and **held fixed** during a gradient step: ``y`` is
differentiable in ``p`` wherever no facet's visibility or front-facing state changes; a fit
recomputes ``v`` each outer iteration. A finer ``divisions`` approaches the exact shadowed flux.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, bool_param, choice_param, int_param
from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, check_unit, shadow_mask
from cssat.scene.mesh import Mesh

__all__ = ["PARAM_NAMES", "DISH_PARAM_NAMES", "DISH2_PARAM_NAMES", "PART_PARAM_NAMES", "param_names", "box_wing",
           "box_wing_mesh", "box_wing_light_curve", "box_wing_visibility", "box_wing_twin"]

PARAM_NAMES = ("a", "b", "c", "length", "width", "hinge", "gap", "cd_bus", "cd_panel")
#: the parameters of the dishes (``dishes=1`` or ``2``), after :data:`PARAM_NAMES`
DISH_PARAM_NAMES = ("dish_x", "dish_y", "dish_z", "dish_tilt", "dish_azimuth", "dish_radius", "dish_depth", "cd_dish")
#: the second dish's own geometry (``dishes=2, dish_pair="free"``; its albedo is ``cd_dish``)
DISH2_PARAM_NAMES = ("dish2_x", "dish2_y", "dish2_z", "dish2_tilt", "dish2_azimuth", "dish2_radius", "dish2_depth")
#: the gap between a wing's panels (``wing_panels > 1``), the booms' side (``booms``), the deck box (``deck``)
PART_PARAM_NAMES = {"wing_panels": ("panel_gap",), "booms": ("boom_width",), "deck": ("deck_a", "deck_b", "deck_h")}
#: the parameters free in sign (angles, positions); ``gap`` is >= 0, every other > 0
SIGNED_NAMES = ("hinge",) + tuple(f"{d}_{k}" for d in ("dish", "dish2") for k in ("x", "y", "z", "tilt", "azimuth"))


def _layout(dishes: int, dish_pair: str, wing_panels: int, booms: bool, deck: bool) -> tuple[int, str, int, bool, bool]:
    """The parts' options checked (errors name the field)."""
    if isinstance(dishes, bool) or dishes not in (0, 1, 2):
        raise FieldError("dishes", f"expected 0, 1 or 2, got {dishes!r}")
    dish_pair = choice_param(dish_pair, "dish_pair", ("mirror", "free"))
    if dish_pair == "free" and dishes != 2:
        raise FieldError("dish_pair", f"'free' (a second dish with its own place and size) needs dishes=2, got {dishes}")
    return dishes, dish_pair, int_param(wing_panels, "wing_panels", 1, 32), bool_param(booms, "booms"), bool_param(deck, "deck")


def param_names(dishes: int = 0, *, dish_pair: str = "mirror", wing_panels: int = 1, booms: bool = False,
                deck: bool = False) -> tuple[str, ...]:
    """The names of ``p``'s entries for the parts asked for (module docstring): :data:`PARAM_NAMES`,
    then :data:`DISH_PARAM_NAMES` with dishes, :data:`DISH2_PARAM_NAMES` with a free pair, then
    ``panel_gap`` (``wing_panels > 1``), ``boom_width`` (``booms``), ``deck_a, deck_b, deck_h`` (``deck``)."""
    dishes, dish_pair, wing_panels, booms, deck = _layout(dishes, dish_pair, wing_panels, booms, deck)
    return (PARAM_NAMES + (DISH_PARAM_NAMES if dishes else ()) + (DISH2_PARAM_NAMES if dish_pair == "free" else ())
            + (PART_PARAM_NAMES["wing_panels"] if wing_panels > 1 else ()) + (PART_PARAM_NAMES["booms"] if booms else ())
            + (PART_PARAM_NAMES["deck"] if deck else ()))


def box_wing_twin(p: Any, dishes: int = 0, *, panels: int = 2, dish_pair: str = "mirror", wing_panels: int = 1,
                  booms: bool = False, deck: bool = False) -> np.ndarray:
    """The parameters ``(len(p),)`` of the same satellite turned by 180° about the body z axis
    (``x, y → −x, −y``): the family's one exact symmetry for a mirror pair of panels, so the
    same object seen in a spin whose phase is 180° further (:func:`cssat.scene.attitude.spin_frame`'s
    ``phase_deg``; z is the pole). ``hinge → −hinge``; each dish's vertex ``(x, y, z) → (−x, −y,
    z)`` and azimuth ``φ → φ + π`` (wrapped to [−π, π]) — a mirror pair (``dishes=2``) kept a
    mirror pair by taking the second dish's image as the first: ``(x, −y, z)``, ``φ → −φ``; every
    size, gap, boom, deck and albedo unchanged. The two are one object (the same vertices; the
    same unshadowed light curve), but the model's shadows, cast from each triangle's centroid,
    differ between them — a face's cells are split along diagonals that the turn does not carry
    onto the face it lands on (on the tests' scene the twins' curves differ by 1.8σ rms at 4 cells
    a side, 0.5σ at 8) — so a fit started in one twin can end in another minimum than in the other,
    with the spin shifted to make up for it. ``panels=1`` (one panel, at +y) has no twin
    in the family: refused."""
    names = param_names(dishes, dish_pair=dish_pair, wing_panels=wing_panels, booms=booms, deck=deck)
    if panels != 2:
        raise FieldError("panels", f"a twin (the object turned by 180° about z) needs the mirror pair, panels=2; got {panels!r}")
    q = np.array(p, dtype=np.float64)
    if q.shape != (len(names),) or not np.isfinite(q).all():
        raise FieldError("p", f"expected {len(names)} finite values {names}, got {q.tolist()}")
    i = {n: k for k, n in enumerate(names)}
    q[i["hinge"]] = -q[i["hinge"]]
    for d in ("dish", "dish2"):
        if f"{d}_x" not in i:
            continue
        x, y, az = i[f"{d}_x"], i[f"{d}_y"], i[f"{d}_azimuth"]
        if dishes == 2 and dish_pair == "mirror":  # the second dish's image (x, −y, z), its axis (a_x, −a_y, a_z)
            q[y], q[az] = -q[y], -q[az]
        else:
            q[x], q[y], q[az] = -q[x], -q[y], math.remainder(q[az] + math.pi, 2 * math.pi)
    return q


def _quad_faces(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid coordinates ``s, t (P,)`` in [0, 1] and faces ``(2 nu nv, 3)`` of a quad split in
    ``nu × nv`` cells, counter-clockwise about ``u × v``."""
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return s.ravel(), t.ravel(), faces


def check_params(p: Any, panels: int, divisions: int, dishes: int = 0, **parts: Any) -> Tensor:
    """``p`` as a float tensor ``(len(param_names(dishes, **parts)),)`` (float64 unless a tensor)
    with positive sizes and albedos; errors name the field. ``parts``: ``dish_pair``,
    ``wing_panels``, ``booms``, ``deck`` (:func:`param_names`)."""
    names = param_names(dishes, **parts)
    if panels not in (1, 2):
        raise FieldError("panels", f"expected 1 or 2, got {panels!r}")
    if isinstance(divisions, bool) or not isinstance(divisions, int) or divisions < 1:
        raise FieldError("divisions", f"expected an integer >= 1, got {divisions!r}")
    t = p if isinstance(p, Tensor) else torch.as_tensor(np.asarray(p, dtype=np.float64))
    if not t.is_floating_point():
        t = t.double()
    if t.shape != (len(names),):
        raise FieldError("params", f"expected {len(names)} values {names}, got shape {tuple(t.shape)}")
    for k, name in enumerate(names):
        v = float(t[k].detach())
        rule = {"gap": "finite and >= 0"}.get(name, "finite" if name in SIGNED_NAMES else "finite and > 0")
        bad = not math.isfinite(v) or (name == "gap" and v < 0) or (name not in SIGNED_NAMES + ("gap",) and v <= 0)
        if bad:
            raise FieldError(f"params.{name}", f"must be {rule}, got {v}")
    return t


def _dish(q: Tensor, mirror: bool, rings: int, segments: int) -> tuple[Tensor, np.ndarray, tuple[Tensor, ...]]:
    """One dish of the dish geometry ``q (7,)`` (vertex x, y, z, tilt, azimuth, radius, depth):
    vertices ``(V, 3)``, faces (two-sided), the triangles of :func:`cssat.scene.models.dish` in its
    order, differentiable in ``q``; and its aperture disk ``(centre (3,), unit axis (3,), radius,
    depth)``."""
    x, y, z, tilt, azim, radius, depth = q[:7].unbind()
    sign = -1.0 if mirror else 1.0
    zero = torch.zeros((), dtype=q.dtype, device=q.device)
    c = torch.stack([sign * x, y + zero, z + zero])
    a = torch.stack([sign * torch.sin(tilt) * torch.cos(azim), torch.sin(tilt) * torch.sin(azim), torch.cos(tilt)])
    a = a / torch.linalg.vector_norm(a)
    helper = torch.tensor([1.0, 0, 0] if abs(float(a[0].detach())) < 0.9 else [0, 1.0, 0], dtype=q.dtype, device=q.device)
    e1 = torch.linalg.cross(a, helper)
    e1 = e1 / torch.linalg.vector_norm(e1)
    e2 = torch.linalg.cross(a, e1)
    rr = torch.as_tensor(np.linspace(0, 1, rings + 1)[1:], dtype=q.dtype, device=q.device) * radius
    th = torch.as_tensor(np.linspace(0, 2 * np.pi, segments, endpoint=False), dtype=q.dtype, device=q.device)
    R, TH = torch.meshgrid(rr, th, indexing="ij")
    H = depth * (R / radius) ** 2
    pts = c + (R * torch.cos(TH))[..., None] * e1 + (R * torch.sin(TH))[..., None] * e2 + H[..., None] * a
    verts = torch.cat([c[None], pts.reshape(-1, 3)])
    idx = 1 + np.arange(rings * segments).reshape(rings, segments)
    nxt = np.roll(idx, -1, axis=1)
    fan = np.stack([np.zeros(segments, np.int64), idx[0], nxt[0]], -1)
    quads = [np.stack([idx[:-1], idx[1:], nxt[1:]], -1).reshape(-1, 3), np.stack([idx[:-1], nxt[1:], nxt[:-1]], -1).reshape(-1, 3)]
    faces = np.concatenate([fan] + quads)
    with torch.no_grad():  # orient the concave side towards +axis, as models.dish
        N, _ = _geometry(verts.detach(), faces)
        if float((N @ a.detach()).mean()) < 0:
            faces = faces[:, ::-1].copy()
    return torch.cat([verts, verts]), np.concatenate([faces, faces[:, ::-1] + len(verts)]), (c + depth * a, a, radius, depth)


def _assemble(p: Any, panels: int, divisions: int, dishes: int, dish_rings: int, dish_segments: int,
              **parts: Any) -> tuple[Tensor, np.ndarray, np.ndarray, Tensor, np.ndarray, list]:
    """:func:`box_wing`'s ``(vertices, faces, part, cd)`` and, for the soft shadows
    (:mod:`cssat.inversion.soft_shadow`), each face's occluder ``(F,)`` (the part instance it
    belongs to: the bus 0, each wing, each boom, the deck, each dish) and the occluders:
    ``("box", centre, half-sizes)``, ``("panels", [(origin, u, w, length, width), ...])`` (a wing),
    ``("disk", centre, axis, radius, depth)`` (a dish's aperture, and its bowl's depth)."""
    p = check_params(p, panels, divisions, dishes, **parts)
    names = param_names(dishes, **parts)
    wing_panels, booms, deck = parts.get("wing_panels", 1), parts.get("booms", False), parts.get("deck", False)
    for name, val, lo in (("dish_rings", dish_rings, 1), ("dish_segments", dish_segments, 3)):
        if isinstance(val, bool) or not isinstance(val, int) or val < lo:
            raise FieldError(name, f"expected an integer >= {lo}, got {val!r}")
    q = dict(zip(names, p.unbind()))
    a, b, c, L, W, hinge, gap = (q[k] for k in PARAM_NAMES[:7])
    dev, dt = p.device, p.dtype
    zero = torch.zeros((), dtype=dt, device=dev)

    def vec(x, y, z):
        return torch.stack([x + zero, y + zero, z + zero])

    def box(centre, half, n=divisions):  # (origin, u, v, cells): outward normal u × v, as cssat.scene.models.box
        X, Y, Z = vec(2 * half[0], 0, 0), vec(0, 2 * half[1], 0), vec(0, 0, 2 * half[2])
        lo = centre - half
        faces = ((lo + X, Y, Z), (lo, Z, Y), (lo + Y, Z, X), (lo, X, Z), (lo + Z, X, Y), (lo, Y, X))
        return [(o, u, v, n, n) for o, u, v in faces]

    pieces: list = []  # (quads, part, occluder)
    occluders: list = [("box", vec(0, 0, 0), vec(a, b, c))]
    pieces.append((box(*occluders[0][1:]), 0, 0))
    ny = divisions if wing_panels == 1 else -(-divisions // wing_panels)  # a wing's cells along y shared by its panels
    w = W * torch.stack([torch.sin(hinge), zero, torch.cos(hinge)])
    g = q["panel_gap"] if wing_panels > 1 else zero
    sides = (1.0, -1.0) if panels == 2 else (1.0,)
    for side in sides:
        u = vec(0, side * L, 0)
        wing = []
        for k in range(wing_panels):
            origin = vec(0, side * (b + gap if k == 0 else b + gap + k * (L + g)), 0) - w / 2
            front = (origin, u, w, ny, divisions) if side > 0 else (origin, w, u, divisions, ny)  # the fronts face alike
            back = (origin, front[2], front[1], front[4], front[3])  # two-sided: the back, coincident
            pieces.append(([front, back], 1, len(occluders)))
            wing.append((origin, u, w, L, W))
        occluders.append(("panels", wing))
    if booms:  # a square boom from the bus's ±y face to the wing's root, on the y axis
        for side in sides:
            occluders.append(("box", vec(0, side * (b + gap / 2), 0), vec(q["boom_width"] / 2, gap / 2, q["boom_width"] / 2)))
            pieces.append((box(*occluders[-1][1:], n=1), 0, len(occluders) - 1))  # thin: one cell a face
    if deck:  # a box on the +z deck, centred on it
        occluders.append(("box", vec(0, 0, c + q["deck_h"] / 2), vec(q["deck_a"], q["deck_b"], q["deck_h"] / 2)))
        pieces.append((box(*occluders[-1][1:]), 0, len(occluders) - 1))
    verts, faces, part, inst = [], [], [], []
    grids: dict = {}
    off = 0  # the vertices so far
    for quads, kind, o_idx in pieces:
        for o, uu, vv, nu, nv in quads:
            if (nu, nv) not in grids:
                s_np, t_np, quad = _quad_faces(nu, nv)
                grids[nu, nv] = (torch.as_tensor(s_np, dtype=dt, device=dev)[:, None],
                                 torch.as_tensor(t_np, dtype=dt, device=dev)[:, None], quad)
            s, t, quad = grids[nu, nv]
            faces.append(quad + off)
            verts.append(o + s * uu + t * vv)
            off += len(s)
            part.append(np.full(len(quad), kind))
            inst.append(np.full(len(quad), o_idx))
    free = parts.get("dish_pair", "mirror") == "free"
    for k in range(dishes):
        geo7 = torch.stack([q[f"dish2_{n}" if free and k == 1 else f"dish_{n}"]
                            for n in ("x", "y", "z", "tilt", "azimuth", "radius", "depth")])
        dv, df, disk = _dish(geo7, k == 1 and not free, dish_rings, dish_segments)
        faces.append(df + off)
        verts.append(dv)
        off += len(dv)
        part.append(np.full(len(df), 2))
        inst.append(np.full(len(df), len(occluders)))
        occluders.append(("disk",) + disk)
    part_np = np.concatenate(part)
    part_t = torch.as_tensor(part_np, device=dev)
    cd = torch.where(part_t == 1, q["cd_panel"], q["cd_bus"])
    if dishes:
        cd = torch.where(part_t == 2, q["cd_dish"], cd)
    return torch.cat(verts), np.concatenate(faces), part_np, cd, np.concatenate(inst), occluders


def box_wing(p: Any, *, panels: int = 2, divisions: int = 4, dishes: int = 0, dish_rings: int = 12,
             dish_segments: int = 40, dish_pair: str = "mirror", wing_panels: int = 1, booms: bool = False,
             deck: bool = False) -> tuple[Tensor, np.ndarray, np.ndarray, Tensor]:
    """The box-wing's triangles as torch functions of ``p``: ``(vertices (V, 3) m, faces (F, 3),
    part (F,) 0 bus (and its booms and deck) / 1 panels / 2 dishes, cd (F,))``; vertices and cd
    follow ``p``'s dtype and device and carry its gradient. Every face of the bus, a boom or the
    deck and each panel side is ``divisions²`` cells; each dish ``dish_rings × dish_segments``
    (``dishes`` 0, 1 or 2, ``dish_pair``, ``wing_panels``, ``booms``, ``deck``: module docstring)."""
    v, f, part, cd, _, _ = _assemble(p, panels, divisions, dishes, dish_rings, dish_segments, dish_pair=dish_pair,
                                     wing_panels=wing_panels, booms=booms, deck=deck)
    return v, f, part, cd


def box_wing_mesh(p: Any, *, panels: int = 2, divisions: int = 4, cs: float = 0.0, dishes: int = 0, dish_rings: int = 12,
                  dish_segments: int = 40, **parts: Any) -> Mesh:
    """The box-wing as a :class:`cssat.scene.mesh.Mesh` (numpy; parts ``bus`` (with its booms and
    deck), ``panel`` and, with ``dishes``, ``dish``; ``C_d`` per part from ``p``, ``C_s = cs``),
    e.g. to write as an OBJ or cast shadows on. ``parts``: :func:`box_wing`'s."""
    v, f, part, cd = box_wing(p, panels=panels, divisions=divisions, dishes=dishes, dish_rings=dish_rings,
                              dish_segments=dish_segments, **parts)
    return Mesh(v.detach().cpu().double().numpy(), f, cd.detach().cpu().double().numpy(), cs,
                name="box_wing", part=part, part_names=("bus", "panel", "dish") if dishes else ("bus", "panel"))


def _geometry(v: Tensor, f: np.ndarray) -> tuple[Tensor, Tensor]:
    """Facet unit normals ``(F, 3)`` and areas ``(F,)`` of triangles ``v[f]``, differentiable."""
    idx = torch.as_tensor(f, device=v.device)
    tri = v[idx]
    cross = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=1)
    twice = torch.linalg.vector_norm(cross, dim=1)
    return cross / twice[:, None], twice / 2


def box_wing_visibility(p: Any, sun: Any, observer: Any, *, panels: int = 2, divisions: int = 4, dishes: int = 0,
                        dish_rings: int = 12, dish_segments: int = 40, resolution_m: float | None = None,
                        **parts: Any) -> Tensor:
    """``(T, F)`` bool: each sub-facet neither self- nor observer-shadowed (Embree rays from its
    centroid, :func:`cssat.optics.photometry.shadow_mask`) at the box-wing ``p`` (with its dishes);
    with ``resolution_m`` (m) float64, each sub-facet's fraction lit and seen (rays from points
    that far apart on it: a flat sub-facet's light is then that of a finer grid's).
    Geometry only: the albedos in ``p`` play no part (a fit's iterate may hold one above 1).
    ``parts``: :func:`box_wing`'s."""
    v, f, _, _ = box_wing(p, panels=panels, divisions=divisions, dishes=dishes, dish_rings=dish_rings,
                          dish_segments=dish_segments, **parts)
    return shadow_mask(Mesh(v.detach().cpu().double().numpy(), f, 0.5, 0.0, name="box_wing"), sun, observer,
                       resolution_m=resolution_m)


def box_wing_light_curve(p: Tensor, sun: Any, observer: Any, visible: Tensor | None = None, *, panels: int = 2,
                         divisions: int = 4, range_km: Any = 1.0, irradiance: float = SOLAR_IRRADIANCE_W_M2,
                         dishes: int = 0, dish_rings: int = 12, dish_segments: int = 40, by_part: bool = False,
                         **parts: Any) -> Tensor:
    """The box-wing's diffuse light curve ``(T,)`` in W/m² at ``range_km`` (module docstring's
    equation), differentiable in ``p`` (``(9,)``, ``(17,)`` with ``dishes``, more with the
    ``parts`` of :func:`box_wing`: :func:`param_names`); ``sun, observer (T, 3)`` body-frame unit
    vectors from the object; ``visible (T, F)`` the fixed visibility (None: unshadowed, i.e.
    convex-like). ``by_part``: ``(T, P)`` instead, each part's curve at unit albedo (``P`` 2, or 3
    with dishes: bus (with booms and deck), panels, dishes) — the light curve is linear in the
    albedos, ``y = Y[:, 0] cd_bus + Y[:, 1] cd_panel (+ Y[:, 2] cd_dish)``, so a fit can solve them
    by least squares (:func:`~cssat.inversion.parametric_fit.fit_box_wing`'s ``albedos="profile"``)."""
    v, f, part, cd = box_wing(p, panels=panels, divisions=divisions, dishes=dishes, dish_rings=dish_rings,
                              dish_segments=dish_segments, **parts)
    if by_part:
        cd = torch.ones_like(cd)
    N, A = _geometry(v, f)
    S = check_unit(sun, "sun").to(device=v.device, dtype=v.dtype)
    V = check_unit(observer, "observer").to(device=v.device, dtype=v.dtype)
    if S.shape != V.shape:
        raise FieldError("observer", f"{V.shape[0]} directions for {S.shape[0]} Sun directions")
    r = torch.as_tensor(range_km, dtype=v.dtype, device=v.device).reshape(-1, 1) * 1e3
    val = (S @ N.T).clamp(min=0) * (V @ N.T).clamp(min=0) * (A * cd) * irradiance / (math.pi * r**2)
    if visible is not None:
        vis = torch.as_tensor(visible, device=v.device)
        if tuple(vis.shape) != tuple(val.shape):
            raise FieldError("visible", f"expected shape {tuple(val.shape)}, got {tuple(vis.shape)}")
        val = val * vis.to(v.dtype)
    if by_part:
        onehot = torch.as_tensor(part[:, None] == np.arange(3 if dishes else 2)[None], dtype=v.dtype, device=v.device)
        return val @ onehot
    return val.sum(1)
