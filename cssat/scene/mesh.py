"""Triangle-mesh satellites: a small container, file loading through trimesh, and procedural models.

Units are metres. Every facet carries its own diffuse and specular coefficients ``Cd``, ``Cs``
(paper Eq. 8; default 0.8 / 0.2, aluminium). Facets are one-sided: a surface that reflects on both
sides (a solar panel, a reflector) is two coincident facets with opposite normals.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cssat._checks import FieldError, FieldTypeError, float_param

if TYPE_CHECKING:
    from typing import Sequence

    import trimesh

__all__ = ["MODELS", "Mesh", "astra_like", "box", "cylinder", "dish", "get_model", "load_mesh", "merge", "panel", "tess_like"]


@dataclass
class Mesh:
    """A triangle mesh with per-facet material.

    vertices : (V, 3) float64, metres (body frame)
    faces : (F, 3) int64, counter-clockwise seen from the front (normal side)
    cd, cs : (F,) diffuse and specular reflection coefficients (Eq. 8)
    part : (F,) int64 or None: each facet's body (an index into ``part_names``), kept from a
        multi-body file or ``trimesh.Scene`` — the materials a BRDF may be given by name
    """

    vertices: np.ndarray
    faces: np.ndarray
    cd: np.ndarray
    cs: np.ndarray
    name: str = ""
    _cache: dict = field(default_factory=dict, repr=False, compare=False)
    part: np.ndarray | None = None
    part_names: tuple = ()

    def __post_init__(self):
        if self.part is not None:
            self.part = np.asarray(self.part, dtype=np.int64)
            if self.part.shape != (len(self.faces),) or (len(self.part) and (self.part.min() < 0 or self.part.max() >= len(self.part_names))):
                raise FieldError("mesh.part", f"expected {len(self.faces)} indices into {len(self.part_names)} part names")
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int64)
        F = len(self.faces)
        self.cd = np.broadcast_to(np.asarray(self.cd, dtype=np.float64), (F,)).copy()
        self.cs = np.broadcast_to(np.asarray(self.cs, dtype=np.float64), (F,)).copy()
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise FieldError("mesh.vertices", f"expected shape (V, 3), got {self.vertices.shape}")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise FieldError("mesh.faces", f"expected shape (F, 3), got {self.faces.shape}")
        if F and (self.faces.min() < 0 or self.faces.max() >= len(self.vertices)):
            raise FieldError("mesh.faces", "vertex index out of range")
        if not np.isfinite(self.vertices).all():
            raise FieldError("mesh.vertices", "contain NaN or Inf")
        for name, arr in (("mesh.cd", self.cd), ("mesh.cs", self.cs)):
            if np.any(arr < 0) or not np.isfinite(arr).all():
                raise FieldError(name, "reflection coefficients must be finite and >= 0")

    def __len__(self) -> int:
        return len(self.faces)

    @property
    def triangles(self) -> np.ndarray:
        """``(F, 3, 3)`` vertex coordinates of each facet (m)."""
        return self.vertices[self.faces]

    def _geometry(self):
        if "geom" not in self._cache:
            tri = self.triangles
            cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            dbl = np.linalg.norm(cross, axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                normals = cross / dbl[:, None]
            self._cache["geom"] = (normals, 0.5 * dbl, tri.mean(axis=1))
        return self._cache["geom"]

    @property
    def normals(self) -> np.ndarray:
        """``(F, 3)`` unit outward normals (right-hand rule on the vertex order)."""
        return self._geometry()[0]

    @property
    def areas(self) -> np.ndarray:
        """``(F,)`` facet areas ``A_i`` (m²)."""
        return self._geometry()[1]

    @property
    def centroids(self) -> np.ndarray:
        """``(F, 3)`` facet centroids (m)."""
        return self._geometry()[2]

    @property
    def radius(self) -> float:
        """Largest distance of a vertex from the origin (m): sets a field of view that holds the
        object in every orientation."""
        return float(np.linalg.norm(self.vertices, axis=1).max())

    def to_trimesh(self) -> trimesh.Trimesh:
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False, validate=False)

    @classmethod
    def from_trimesh(cls, tm: trimesh.Trimesh, cd: float = 0.8, cs: float = 0.2, name: str | None = None) -> "Mesh":
        """A :class:`Mesh` of a ``trimesh.Trimesh`` (metres, as it is: no centring or welding).
        Per-facet ``cd``/``cs`` come from the mesh's ``face_attributes`` of those names when it has
        them, else the given constants."""
        attrs = getattr(tm, "face_attributes", None) or {}
        return cls(np.asarray(tm.vertices), np.asarray(tm.faces), attrs.get("cd", cd), attrs.get("cs", cs),
                   name=name if name is not None else str(getattr(tm, "metadata", {}).get("name", "") or ""))


    @classmethod
    def from_scene(cls, scene: Any, cd: float = 0.8, cs: float = 0.2, name: str | None = None) -> "Mesh":
        """One :class:`Mesh` of a ``trimesh.Scene`` (what GLB/GLTF files load as): every body's
        triangles placed by its node's transform and concatenated; each body is a ``part`` named
        by its material (else its node), with its own ``cd``/``cs`` face attributes when it has
        them."""
        import trimesh

        verts, faces, cds, css, part, names, off = [], [], [], [], [], [], 0
        for node in scene.graph.nodes_geometry:
            transform, geom = scene.graph[node]
            g = scene.geometry[geom]
            if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
                continue
            attrs = getattr(g, "face_attributes", None) or {}
            F = len(g.faces)
            verts.append(trimesh.transform_points(np.asarray(g.vertices, dtype=np.float64), transform))
            faces.append(np.asarray(g.faces, dtype=np.int64) + off)
            cds.append(np.broadcast_to(np.asarray(attrs.get("cd", cd), dtype=np.float64), (F,)))
            css.append(np.broadcast_to(np.asarray(attrs.get("cs", cs), dtype=np.float64), (F,)))
            label = str(getattr(getattr(getattr(g, "visual", None), "material", None), "name", None) or node)
            if label not in names:
                names.append(label)
            part.append(np.full(F, names.index(label)))
            off += len(g.vertices)
        if not faces:
            raise FieldError("mesh", "the scene holds no triangles")
        return cls(np.concatenate(verts), np.concatenate(faces), np.concatenate(cds), np.concatenate(css),
                   name=name if name is not None else str(getattr(scene, "metadata", {}).get("name", "") or ""),
                   part=np.concatenate(part), part_names=tuple(names))


def as_mesh(mesh: Mesh | trimesh.Trimesh) -> Mesh:
    """``mesh`` as a :class:`Mesh`: a ``trimesh.Trimesh`` is converted (:meth:`Mesh.from_trimesh`),
    a ``trimesh.Scene`` concatenated with its bodies kept as parts (:meth:`Mesh.from_scene`)."""
    if isinstance(mesh, Mesh):
        return mesh
    if type(mesh).__module__.startswith("trimesh") and hasattr(mesh, "graph") and hasattr(mesh, "geometry"):
        return Mesh.from_scene(mesh)
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces") and type(mesh).__module__.startswith("trimesh"):
        return Mesh.from_trimesh(mesh)
    raise FieldTypeError("mesh", f"expected a cssat.scene.Mesh, a trimesh.Trimesh or a trimesh.Scene, got {type(mesh).__name__}")


def load_mesh(
    path: str | os.PathLike,
    scale: float = 1.0,
    cd: float = 0.8,
    cs: float = 0.2,
    center: bool = True,
    field: str = "path",
) -> Mesh:
    """Load any mesh file trimesh reads (OBJ, STL, GLB/GLTF, PLY, OFF, …) as one :class:`Mesh`.

    Scenes are flattened into one mesh; polygon soups are kept as they are (each facet stands for
    itself, no welding needed). ``scale`` converts the file's units to metres; ``center`` moves the
    bounding-box centre to the origin. Zero-area facets reflect nothing and are dropped; a file
    with no facet of positive area is refused. Errors name ``field``.
    """
    import trimesh

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FieldError(field, f"no such file: {path!r}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise FieldError("scale", f"must be a positive number, got {scale!r}")
    import io

    from cssat._record import read_input

    data = read_input(path, 4 << 30, field)  # hashed as read: the manifest's input is what was loaded
    ext = os.path.splitext(path)[1].lstrip(".").lower()
    from cssat.scene._obj import check_obj

    expected = check_obj(data, field, path) if ext == "obj" else 0
    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=ext, force="scene" if ext in ("glb", "gltf") else "mesh",
                              process=False, resolver=trimesh.resolvers.FilePathResolver(path))
    except Exception as err:  # trimesh raises many types for unreadable files
        raise FieldError(field, f"cannot read {path!r} as a mesh: {err}") from None
    part, part_names = None, ()
    if hasattr(loaded, "graph"):  # GLB/GLTF: several bodies, each kept as a part
        whole = Mesh.from_scene(loaded, cd, cs)
        loaded, part, part_names = whole, whole.part, whole.part_names
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if expected and len(faces) != expected:
        raise FieldError(field, f"{path!r} describes {expected} triangles but {len(faces)} could be read")
    verts = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    if len(faces) == 0:
        raise FieldError(field, f"{path!r} holds no triangles")
    verts = verts * float(scale)
    if center and len(verts):
        verts = verts - 0.5 * (verts.min(0) + verts.max(0))
    try:
        mesh = Mesh(verts, faces, getattr(loaded, "cd", cd), getattr(loaded, "cs", cs), name=os.path.basename(path),
                    part=part, part_names=part_names)
    except ValueError as err:  # e.g. a file truncated mid-way: faces pointing past the vertices
        raise FieldError(field, f"{path!r} is not a valid mesh ({err})") from None
    good = mesh.areas > 1e-12 * max(mesh.radius, 1e-300) ** 2
    if not good.any():
        raise FieldError(field, f"every facet of {path!r} is degenerate (zero area)")
    if not good.all():
        import logging

        logging.getLogger("cssat").warning(
            "%s: dropped %d zero-area (degenerate) facets of %d in %r", field, int((~good).sum()), len(faces), path
        )
        mesh = Mesh(verts, faces[good], mesh.cd[good], mesh.cs[good], name=mesh.name,
                    part=None if part is None else part[good], part_names=part_names)
    outward = float((np.sign(np.einsum("ij,ij->i", mesh.normals, mesh.centroids - mesh.centroids.mean(0))) * mesh.areas).sum()
                    / mesh.areas.sum())
    if outward < -0.5:
        import logging

        logging.getLogger("cssat").warning(
            "%s: most facets of %r face inward (area-weighted %.0f %%): their winding may be reversed, which "
            "makes the satellite nearly dark; flip it (e.g. trimesh's mesh.invert())", field, path, 50 * (1 - outward))
    return mesh


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


def merge(meshes: Sequence[Mesh], name: str = "") -> Mesh:
    """One mesh from several, keeping each facet's material."""
    verts, faces, cd, cs, off = [], [], [], [], 0
    for m in meshes:
        verts.append(m.vertices)
        faces.append(m.faces + off)
        cd.append(m.cd)
        cs.append(m.cs)
        off += len(m.vertices)
    return Mesh(np.concatenate(verts), np.concatenate(faces), np.concatenate(cd), np.concatenate(cs), name=name)


