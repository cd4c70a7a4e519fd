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
a_z)``), the pair on the ±x faces of :func:`cssat.scene.models.astra_like`. The dishes cast and
take shadows like every other facet. Their specular part is not in the family (Lambertian, as the
rest).

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

from cssat._checks import FieldError
from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, check_unit, shadow_mask
from cssat.scene.mesh import Mesh

__all__ = ["PARAM_NAMES", "DISH_PARAM_NAMES", "param_names", "box_wing", "box_wing_mesh", "box_wing_light_curve",
           "box_wing_visibility"]

PARAM_NAMES = ("a", "b", "c", "length", "width", "hinge", "gap", "cd_bus", "cd_panel")
#: the parameters of the dishes (``dishes=1`` or ``2``), after :data:`PARAM_NAMES`
DISH_PARAM_NAMES = ("dish_x", "dish_y", "dish_z", "dish_tilt", "dish_azimuth", "dish_radius", "dish_depth", "cd_dish")


def param_names(dishes: int = 0) -> tuple[str, ...]:
    """The names of ``p``'s entries: :data:`PARAM_NAMES`, and :data:`DISH_PARAM_NAMES` with dishes."""
    if isinstance(dishes, bool) or dishes not in (0, 1, 2):
        raise FieldError("dishes", f"expected 0, 1 or 2, got {dishes!r}")
    return PARAM_NAMES + (DISH_PARAM_NAMES if dishes else ())


