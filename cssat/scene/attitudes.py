"""Attitude models as objects (the ``attitude`` config group): each gives the body frames
``(T, 3, 3)`` of a :class:`~cssat.scene.Scenario` in :mod:`cssat.scene.attitude`'s convention
(rows = the body axes in GCRS, ``v_body = R v_inertial``).

=============  ==========================================================================
``nadir``      the paper's three-axis stabilised attitude (default; Fig. 3b)
``inertial``   fixed in inertial space: one quaternion
``spin``       a spin about body +z: pole (λ, β) ecliptic or (α, δ) equatorial, period, phase
``tumbling``   a torque-free rigid body: inertia tensor, initial quaternion and angular velocity
``quaternions`` user-supplied quaternions at UTC instants, interpolated by slerp
=============  ==========================================================================

Articulated parts (:class:`Joint`, :class:`ArticulatedMesh`): parts of a mesh a 1-axis drive
turns relative to the body, e.g. solar arrays that track the Sun; their pose at each sample
follows from the Sun's direction in the body frame these attitudes give.

Quaternions are [x, y, z, w] (scalar last) and rotate body-frame vectors into GCRS (scipy's
convention). ``epoch_utc`` (null: the scenario's first time) is when a spin has its phase or a
tumbling body its initial state.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from cssat._checks import FieldError, choice_param, float_param
from cssat.scene.attitude import interpolated_frames, nadir_pointing_frame, quaternion_frames, spin_frame, torque_free
from cssat.scene.mesh import Mesh
from cssat.scene.orbit import utc_times

if TYPE_CHECKING:
    from cssat.scene.orbit import Scenario

__all__ = ["Attitude", "Nadir", "Inertial", "Spin", "Tumbling", "Quaternions", "Joint", "ArticulatedMesh", "TRACKING_CHOICES"]


def _seconds(scenario: Scenario, epoch_utc: Any) -> np.ndarray:
    t0 = scenario.times[0] if epoch_utc is None else utc_times(epoch_utc, "attitude.epoch_utc")[0]
    return (scenario.times - t0).astype(np.int64) * 1e-6


def _vector(v: Any, n: int, field: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise FieldError(field, f"expected {n} finite numbers, got {v!r}") from None
    if a.shape != (n,) or not np.isfinite(a).all():
        raise FieldError(field, f"expected {n} finite numbers, got {v!r}")
    return a


class Attitude:
    """``frames(scenario) -> (T, 3, 3)``; ``describe()`` for ``metrics.json``."""

    name = "attitude"

    def frames(self, scenario: Scenario) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        return {"attitude": self.name}


class Nadir(Attitude):
    """The paper's nadir-pointing three-axis stabilised attitude
    (:func:`~cssat.scene.attitude.nadir_pointing_frame`)."""

    name = "nadir"

    def frames(self, scenario: Scenario) -> np.ndarray:
        return nadir_pointing_frame(scenario.r_sat, scenario.v_sat)


class Inertial(Attitude):
    """Fixed in inertial space: ``quaternion`` [x, y, z, w] (body → GCRS)."""

    name = "inertial"

    def __init__(self, quaternion: Sequence[float] = (0.0, 0.0, 0.0, 1.0)):
        self.quaternion = _vector(quaternion, 4, "attitude.quaternion")
        self._frame = quaternion_frames(self.quaternion)

    def frames(self, scenario: Scenario) -> np.ndarray:
        return np.repeat(self._frame[None], len(scenario), axis=0)


class Spin(Attitude):
    """A spin about body +z (:func:`~cssat.scene.attitude.spin_frame`): the pole
    ``pole_lon_deg``/``pole_lat_deg`` (ecliptic λ, β, J2000 — the asteroid convention — or
    equatorial α, δ with ``frame: equatorial``), the sidereal ``period_s`` (negative: retrograde),
    the rotation phase ``phase_deg`` at ``epoch_utc``."""

    name = "spin"

    def __init__(self, pole_lon_deg: float = 0.0, pole_lat_deg: float = 90.0, period_s: float = 600.0,
                 phase_deg: float = 0.0, epoch_utc: Any = None, frame: str = "ecliptic"):
        self.pole_lon_deg = float_param(pole_lon_deg, "attitude.pole_lon_deg", -360.0, 360.0)
        self.pole_lat_deg = float_param(pole_lat_deg, "attitude.pole_lat_deg", -90.0, 90.0)
        try:
            self.period_s = float(period_s)
        except (TypeError, ValueError):
            self.period_s = float("nan")
        if isinstance(period_s, bool) or not (np.isfinite(self.period_s) and self.period_s != 0):
            raise FieldError("attitude.period_s", f"expected a non-zero finite period in seconds, got {period_s!r}")
        self.phase_deg = float_param(phase_deg, "attitude.phase_deg")
        self.epoch_utc, self.frame = epoch_utc, choice_param(frame, "attitude.frame", ("ecliptic", "equatorial"))

    def frames(self, scenario: Scenario) -> np.ndarray:
        return spin_frame(_seconds(scenario, self.epoch_utc), self.pole_lon_deg, self.pole_lat_deg, self.period_s,
                          self.phase_deg, self.frame)

    def describe(self) -> dict[str, Any]:
        return {"attitude": self.name, "attitude_pole_lon_deg": self.pole_lon_deg, "attitude_pole_lat_deg": self.pole_lat_deg,
                "attitude_period_s": self.period_s, "attitude_frame": self.frame}


class Tumbling(Attitude):
    """A torque-free rigid body (:func:`~cssat.scene.attitude.torque_free`): ``inertia_kg_m2``
    (3 principal moments or a (3, 3) tensor in the body frame), ``q0`` [x, y, z, w] and
    ``omega0_rad_s`` (body frame) at ``epoch_utc``."""

    name = "tumbling"

    def __init__(self, inertia_kg_m2: Sequence[Any] = (3000.0, 4000.0, 5000.0),
                 q0: Sequence[float] = (0.0, 0.0, 0.0, 1.0), omega0_rad_s: Sequence[float] = (0.01, 0.005, 0.02),
                 epoch_utc: Any = None):
        try:
            I = np.asarray(inertia_kg_m2, dtype=np.float64)
        except (TypeError, ValueError):
            raise FieldError("attitude.inertia_kg_m2", f"expected 3 principal moments or a (3, 3) tensor of numbers (kg m²), "
                                                       f"got {inertia_kg_m2!r}") from None
        if I.shape == (3,):
            I = np.diag(I)
        if I.shape != (3, 3):
            raise FieldError("attitude.inertia_kg_m2", f"expected 3 principal moments or a (3, 3) tensor, got shape {I.shape}")
        self.inertia = I
        self.q0 = _vector(q0, 4, "attitude.q0")
        self.omega0 = _vector(omega0_rad_s, 3, "attitude.omega0_rad_s")
        self.epoch_utc = epoch_utc

    def frames(self, scenario: Scenario) -> np.ndarray:
        return torque_free(self.inertia, self.q0, self.omega0, _seconds(scenario, self.epoch_utc))

    def describe(self) -> dict[str, Any]:
        return {"attitude": self.name, "attitude_omega0_rad_s": float(np.linalg.norm(self.omega0))}


class Quaternions(Attitude):
    """User-supplied attitudes: ``quaternions`` (K, 4) [x, y, z, w] at ``times_utc`` (K,
    increasing), slerped at the scenario's times (which must lie within them)."""

    name = "quaternions"

    def __init__(self, times_utc: Sequence[Any], quaternions: Sequence[Sequence[float]]):
        self.times_utc = utc_times(list(times_utc) if not isinstance(times_utc, np.ndarray) else times_utc,
                                   "attitude.times_utc")
        try:
            self.quaternions = np.asarray(quaternions, dtype=np.float64)
        except (TypeError, ValueError):
            raise FieldError("attitude.quaternions", f"expected (K, 4) numbers [x, y, z, w], one a time, got {quaternions!r}") from None
        if self.quaternions.ndim != 2 or self.quaternions.shape[1] != 4 or len(self.quaternions) != len(self.times_utc):
            raise FieldError("attitude.quaternions", f"expected one [x, y, z, w] for each of the {len(self.times_utc)} "
                                                     f"times_utc, got shape {self.quaternions.shape}")

    def frames(self, scenario: Scenario) -> np.ndarray:
        t0 = self.times_utc[0]
        sec = lambda t: (t - t0).astype(np.int64) * 1e-6  # noqa: E731
        return interpolated_frames(sec(scenario.times), sec(self.times_utc), self.quaternions)


