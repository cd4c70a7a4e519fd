"""Triangle-mesh satellites: a small container with per-facet material, and loading it from files through trimesh.

Units are metres. Every facet carries its own diffuse and specular coefficients ``Cd``, ``Cs``
(paper Eq. 8; default 0.8 / 0.2, aluminium). Facets are one-sided: a surface that reflects on both
sides (a solar panel, a reflector) is two coincident facets with opposite normals. The procedural
models and the config's choice of a model (:func:`get_model`) are in :mod:`cssat.scene.models`.
"""

from __future__ import annotations

import io
import logging
import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cssat._checks import FieldError, FieldTypeError
from cssat._record import read_input
from cssat.scene._obj import check_obj

if TYPE_CHECKING:
    from typing import Sequence

    import trimesh

__all__ = ["Mesh", "as_mesh", "load_mesh", "merge"]


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
        over = np.flatnonzero(self.cd + self.cs > 1 + 1e-12)
        if len(over):
            i = int(over[0])
            raise FieldError("mesh.cs", f"cd + cs = {self.cd[i] + self.cs[i]:g} > 1 on {len(over)} facet(s) (the first: "
                                        f"facet {i}): a surface cannot reflect more light than arrives (cd + cs <= 1)")

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
        import trimesh  # heavy: trimesh, only for to_trimesh()

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
        import trimesh  # heavy: trimesh, only for from_scene()

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
    import trimesh  # heavy: trimesh, only for load_mesh()

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FieldError(field, f"no such file: {path!r}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise FieldError("scale", f"must be a positive number, got {scale!r}")

    data = read_input(path, 4 << 30, field)  # hashed as read: the manifest's input is what was loaded
    ext = os.path.splitext(path)[1].lstrip(".").lower()

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
        logging.getLogger("cssat").warning(
            "%s: dropped %d zero-area (degenerate) facets of %d in %r", field, int((~good).sum()), len(faces), path
        )
        mesh = Mesh(verts, faces[good], mesh.cd[good], mesh.cs[good], name=mesh.name,
                    part=None if part is None else part[good], part_names=part_names)
    outward = float((np.sign(np.einsum("ij,ij->i", mesh.normals, mesh.centroids - mesh.centroids.mean(0))) * mesh.areas).sum()
                    / mesh.areas.sum())
    if outward < -0.5:
        logging.getLogger("cssat").warning(
            "%s: most facets of %r face inward (area-weighted %.0f %%): their winding may be reversed, which "
            "makes the satellite nearly dark; flip it (e.g. trimesh's mesh.invert())", field, path, 50 * (1 - outward))
    return mesh


def merge(meshes: Sequence[Mesh], name: str = "") -> Mesh:
    """One mesh from several, keeping each facet's material and, when any of them has parts,
    their parts (merged by name; a mesh without parts joins as the part ``"default"``)."""
    verts, faces, cd, cs, off = [], [], [], [], 0
    names: list = []
    parts = []
    for m in meshes:
        verts.append(m.vertices)
        faces.append(m.faces + off)
        cd.append(m.cd)
        cs.append(m.cs)
        off += len(m.vertices)
        own = list(m.part_names) if m.part is not None else ["default"]
        idx = np.zeros(len(m), np.int64) if m.part is None else m.part
        for n in own:
            if n not in names:
                names.append(n)
        parts.append(np.array([names.index(n) for n in own], dtype=np.int64)[idx] if len(m) else idx)
    any_parts = any(m.part is not None for m in meshes)
    return Mesh(np.concatenate(verts), np.concatenate(faces), np.concatenate(cd), np.concatenate(cs), name=name,
                part=np.concatenate(parts) if any_parts else None, part_names=tuple(names) if any_parts else ())
