"""A parametric box-wing satellite and its differentiable, self-shadowed light curve (issue 36 point 2).

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

__all__ = ["PARAM_NAMES", "box_wing", "box_wing_mesh", "box_wing_light_curve", "box_wing_visibility"]

PARAM_NAMES = ("a", "b", "c", "length", "width", "hinge", "gap", "cd_bus", "cd_panel")


def _quad_faces(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid coordinates ``s, t (P,)`` in [0, 1] and faces ``(2 nu nv, 3)`` of a quad split in
    ``nu × nv`` cells, counter-clockwise about ``u × v``."""
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return s.ravel(), t.ravel(), faces


def check_params(p: Any, panels: int, divisions: int) -> Tensor:
    """``p`` as a float tensor ``(9,)`` (float64 unless a tensor) with positive sizes and albedos; errors name the field."""
    if panels not in (1, 2):
        raise FieldError("panels", f"expected 1 or 2, got {panels!r}")
    if isinstance(divisions, bool) or not isinstance(divisions, int) or divisions < 1:
        raise FieldError("divisions", f"expected an integer >= 1, got {divisions!r}")
    t = p if isinstance(p, Tensor) else torch.as_tensor(np.asarray(p, dtype=np.float64))
    if not t.is_floating_point():
        t = t.double()
    if t.shape != (len(PARAM_NAMES),):
        raise FieldError("params", f"expected {len(PARAM_NAMES)} values {PARAM_NAMES}, got shape {tuple(t.shape)}")
    for k, name in enumerate(PARAM_NAMES):
        v = float(t[k].detach())
        rule = {"hinge": "finite", "gap": "finite and >= 0"}.get(name, "finite and > 0")
        bad = not math.isfinite(v) or (name == "gap" and v < 0) or (name not in ("hinge", "gap") and v <= 0)
        if bad:
            raise FieldError(f"params.{name}", f"must be {rule}, got {v}")
    return t


def box_wing(p: Any, *, panels: int = 2, divisions: int = 4) -> tuple[Tensor, np.ndarray, np.ndarray, Tensor]:
    """The box-wing's triangles as torch functions of ``p``: ``(vertices (V, 3) m, faces (F, 3),
    part (F,) 0 bus / 1 panels, cd (F,))``; vertices and cd follow ``p``'s dtype and device and
    carry its gradient. Every face of the bus and each panel side is ``divisions²`` cells."""
    p = check_params(p, panels, divisions)
    a, b, c, L, W, hinge, gap, cd_bus, cd_panel = p.unbind()
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
    part_np = np.concatenate(part)
    cd = torch.where(torch.as_tensor(part_np, device=dev) == 1, cd_panel, cd_bus)
    return torch.cat(verts), np.concatenate(faces), part_np, cd


def box_wing_mesh(p: Any, *, panels: int = 2, divisions: int = 4, cs: float = 0.0) -> Mesh:
    """The box-wing as a :class:`cssat.scene.mesh.Mesh` (numpy; parts ``bus`` and ``panel``,
    ``C_d`` per part from ``p``, ``C_s = cs``), e.g. to write as an OBJ or cast shadows on."""
    v, f, part, cd = box_wing(p, panels=panels, divisions=divisions)
    return Mesh(v.detach().cpu().double().numpy(), f, cd.detach().cpu().double().numpy(), cs,
                name="box_wing", part=part, part_names=("bus", "panel"))


def _geometry(v: Tensor, f: np.ndarray) -> tuple[Tensor, Tensor]:
    """Facet unit normals ``(F, 3)`` and areas ``(F,)`` of triangles ``v[f]``, differentiable."""
    idx = torch.as_tensor(f, device=v.device)
    tri = v[idx]
    cross = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=1)
    twice = torch.linalg.vector_norm(cross, dim=1)
    return cross / twice[:, None], twice / 2


def box_wing_visibility(p: Any, sun: Any, observer: Any, *, panels: int = 2, divisions: int = 4) -> Tensor:
    """``(T, F)`` bool: each sub-facet neither self- nor observer-shadowed (Embree rays from its
    centroid, :func:`cssat.optics.photometry.shadow_mask`) at the box-wing ``p``."""
    return shadow_mask(box_wing_mesh(p, panels=panels, divisions=divisions), sun, observer)


def box_wing_light_curve(p: Tensor, sun: Any, observer: Any, visible: Tensor | None = None, *, panels: int = 2,
                         divisions: int = 4, range_km: Any = 1.0, irradiance: float = SOLAR_IRRADIANCE_W_M2) -> Tensor:
    """The box-wing's diffuse light curve ``(T,)`` in W/m² at ``range_km`` (module docstring's
    equation), differentiable in ``p (9,)``; ``sun, observer (T, 3)`` body-frame unit vectors from
    the object; ``visible (T, F)`` the fixed visibility (None: unshadowed, i.e. convex-like)."""
    v, f, _, cd = box_wing(p, panels=panels, divisions=divisions)
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