# ---------------------------------------------------------------- articulated parts (Sun-tracking solar arrays)

#: how an articulated part moves: ``fixed`` at the angle it was built at, ``sun`` its drive turned to the Sun
TRACKING_CHOICES = ("fixed", "sun")


def check_limits(limits_deg: Any, field: str = "array_limits_deg") -> tuple[float, float]:
    """``(lo, hi)`` drive-angle limits (deg) with ``-180 <= lo < hi <= 180``; a FieldError naming
    ``field`` otherwise. ``(-180, 180)`` is an unlimited (continuously rotating) drive."""
    try:
        lo, hi = (float(x) for x in limits_deg)
        ok = all(not isinstance(x, bool) for x in limits_deg)
    except (TypeError, ValueError):
        ok = False
    if not ok or not (np.isfinite(lo) and np.isfinite(hi) and -180.0 <= lo < hi <= 180.0):
        raise FieldError(field, f"expected [lo, hi] degrees with -180 <= lo < hi <= 180 ([-180, 180]: no limit), "
                                f"got {limits_deg!r}")
    return lo, hi


def _rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """The (3, 3) right-handed rotation by ``angle_rad`` about the unit ``axis`` (Rodrigues)."""
    a = axis
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle_rad) * K + (1.0 - math.cos(angle_rad)) * (K @ K)


