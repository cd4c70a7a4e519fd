"""Satellite models: procedural parts (box, panel, dish, cylinder), two procedural spacecraft
(Astra 1KR-like, TESS-like) and the config's choice of a model, procedural or a mesh file.

Units are metres; every part takes the facets' diffuse and specular coefficients ``cd``, ``cs``
(paper Eq. 8). The container, :func:`~cssat.scene.mesh.merge` and file loading are in
:mod:`cssat.scene.mesh`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cssat._checks import FieldError, choice_param, float_param
from cssat.scene.materials import check_material, paint
from cssat.scene.mesh import Mesh, load_mesh, merge

if TYPE_CHECKING:
    from typing import Sequence

__all__ = ["MAX_RADIUS_M", "MODELS", "astra_like", "box", "cylinder", "dish", "get_model", "panel", "tess_like"]


# ---------------------------------------------------------------- procedural parts


def _grid_quad(origin, u, v, nu: int, nv: int):
    """Vertices and faces of a planar quad ``origin + s u + t v`` (s, t ∈ [0, 1]) split into
    ``nu × nv`` cells, two triangles each, normal along ``u × v``."""
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    verts = origin + s[..., None] * u + t[..., None] * v
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return verts.reshape(-1, 3), faces


def _mesh(parts, cd, cs, name=""):
    verts, faces, off = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + off)
        off += len(v)
    return Mesh(np.concatenate(verts), np.concatenate(faces), cd, cs, name=name)


def box(size: Sequence[float], center: Sequence[float] = (0.0, 0.0, 0.0), divisions: int = 1, cd: float = 0.8, cs: float = 0.2) -> Mesh:
    """A closed axis-aligned box of ``size`` (m) with outward normals; each face is split into a
    ``divisions × divisions`` grid."""
    sx, sy, sz = (float(s) / 2 for s in size)
    c = np.asarray(center, dtype=np.float64)
    n = int(divisions)
    X, Y, Z = np.eye(3)
    parts = [
        _grid_quad(c + [sx, -sy, -sz], 2 * sy * Y, 2 * sz * Z, n, n),  # +x
        _grid_quad(c + [-sx, -sy, -sz], 2 * sz * Z, 2 * sy * Y, n, n),  # -x
        _grid_quad(c + [-sx, sy, -sz], 2 * sz * Z, 2 * sx * X, n, n),  # +y
        _grid_quad(c + [-sx, -sy, -sz], 2 * sx * X, 2 * sz * Z, n, n),  # -y
        _grid_quad(c + [-sx, -sy, sz], 2 * sx * X, 2 * sy * Y, n, n),  # +z
        _grid_quad(c + [-sx, -sy, -sz], 2 * sy * Y, 2 * sx * X, n, n),  # -z
    ]
    return _mesh(parts, cd, cs, "box")


def panel(u: Sequence[float], v: Sequence[float], origin: Sequence[float], divisions: tuple[int, int] = (1, 1), cd: float = 0.8, cs: float = 0.2, two_sided: bool = True) -> Mesh:
    """A flat panel ``origin + s u + t v`` (m), front normal ``u × v``; ``two_sided`` adds the
    back facets (coincident, opposite normals)."""
    u, v, origin = (np.asarray(a, dtype=np.float64) for a in (u, v, origin))
    parts = [_grid_quad(origin, u, v, *divisions)]
    if two_sided:
        parts.append(_grid_quad(origin, v, u, divisions[1], divisions[0]))
    return _mesh(parts, cd, cs, "panel")


def _frame(axis):
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1), a


def dish(radius: float, depth: float, center: Sequence[float], axis: Sequence[float], rings: int = 8, segments: int = 32,
         cd: float = 0.8, cs: float = 0.2, two_sided: bool = True) -> Mesh:
    """A parabolic reflector of aperture ``radius`` and ``depth`` (m), its vertex at ``center``,
    opening along ``axis``; the concave side faces ``axis``. ``rings × segments`` cells."""
    e1, e2, a = _frame(axis)
    c = np.asarray(center, dtype=np.float64)
    rr = np.linspace(0, 1, rings + 1)[1:] * radius
    th = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    R, TH = np.meshgrid(rr, th, indexing="ij")
    H = depth * (R / radius) ** 2
    pts = c + (R * np.cos(TH))[..., None] * e1 + (R * np.sin(TH))[..., None] * e2 + H[..., None] * a
    verts = np.concatenate([c[None], pts.reshape(-1, 3)])
    idx = 1 + np.arange(rings * segments).reshape(rings, segments)
    nxt = np.roll(idx, -1, axis=1)
    fan = np.stack([np.zeros(segments, np.int64), idx[0], nxt[0]], -1)
    quads = [np.stack([idx[:-1], idx[1:], nxt[1:]], -1).reshape(-1, 3),
             np.stack([idx[:-1], nxt[1:], nxt[:-1]], -1).reshape(-1, 3)]
    faces = np.concatenate([fan] + quads)
    # orient the concave (inner) side towards +axis
    m = Mesh(verts, faces, cd, cs)
    if np.mean(m.normals @ a) < 0:
        faces = faces[:, ::-1]
    parts = [(verts, faces)]
    if two_sided:
        parts.append((verts, faces[:, ::-1]))
    return _mesh(parts, cd, cs, "dish")


def cylinder(radius: float, length: float, center: Sequence[float], axis: Sequence[float], segments: int = 24, capped: bool = True,
             cd: float = 0.8, cs: float = 0.2) -> Mesh:
    """A closed cylinder (m) along ``axis`` centred at ``center``, outward normals."""
    e1, e2, a = _frame(axis)
    c = np.asarray(center, dtype=np.float64)
    th = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = radius * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
    bottom, top = c - 0.5 * length * a + ring, c + 0.5 * length * a + ring
    verts = np.concatenate([bottom, top, [c - 0.5 * length * a, c + 0.5 * length * a]])
    i = np.arange(segments)
    j = (i + 1) % segments
    faces = [np.stack([i, j, segments + j], -1), np.stack([i, segments + j, segments + i], -1)]
    if capped:
        b0, t0 = 2 * segments, 2 * segments + 1
        faces += [np.stack([np.full(segments, b0), j, i], -1), np.stack([np.full(segments, t0), segments + i, segments + j], -1)]
    return _mesh([(verts, np.concatenate(faces))], cd, cs, "cylinder")


# ---------------------------------------------------------------- procedural spacecraft


def _dress(material: str | None, cd: float | None, cs: float | None) -> tuple[bool, float, float]:
    """``(real, cd, cs)``: whether the parts wear their real materials (:mod:`cssat.scene.materials`)
    or every facet the uniform ``cd``/``cs``. ``material`` None: real unless ``cd`` or ``cs`` is
    given (the old calls keep their uniform model); ``"uniform"``: ``cd``, ``cs`` (default 0.8, 0.2)."""
    check_material(material)
    if material is None:
        material = "uniform" if cd is not None or cs is not None else "satellite"
    if material == "satellite":
        for fname, val in (("cd", cd), ("cs", cs)):
            if val is not None:
                raise FieldError(fname, f"a uniform {fname} ({val!r}) needs material='uniform'; material='satellite' "
                                        "takes each part's from cssat.scene.materials")
        return True, 0.8, 0.2
    return False, 0.8 if cd is None else float(cd), 0.2 if cs is None else float(cs)


def _assemble(pieces: list, real: bool, name: str) -> Mesh:
    """Merge ``(mesh, material names)`` pieces, each painted with its materials when ``real``."""
    return merge([paint(m, names) if real else m for m, names in pieces], name=name)


def _halves(mesh: Mesh, first: str, second: str) -> list:
    """Per-facet names of a two-sided part: ``first`` on its front facets, ``second`` on its back."""
    h = len(mesh) // 2
    return [first] * h + [second] * (len(mesh) - h)


def astra_like(cd: float | None = None, cs: float | None = None, array_angle_deg: float = 0.0,
               material: str | None = None, array_tracking: str = "fixed",
               array_limits_deg: Sequence[float] = (-180.0, 180.0)) -> Mesh:
    """A procedural GEO communications satellite like Astra 1KR (paper Fig. 3b), 4,028 facets
    like the paper's model.

    Body frame as in :func:`cssat.scene.attitude.nadir_pointing_frame`: +z to the Earth, ±y the
    solar-array axis (perpendicular to the orbit), ±x east/west. A 2.6 × 2.4 × 3.6 m bus, two
    wings of four 2.4 × 2.2 m two-sided solar panels on 1.5 m yokes (≈ 23 m span), and two
    2.3 m two-sided parabolic reflectors on the ±x faces, facing the Earth.

    ``array_angle_deg``: the solar-array drive angle, both wings turned about the ±y axis by
    that angle from the y–z plane (0: the panels' normals along ±x). A nadir-pointing satellite's
    arrays track the Sun; a defunct one's are frozen at some angle — which also breaks the
    bus's symmetry under a half turn about its axes (a Lambertian light curve of the symmetric
    model repeats every half rotation, so its period is ambiguous).

    Materials (``material="satellite"``, the default unless ``cd``/``cs`` are given; parts named
    by material, :mod:`cssat.scene.materials`): the bus in MLI with OSR radiators on its ±y
    (north/south) faces, solar cells on the wings' side facing ``(−cos θ, 0, sin θ)`` (θ the
    array angle: +z, the Sun at local midnight, at 90°) and CFRP on their backs, reflectors behind
    germanium-coated Kapton sunshields (CFRP behind), aluminium yokes and plate. ``material="uniform"``: every facet
    ``cd``, ``cs`` (default 0.8, 0.2, the paper's).

    ``array_tracking``: ``"fixed"`` (default: the wings stay at ``array_angle_deg``, a plain
    :class:`~cssat.scene.Mesh`) or ``"sun"``: each wing (panels and yoke) on a 1-axis drive about
    body +y through the bus centre, turned at every time sample to bring the cells' normal as
    close to the Sun as ``array_limits_deg`` (``[lo, hi]`` on the drive angle, deg; ``[-180,
    180]``: no limit) allow — an :class:`~cssat.scene.attitudes.ArticulatedMesh` in its built pose
    (``array_angle_deg``) that the photometry and the renderer pose per sample. A 1-axis drive
    cannot follow the Sun out of the orbit plane (:class:`~cssat.scene.attitudes.Joint`).
    """
    from cssat.scene.attitudes import TRACKING_CHOICES, check_limits  # local: the articulation lives with the attitudes

    choice_param(array_tracking, "array_tracking", TRACKING_CHOICES)
    limits = check_limits(array_limits_deg)
    real, cd, cs = _dress(material, cd, cs)
    ang = math.radians(float_param(array_angle_deg, "array_angle_deg", -360.0, 360.0))
    v = 2.4 * np.array([math.sin(ang), 0.0, math.cos(ang)])
    bus = box((2.6, 2.4, 3.6), divisions=4, cd=cd, cs=cs)
    pieces = [(bus, np.where(np.abs(bus.normals[:, 1]) > 0.9, "osr", "mli"))]
    for side in (1, -1):
        pieces.append((box((0.08, 1.5, 0.08), center=(0, side * (1.2 + 0.75), 0), cd=cd, cs=cs), "aluminium"))
        for k in range(4):
            y0 = 2.7 + 2.3 * k if side > 0 else -(2.7 + 2.3 * k + 2.2)
            p = panel((0, 2.2, 0), v, np.array([0.0, y0, 0.0]) - v / 2, divisions=(2, 2), cd=cd, cs=cs)
            pieces.append((p, _halves(p, "panel_back", "solar_cell")))
        d = dish(1.15, 0.35, center=(side * 1.65, 0, 0.6), axis=(side * 0.35, 0, 1.0), rings=12, segments=40, cd=cd, cs=cs)
        pieces.append((d, _halves(d, "ge_kapton", "panel_back")))
    # a two-sided telemetry plate on the anti-Earth face (4 facets): 4,028 facets in all
    pieces.append((panel((0.5, 0, 0), (0, 0.5, 0), (-0.25, -0.25, -1.85), cd=cd, cs=cs), "aluminium"))
    mesh = _assemble(pieces, real, "astra_like")
    if array_tracking == "fixed":
        return mesh
    from cssat.scene.attitudes import ArticulatedMesh, Joint  # local: the articulation lives with the attitudes

    start = np.cumsum([0] + [len(m) for m, _ in pieces])
    joints = []
    for w, side in enumerate((1, -1)):  # pieces 1 + 6w .. 5 + 6w: the yoke and the four panels of that wing
        facets = np.concatenate([np.arange(start[k], start[k + 1]) for k in range(1 + 6 * w, 6 + 6 * w)])
        joints.append(Joint(facets, axis=(0.0, 1.0, 0.0), pivot=(0.0, 0.0, 0.0), normal=(-math.cos(ang), 0.0, math.sin(ang)),
                            angle0_deg=math.degrees(ang), tracking=array_tracking, limits_deg=limits,
                            name="+y wing" if side > 0 else "-y wing"))
    return ArticulatedMesh(mesh.vertices, mesh.faces, mesh.cd, mesh.cs, name=mesh.name, part=mesh.part,
                           part_names=mesh.part_names, joints=tuple(joints))


def tess_like(cd: float | None = None, cs: float | None = None, material: str | None = None) -> Mesh:
    """A procedural spacecraft like NASA's TESS (the paper's target), in metres: a 1.2 × 1.2 ×
    1.0 m bus, four camera lens hoods in a 2 × 2 block with a sunshade on the +z side, two
    solar-array wings along ±y, and a high-gain antenna dish below the bus. Materials as
    :func:`astra_like`'s (``material``): an MLI bus, black lens hoods, a white camera deck, solar
    cells on the wings' +x side (CFRP behind), a white dish on an aluminium mast."""
    real, cd, cs = _dress(material, cd, cs)
    pieces = [(box((1.2, 1.2, 1.0), divisions=4, cd=cd, cs=cs), "mli")]
    for ix in (-1, 1):
        for iy in (-1, 1):
            pieces.append((cylinder(0.2, 0.6, center=(0.26 * ix, 0.26 * iy, 0.85), axis=(0, 0, 1), segments=24, cd=cd, cs=cs),
                           "black_paint"))
    pieces.append((box((1.3, 1.3, 0.08), center=(0, 0, 0.56), divisions=3, cd=cd, cs=cs), "white_paint"))  # camera deck
    for side in (1, -1):
        for k in range(2):
            y0 = 0.7 + 1.05 * k if side > 0 else -(0.7 + 1.05 * k + 1.0)
            p = panel((0, 1.0, 0), (0, 0, 1.3), (0, y0, -0.65), divisions=(3, 4), cd=cd, cs=cs)
            pieces.append((p, _halves(p, "solar_cell", "panel_back")))
    d = dish(0.35, 0.1, center=(0, 0, -0.75), axis=(0, 0, -1), rings=6, segments=24, cd=cd, cs=cs)
    pieces.append((d, _halves(d, "white_paint", "panel_back")))
    pieces.append((cylinder(0.05, 0.25, center=(0, 0, -0.625), axis=(0, 0, 1), segments=8, cd=cd, cs=cs), "aluminium"))
    return _assemble(pieces, real, "tess_like")