def _quad_faces(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid coordinates ``s, t (P,)`` in [0, 1] and faces ``(2 nu nv, 3)`` of a quad split in
    ``nu × nv`` cells, counter-clockwise about ``u × v``."""
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return s.ravel(), t.ravel(), faces


def check_params(p: Any, panels: int, divisions: int, dishes: int = 0) -> Tensor:
    """``p`` as a float tensor ``(9,)`` (``(17,)`` with dishes; float64 unless a tensor) with
    positive sizes and albedos; errors name the field."""
    names = param_names(dishes)
    if panels not in (1, 2):
        raise FieldError("panels", f"expected 1 or 2, got {panels!r}")
    if isinstance(divisions, bool) or not isinstance(divisions, int) or divisions < 1:
        raise FieldError("divisions", f"expected an integer >= 1, got {divisions!r}")
    t = p if isinstance(p, Tensor) else torch.as_tensor(np.asarray(p, dtype=np.float64))
    if not t.is_floating_point():
        t = t.double()
    if t.shape != (len(names),):
        raise FieldError("params", f"expected {len(names)} values {names}, got shape {tuple(t.shape)}")
    free_sign = ("hinge", "dish_x", "dish_y", "dish_z", "dish_tilt", "dish_azimuth")
    for k, name in enumerate(names):
        v = float(t[k].detach())
        rule = {"gap": "finite and >= 0"}.get(name, "finite" if name in free_sign else "finite and > 0")
        bad = not math.isfinite(v) or (name == "gap" and v < 0) or (name not in free_sign + ("gap",) and v <= 0)
        if bad:
            raise FieldError(f"params.{name}", f"must be {rule}, got {v}")
    return t


def _dish(q: Tensor, mirror: bool, rings: int, segments: int) -> tuple[Tensor, np.ndarray]:
    """One dish of the dish parameters ``q (8,)``: vertices ``(V, 3)`` and faces (two-sided), the
    triangles of :func:`cssat.scene.models.dish` in its order, differentiable in ``q``."""
    x, y, z, tilt, azim, radius, depth, _ = q.unbind()
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
    return torch.cat([verts, verts]), np.concatenate([faces, faces[:, ::-1] + len(verts)])


def box_wing(p: Any, *, panels: int = 2, divisions: int = 4, dishes: int = 0, dish_rings: int = 12,
             dish_segments: int = 40) -> tuple[Tensor, np.ndarray, np.ndarray, Tensor]:
    """The box-wing's triangles as torch functions of ``p``: ``(vertices (V, 3) m, faces (F, 3),
    part (F,) 0 bus / 1 panels / 2 dishes, cd (F,))``; vertices and cd follow ``p``'s dtype and
    device and carry its gradient. Every face of the bus and each panel side is ``divisions²``
    cells; each dish ``dish_rings × dish_segments`` (``dishes`` 0, 1 or 2: module docstring)."""
    p = check_params(p, panels, divisions, dishes)
    for name, val, lo in (("dish_rings", dish_rings, 1), ("dish_segments", dish_segments, 3)):
        if isinstance(val, bool) or not isinstance(val, int) or val < lo:
            raise FieldError(name, f"expected an integer >= {lo}, got {val!r}")
    a, b, c, L, W, hinge, gap, cd_bus, cd_panel = p[:len(PARAM_NAMES)].unbind()
    dev, dt = p.device, p.dtype
    s_np, t_np, quad = _quad_faces(divisions, divisions)
    s = torch.as_tensor(s_np, dtype=dt, device=dev)[:, None]
    t = torch.as_tensor(t_np, dtype=dt, device=dev)[:, None]
    zero = torch.zeros((), dtype=dt, device=dev)

    def vec(x, y, z):
        return torch.stack([x + zero, y + zero, z + zero])

    X, Y, Z = vec(2 * a, 0, 0), vec(0, 2 * b, 0), vec(0, 0, 2 * c)
    quads = [  # (origin, u, v): outward normal u × v, as cssat.scene.models.box
        (vec(a, -b, -c), Y, Z), (vec(-a, -b, -c), Z, Y), (vec(-a, b, -c), Z, X),
        (vec(-a, -b, -c), X, Z), (vec(-a, -b, c), X, Y), (vec(-a, -b, -c), Y, X),
    ]
    n_bus = len(quads)
    w = W * torch.stack([torch.sin(hinge), zero, torch.cos(hinge)])
    for side in ((1.0, -1.0) if panels == 2 else (1.0,)):
        u = vec(0, side * L, 0)
        origin = vec(0, side * (b + gap), 0) - w / 2
        front = (origin, u, w) if side > 0 else (origin, w, u)  # the two wings' fronts face alike
        quads += [front, (front[0], front[2], front[1])]  # two-sided: the back, coincident
    verts, faces, part = [], [], []
    for k, (o, u, v) in enumerate(quads):
        verts.append(o + s * u + t * v)
        faces.append(quad + k * len(s_np))
        part.append(np.full(len(quad), int(k >= n_bus)))
    off = sum(len(v) for v in verts)
    for k in range(dishes):
        dv, df = _dish(p[len(PARAM_NAMES):], k == 1, dish_rings, dish_segments)
        verts.append(dv)
        faces.append(df + off)
        part.append(np.full(len(df), 2))
        off += len(dv)
    part_np = np.concatenate(part)
    part_t = torch.as_tensor(part_np, device=dev)
    cd = torch.where(part_t == 1, cd_panel, cd_bus)
    if dishes:
        cd = torch.where(part_t == 2, p[-1], cd)
    return torch.cat(verts), np.concatenate(faces), part_np, cd


def box_wing_mesh(p: Any, *, panels: int = 2, divisions: int = 4, cs: float = 0.0, dishes: int = 0, dish_rings: int = 12,
                  dish_segments: int = 40) -> Mesh:
    """The box-wing as a :class:`cssat.scene.mesh.Mesh` (numpy; parts ``bus``, ``panel`` and,
    with ``dishes``, ``dish``; ``C_d`` per part from ``p``, ``C_s = cs``), e.g. to write as an
    OBJ or cast shadows on."""
    v, f, part, cd = box_wing(p, panels=panels, divisions=divisions, dishes=dishes, dish_rings=dish_rings,
                              dish_segments=dish_segments)
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
                        dish_rings: int = 12, dish_segments: int = 40) -> Tensor:
    """``(T, F)`` bool: each sub-facet neither self- nor observer-shadowed (Embree rays from its
    centroid, :func:`cssat.optics.photometry.shadow_mask`) at the box-wing ``p`` (with its dishes).
    Geometry only: the albedos in ``p`` play no part (a fit's iterate may hold one above 1)."""
    v, f, _, _ = box_wing(p, panels=panels, divisions=divisions, dishes=dishes, dish_rings=dish_rings,
                          dish_segments=dish_segments)
    return shadow_mask(Mesh(v.detach().cpu().double().numpy(), f, 0.5, 0.0, name="box_wing"), sun, observer)


def box_wing_light_curve(p: Tensor, sun: Any, observer: Any, visible: Tensor | None = None, *, panels: int = 2,
                         divisions: int = 4, range_km: Any = 1.0, irradiance: float = SOLAR_IRRADIANCE_W_M2,
                         dishes: int = 0, dish_rings: int = 12, dish_segments: int = 40) -> Tensor:
    """The box-wing's diffuse light curve ``(T,)`` in W/m² at ``range_km`` (module docstring's
    equation), differentiable in ``p (9,)`` (``(17,)`` with ``dishes``); ``sun, observer (T, 3)``
    body-frame unit vectors from the object; ``visible (T, F)`` the fixed visibility (None:
    unshadowed, i.e. convex-like)."""
    v, f, _, cd = box_wing(p, panels=panels, divisions=divisions, dishes=dishes, dish_rings=dish_rings,
                           dish_segments=dish_segments)
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
    return val.sum(1)
