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

Quaternions are [x, y, z, w] (scalar last) and rotate body-frame vectors into GCRS (scipy's
convention). ``epoch_utc`` (null: the scenario's first time) is when a spin has its phase or a
tumbling body its initial state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from cssat._checks import FieldError, choice_param, float_param
from cssat.scene.attitude import interpolated_frames, nadir_pointing_frame, quaternion_frames, spin_frame, torque_free
from cssat.scene.orbit import utc_times

if TYPE_CHECKING:
    from cssat.scene.orbit import Scenario

__all__ = ["Attitude", "Nadir", "Inertial", "Spin", "Tumbling", "Quaternions"]


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