def astra_like(cd: float = 0.8, cs: float = 0.2, array_angle_deg: float = 0.0) -> Mesh:
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
    """
    ang = math.radians(float_param(array_angle_deg, "array_angle_deg", -360.0, 360.0))
    v = 2.4 * np.array([math.sin(ang), 0.0, math.cos(ang)])
    parts = [box((2.6, 2.4, 3.6), divisions=4, cd=cd, cs=cs)]
    for side in (1, -1):
        yoke = box((0.08, 1.5, 0.08), center=(0, side * (1.2 + 0.75), 0), cd=cd, cs=cs)
        parts.append(yoke)
        for k in range(4):
            y0 = 2.7 + 2.3 * k if side > 0 else -(2.7 + 2.3 * k + 2.2)
            parts.append(panel((0, 2.2, 0), v, np.array([0.0, y0, 0.0]) - v / 2, divisions=(2, 2), cd=cd, cs=cs))
        parts.append(dish(1.15, 0.35, center=(side * 1.65, 0, 0.6), axis=(side * 0.35, 0, 1.0),
                          rings=12, segments=40, cd=cd, cs=cs))
    # a two-sided telemetry plate on the anti-Earth face (4 facets): 4,028 facets in all
    parts.append(panel((0.5, 0, 0), (0, 0.5, 0), (-0.25, -0.25, -1.85), cd=cd, cs=cs))
    return merge(parts, name="astra_like")


def tess_like(cd: float = 0.8, cs: float = 0.2) -> Mesh:
    """A procedural spacecraft like NASA's TESS (the paper's target), in metres: a 1.2 × 1.2 ×
    1.0 m bus, four camera lens hoods in a 2 × 2 block with a sunshade on the +z side, two
    solar-array wings along ±y, and a high-gain antenna dish below the bus."""
    parts = [box((1.2, 1.2, 1.0), divisions=4, cd=cd, cs=cs)]
    for ix in (-1, 1):
        for iy in (-1, 1):
            parts.append(cylinder(0.2, 0.6, center=(0.26 * ix, 0.26 * iy, 0.85), axis=(0, 0, 1), segments=24, cd=cd, cs=cs))
    parts.append(box((1.3, 1.3, 0.08), center=(0, 0, 0.56), divisions=3, cd=cd, cs=cs))  # camera deck
    for side in (1, -1):
        for k in range(2):
            y0 = 0.7 + 1.05 * k if side > 0 else -(0.7 + 1.05 * k + 1.0)
            parts.append(panel((0, 1.0, 0), (0, 0, 1.3), (0, y0, -0.65), divisions=(3, 4), cd=cd, cs=cs))
    parts.append(dish(0.35, 0.1, center=(0, 0, -0.75), axis=(0, 0, -1), rings=6, segments=24, cd=cd, cs=cs))
    parts.append(cylinder(0.05, 0.25, center=(0, 0, -0.625), axis=(0, 0, 1), segments=8, cd=cd, cs=cs))
    return merge(parts, name="tess_like")


#: procedural models by name
MODELS = {"astra_like": astra_like, "tess_like": tess_like}


def get_model(name: str = "astra_like", path: str | None = None, scale: float = 1.0, cd: float = 0.8, cs: float = 0.2,
              array_angle_deg: float | None = None) -> Mesh:
    """A satellite model from config: a procedural one by ``name`` (``astra_like``, ``tess_like``)
    or, with ``name="file"``, the mesh file at ``path`` (scaled to metres by ``scale``). ``scale``
    multiplies a procedural model too (its native size is metres); the result must be a satellite:
    at most :data:`MAX_RADIUS_M` from its centre to its farthest vertex. ``array_angle_deg``: the
    ``astra_like`` model's solar-array angle (null: 0; an error for the other models)."""
    for fname, val in (("cd", cd), ("cs", cs)):
        if not (isinstance(val, (int, float)) and not isinstance(val, bool) and math.isfinite(val) and val >= 0):
            raise FieldError(fname, f"must be a number >= 0, got {val!r}")
    if not (isinstance(scale, (int, float)) and not isinstance(scale, bool) and math.isfinite(scale) and scale > 0):
        raise FieldError("scale", f"must be a number > 0 (the model's units in metres), got {scale!r}")
    if name == "file":
        if not path:
            raise FieldError("path", "required when name is 'file' (model.path=<a mesh file>)")
        mesh = load_mesh(path, scale=scale, cd=cd, cs=cs)
    elif name not in MODELS:
        raise FieldError("name", f"expected one of {sorted(MODELS) + ['file']}, got {name!r}")
    else:
        extra = {}
        if array_angle_deg is not None:
            if name != "astra_like":
                raise FieldError("array_angle_deg", f"only the astra_like model has solar arrays to turn, not {name!r}")
            extra["array_angle_deg"] = array_angle_deg
        mesh = MODELS[name](cd=cd, cs=cs, **extra)
        if scale != 1.0:
            mesh = Mesh(mesh.vertices * float(scale), mesh.faces, mesh.cd, mesh.cs, name=mesh.name)
    if not mesh.radius <= MAX_RADIUS_M:
        raise FieldError("scale", f"the model reaches {mesh.radius:.3g} m from its centre; a satellite is at most "
                                  f"{MAX_RADIUS_M:g} m (is model.scale in metres per file unit?)")
    return mesh


#: the largest satellite cssat models: the ISS spans ~110 m; 1 km leaves room, 1e30 m is an error
MAX_RADIUS_M = 1000.0