@dataclass(frozen=True)
class Joint:
    """A 1-axis drive carrying some facets of a mesh (a solar-array wing and its yoke).

    facets : (k,) int indices of the facets it carries (their vertices are theirs alone)
    axis : (3,) unit drive axis (body frame), through ``pivot`` (3,) (m)
    normal : (3,) unit normal of the face that tracks (the cells), perpendicular to ``axis``,
        in the mesh as built, where the drive angle is ``angle0_deg``
    tracking : ``"sun"`` (the drive turns the cells to the Sun) or ``"fixed"`` (stays at ``angle0_deg``)
    limits_deg : (lo, hi) the drive's mechanical limits (deg, on the drive angle; (-180, 180): none)

    The drive angle θ turns ``normal`` about ``axis`` by ``θ − angle0_deg`` (right-handed).
    Sun tracking minimises the angle between the cells' normal and the Sun: with ``b = axis ×
    normal``, the best angle is ``angle0 + atan2(b·s, normal·s)``, which puts the normal on the
    Sun's direction projected on the plane perpendicular to the axis. A real 1-axis drive cannot
    follow the Sun out of that plane: the residual angle between the cells and the Sun is the
    Sun's elevation out of the plane (for a nadir-pointing GEO bus, whose array axis is the orbit
    normal, the Sun's angle from the orbit plane: up to ~23.4° at the solstices, a cos loss of
    up to 8 %). Beyond the limits, the drive stops at the limit nearer the Sun (in angle).
    """

    facets: np.ndarray
    axis: np.ndarray
    pivot: np.ndarray
    normal: np.ndarray
    angle0_deg: float = 0.0
    tracking: str = "sun"
    limits_deg: tuple = (-180.0, 180.0)
    name: str = ""

    def __post_init__(self):
        axis = np.asarray(self.axis, dtype=np.float64)
        axis = axis / np.linalg.norm(axis)
        normal = np.asarray(self.normal, dtype=np.float64)
        normal = normal - (normal @ axis) * axis
        if not np.linalg.norm(normal) > 1e-9:
            raise FieldError("joint.normal", "the tracking face's normal must not be along the drive axis")
        object.__setattr__(self, "axis", axis)
        object.__setattr__(self, "normal", normal / np.linalg.norm(normal))
        object.__setattr__(self, "pivot", np.asarray(self.pivot, dtype=np.float64).reshape(3))
        object.__setattr__(self, "facets", np.asarray(self.facets, dtype=np.int64).reshape(-1))
        object.__setattr__(self, "tracking", choice_param(self.tracking, "array_tracking", TRACKING_CHOICES))
        object.__setattr__(self, "limits_deg", check_limits(self.limits_deg))

    def angles_deg(self, sun: np.ndarray) -> np.ndarray:
        """The drive angle (deg) at each body-frame Sun direction ``sun (T, 3)``: ``(T,)``."""
        s = np.asarray(sun, dtype=np.float64).reshape(-1, 3)
        if self.tracking == "fixed":
            return np.full(len(s), float(self.angle0_deg))
        b = np.cross(self.axis, self.normal)
        best = self.angle0_deg + np.degrees(np.arctan2(s @ b, s @ self.normal))
        best = (best + 180.0) % 360.0 - 180.0  # in [-180, 180)
        lo, hi = self.limits_deg
        if hi - lo >= 360.0:
            return best
        inside = (best >= lo) & (best <= hi)
        gap = lambda a, b: np.abs((a - b + 180.0) % 360.0 - 180.0)  # noqa: E731 - circular distance
        nearer = np.where(gap(best, lo) <= gap(best, hi), lo, hi)
        return np.where(inside, best, nearer)

    def rotation(self, angle_deg: float) -> np.ndarray:
        """The (3, 3) rotation taking the built pose to drive angle ``angle_deg``."""
        return _rotation(self.axis, math.radians(angle_deg - self.angle0_deg))

    def scaled(self, factor: float) -> "Joint":
        return dataclasses.replace(self, pivot=self.pivot * factor)