#: procedural models by name
MODELS = {"astra_like": astra_like, "tess_like": tess_like}


def get_model(name: str = "astra_like", path: str | None = None, scale: float = 1.0, cd: float | None = None,
              cs: float | None = None, array_angle_deg: float | None = None, material: str | None = None,
              array_tracking: str = "fixed", array_limits_deg: Sequence[float] = (-180.0, 180.0)) -> Mesh:
    """A satellite model from config: a procedural one by ``name`` (``astra_like``, ``tess_like``)
    or, with ``name="file"``, the mesh file at ``path`` (scaled to metres by ``scale``). ``scale``
    multiplies a procedural model too (its native size is metres); the result must be a satellite:
    at most :data:`MAX_RADIUS_M` from its centre to its farthest vertex. ``array_angle_deg``: the
    ``astra_like`` model's solar-array angle (null: 0; an error for the other models).
    ``array_tracking``: ``fixed`` (the arrays stay at that angle) or ``sun`` (``astra_like`` only:
    its arrays turn to the Sun at every sample within ``array_limits_deg``, ``[lo, hi]`` deg,
    ``[-180, 180]`` unlimited; :func:`astra_like`).

    ``material``: ``"satellite"`` dresses a procedural model's parts in real materials
    (:mod:`cssat.scene.materials`; the default unless ``cd``/``cs`` are given), ``"uniform"``
    gives every facet ``cd``/``cs`` (default 0.8/0.2, the paper's). A file takes ``cd``/``cs``
    (default 0.8/0.2) where it has no ``cd``/``cs`` face attributes; ``"satellite"`` is an error
    for it (its parts are not known to be of any material)."""
    check_material(material)
    for fname, val in (("cd", cd), ("cs", cs)):
        if val is not None and not (isinstance(val, (int, float)) and not isinstance(val, bool) and math.isfinite(val) and val >= 0):
            raise FieldError(fname, f"must be a number >= 0, got {val!r}")
    if (0.8 if cd is None else cd) + (0.2 if cs is None else cs) > 1 + 1e-12:
        raise FieldError("cs", f"cd + cs = {(0.8 if cd is None else cd) + (0.2 if cs is None else cs):g} > 1: a surface "
                               "cannot reflect more light than arrives (cd + cs <= 1; defaults 0.8 and 0.2)")
    if not (isinstance(scale, (int, float)) and not isinstance(scale, bool) and math.isfinite(scale) and scale > 0):
        raise FieldError("scale", f"must be a number > 0 (the model's units in metres), got {scale!r}")
    if name == "file":
        if not path:
            raise FieldError("path", "required when name is 'file' (model.path=<a mesh file>)")
        if material == "satellite":
            raise FieldError("material", "'satellite' dresses the procedural models' parts; a file takes "
                                         "'uniform' (or null) and its own cd/cs face attributes")
        mesh = load_mesh(path, scale=scale, cd=0.8 if cd is None else cd, cs=0.2 if cs is None else cs)
    elif name not in MODELS:
        raise FieldError("name", f"expected one of {sorted(MODELS) + ['file']}, got {name!r}")
    else:
        extra = {}
        from cssat.scene.attitudes import TRACKING_CHOICES, check_limits  # local: the articulation lives with the attitudes

        choice_param(array_tracking, "array_tracking", TRACKING_CHOICES)
        limits = check_limits(array_limits_deg)
        if array_tracking != "fixed":
            if name != "astra_like":
                raise FieldError("array_tracking", f"only the astra_like model has solar-array drives, not {name!r} "
                                                   f"(expected 'fixed' for it)")
            extra.update(array_tracking=array_tracking, array_limits_deg=limits)
        if array_angle_deg is not None:
            if name != "astra_like":
                raise FieldError("array_angle_deg", f"only the astra_like model has solar arrays to turn, not {name!r}")
            extra["array_angle_deg"] = array_angle_deg
        mesh = MODELS[name](cd=cd, cs=cs, material=material, **extra)
        if scale != 1.0 and hasattr(mesh, "joints"):
            mesh = mesh.scaled(float(scale))
        elif scale != 1.0:
            mesh = Mesh(mesh.vertices * float(scale), mesh.faces, mesh.cd, mesh.cs, name=mesh.name, part=mesh.part,
                        part_names=mesh.part_names)
    if not mesh.radius <= MAX_RADIUS_M:
        raise FieldError("scale", f"the model reaches {mesh.radius:.3g} m from its centre; a satellite is at most "
                                  f"{MAX_RADIUS_M:g} m (is model.scale in metres per file unit?)")
    return mesh


#: the largest satellite cssat models: the ISS spans ~110 m; 1 km leaves room, 1e30 m is an error
MAX_RADIUS_M = 1000.0