@dataclass
class ArticulatedMesh(Mesh):
    """A :class:`~cssat.scene.Mesh` (in its built pose) with ``joints``: parts a drive turns.

    The pose depends only on the Sun's direction in the body frame, which the photometry and the
    renderer are given: :func:`cssat.optics.facet_brightness`, :func:`cssat.optics.shadow_mask`,
    :func:`cssat.optics.render` and :func:`cssat.optics.earthshine_brightness` pose it at every
    time sample (:meth:`poses`) — a light curve over a night has its arrays' angle per epoch.
    The facets keep their order and number in every pose."""

    joints: tuple = ()

    def __post_init__(self):
        super().__post_init__()
        self.joints = tuple(self.joints)
        owner = np.full(len(self.vertices), -1)
        for k, j in enumerate(self.joints):
            if not isinstance(j, Joint):
                raise FieldError("joints", f"expected Joint objects, got {type(j).__name__}")
            if len(j.facets) and (j.facets.min() < 0 or j.facets.max() >= len(self.faces)):
                raise FieldError("joints", f"joint {j.name or k}: facet index out of range")
            owner[np.unique(self.faces[j.facets])] = k
        for k, j in enumerate(self.joints):
            rest = np.setdiff1d(np.arange(len(self.faces)), j.facets)
            if np.any(owner[self.faces[rest]] == k):
                raise FieldError("joints", f"joint {j.name or k}: its vertices are shared with facets it does not carry")

    @property
    def rigid(self) -> Mesh:
        """The mesh in its built pose, as a plain :class:`~cssat.scene.Mesh`."""
        return Mesh(self.vertices, self.faces, self.cd, self.cs, name=self.name, part=self.part, part_names=self.part_names)

    def angles_deg(self, sun: np.ndarray) -> np.ndarray:
        """``(T, J)`` drive angles (deg) of the joints at body-frame Sun directions ``sun (T, 3)``."""
        s = np.asarray(sun, dtype=np.float64).reshape(-1, 3)
        return np.stack([j.angles_deg(s) for j in self.joints], axis=1) if self.joints else np.zeros((len(s), 0))

    def posed(self, angles_deg: Sequence[float]) -> Mesh:
        """A plain :class:`~cssat.scene.Mesh` with every joint at its drive angle ``angles_deg (J,)``."""
        verts = self.vertices.copy()
        for j, ang in zip(self.joints, angles_deg):
            if ang == j.angle0_deg:
                continue
            idx = np.unique(self.faces[j.facets])
            verts[idx] = (verts[idx] - j.pivot) @ j.rotation(float(ang)).T + j.pivot
        return Mesh(verts, self.faces, self.cd, self.cs, name=self.name, part=self.part, part_names=self.part_names)

    def poses(self, sun: Any) -> list[tuple[np.ndarray, Mesh]]:
        """``[(time indices, posed mesh), ...]`` over body-frame Sun directions ``sun (T, 3)``:
        the samples that share a pose grouped (a fixed drive: one group)."""
        s = np.asarray(sun.detach().cpu() if hasattr(sun, "detach") else sun, dtype=np.float64).reshape(-1, 3)
        ang = self.angles_deg(s)
        uniq, inv = np.unique(ang, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        return [(np.flatnonzero(inv == k), self.posed(uniq[k])) for k in range(len(uniq))]

    def scaled(self, factor: float) -> "ArticulatedMesh":
        """The mesh and its joints' pivots scaled by ``factor``."""
        return ArticulatedMesh(self.vertices * factor, self.faces, self.cd, self.cs, name=self.name, part=self.part,
                               part_names=self.part_names, joints=tuple(j.scaled(factor) for j in self.joints))
