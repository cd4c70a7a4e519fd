"""Attitude: body frames of a three-axis stabilised satellite, and random view geometries.

A body frame is a rotation ``R (T, 3, 3)`` whose *rows* are the body axes expressed in the
inertial (GCRS) frame, so ``v_body = R @ v_inertial``.
"""

from __future__ import annotations

import numpy as np

from cssat._checks import FieldError, choice_param, float_param

__all__ = ["nadir_pointing_frame", "to_body", "random_unit_vectors", "quaternion_frames", "inertial_frame",
           "spin_frame", "interpolated_frames", "torque_free", "OBLIQUITY_DEG"]

#: the obliquity of the ecliptic (IAU 2006, J2000), degrees: ecliptic (λ, β) poles to GCRS
OBLIQUITY_DEG = 23.439279444


def nadir_pointing_frame(r_sat: np.ndarray, v_sat: np.ndarray) -> np.ndarray:
    """The paper's three-axis stabilised attitude (Fig. 3b), ``(T, 3, 3)``.

    * body +z points to the geocentre (the antennas face the Earth): ``z = −r/|r|``;
    * body +y is perpendicular to the orbital plane, along the negative orbit normal
      ``y = −(r × v)/|r × v|`` (south for a prograde equatorial orbit): the solar-array axis;
    * body +x completes the right-handed frame, ``x = y × z`` (along the velocity for a circular orbit).

    ``r_sat`` (km) and ``v_sat`` (km/s) are ``(T, 3)`` geocentric inertial vectors.
    """
    r = np.asarray(r_sat, dtype=np.float64)
    v = np.asarray(v_sat, dtype=np.float64)
    z = -r / np.linalg.norm(r, axis=1, keepdims=True)
    h = np.cross(r, v)
    hn = np.linalg.norm(h, axis=1, keepdims=True)
    if np.any(hn == 0):
        raise FieldError("v_sat", "velocity parallel to position, the orbital plane is undefined")
    y = -h / hn
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=1)


def to_body(frame: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Express inertial ``vectors (T, 3)`` in the body ``frame (T, 3, 3)``: ``(T, 3)``."""
    return np.einsum("tij,tj->ti", frame, vectors)


def random_unit_vectors(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` directions uniform on the unit sphere, ``(n, 3)``, from the given generator."""
    v = rng.standard_normal((n, 3))
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    while np.any(norm < 1e-12):  # measure-zero, but keep the result exact
        bad = (norm < 1e-12)[:, 0]
        v[bad] = rng.standard_normal((int(bad.sum()), 3))
        norm = np.linalg.norm(v, axis=1, keepdims=True)
    return v / norm


def _unit_quaternions(q: np.ndarray, field: str) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 4 or not np.isfinite(q).all():
        raise FieldError(field, f"expected finite quaternions (..., 4) [x, y, z, w] (scalar last), got shape {q.shape}")
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n < 1e-12):
        raise FieldError(field, "a quaternion of norm 0 is no rotation")
    return q / n


def quaternion_frames(q: np.ndarray, field: str = "attitude.quaternion") -> np.ndarray:
    """Body frames ``(..., 3, 3)`` of attitude quaternions ``q (..., 4)`` [x, y, z, w] (scalar
    last, normalised here), each the rotation that takes body-frame vectors to the inertial frame
    (scipy's ``Rotation.from_quat`` convention): the frame's rows are ``R(q)ᵀ``."""
    from scipy.spatial.transform import Rotation  # heavy: scipy.spatial, only for quaternion_frames()

    q = _unit_quaternions(q, field)
    R = Rotation.from_quat(q.reshape(-1, 4)).as_matrix()
    return np.swapaxes(R, -1, -2).reshape(*q.shape[:-1], 3, 3)


def inertial_frame(q: np.ndarray, n: int) -> np.ndarray:
    """An inertially fixed attitude: the frame of ``q (4,)`` repeated ``n`` times, ``(n, 3, 3)``."""
    return np.repeat(quaternion_frames(q)[None], int(n), axis=0)


def rot_z(a: np.ndarray) -> np.ndarray:
    """Passive rotations about z by ``a (T,)`` rad: ``(T, 3, 3)``."""
    c, s_ = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, s_, z], -1), np.stack([-s_, c, z], -1), np.stack([z, z, o], -1)], -2)


def rot_y(a: float) -> np.ndarray:
    c, s_ = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, -s_], [0.0, 1.0, 0.0], [s_, 0.0, c]])


def spin_frame(times_s: np.ndarray, pole_lon_deg: float, pole_lat_deg: float, period_s: float,
               phase_deg: float = 0.0, frame: str = "ecliptic") -> np.ndarray:
    """A body spinning about its +z axis (the asteroid convention, Kaasalainen & Torppa 2001):
    ``(T, 3, 3)`` frames at ``times_s`` seconds after the epoch where the rotation phase is
    ``phase_deg``, ``v_body = R_z(φ(t)) R_y(90° − β) R_z(λ) E v``, ``φ(t) = φ₀ + 2π t / P``.

    The pole ``(λ, β) = (pole_lon_deg, pole_lat_deg)`` is ecliptic longitude and latitude
    (``frame="ecliptic"``, J2000; ``E`` rotates GCRS into the ecliptic by the obliquity) or right
    ascension and declination (``"equatorial"``, ``E = I``). ``period_s > 0`` (sidereal);
    a negative period spins retrograde about the pole."""
    frame = choice_param(frame, "attitude.frame", ("ecliptic", "equatorial"))
    lam = np.radians(float_param(pole_lon_deg, "attitude.pole_lon_deg", -360.0, 360.0))
    beta = np.radians(float_param(pole_lat_deg, "attitude.pole_lat_deg", -90.0, 90.0))
    period = float(period_s)
    if not (np.isfinite(period) and period != 0):
        raise FieldError("attitude.period_s", f"expected a non-zero finite period (s), got {period_s!r}")
    t = np.asarray(times_s, dtype=np.float64)
    phi = np.radians(float(phase_deg)) + 2 * np.pi * t / period
    fixed = rot_y(np.pi / 2 - beta) @ rot_z(np.array([lam]))[0]
    if frame == "ecliptic":
        fixed = fixed @ rot_x3(np.radians(OBLIQUITY_DEG))[0]
    return rot_z(phi) @ fixed


def interpolated_frames(times_s: np.ndarray, knot_times_s: np.ndarray, quaternions: np.ndarray) -> np.ndarray:
    """User-supplied attitudes: quaternions ``(K, 4)`` [x, y, z, w] at ``knot_times_s (K,)``
    (increasing), interpolated by slerp (scipy's ``Slerp``) at ``times_s (T,)`` inside
    ``[knot_times_s[0], knot_times_s[-1]]``: ``(T, 3, 3)``."""
    from scipy.spatial.transform import Rotation, Slerp  # heavy: scipy.spatial, only for interpolated_frames()

    kt = np.asarray(knot_times_s, dtype=np.float64)
    q = _unit_quaternions(quaternions, "attitude.quaternions")
    if kt.ndim != 1 or len(kt) != len(q) or len(kt) < 2:
        raise FieldError("attitude.times_s", f"expected one time per quaternion and at least two, got {kt.shape} and {q.shape}")
    if np.any(np.diff(kt) <= 0):
        raise FieldError("attitude.times_s", "the quaternions' times must increase")
    t = np.asarray(times_s, dtype=np.float64)
    if t.min() < kt[0] or t.max() > kt[-1]:
        raise FieldError("attitude.times_s", f"the scenario's times ({t.min():g}–{t.max():g} s) leave the quaternions' "
                                             f"span ({kt[0]:g}–{kt[-1]:g} s): slerp does not extrapolate")
    R = Slerp(kt, Rotation.from_quat(q))(t).as_matrix()
    return np.swapaxes(R, -1, -2)


def torque_free(inertia_kg_m2: np.ndarray, q0: np.ndarray, omega0_rad_s: np.ndarray, times_s: np.ndarray,
                *, return_omega: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """A tumbling rigid body (no torque): body frames ``(T, 3, 3)`` at ``times_s (T,)`` seconds
    after the initial state — attitude ``q0 (4,)`` [x, y, z, w] (scalar last, body → inertial)
    and angular velocity ``omega0_rad_s (3,)`` in the body frame — for the inertia tensor
    ``inertia_kg_m2 (3, 3)`` (symmetric positive definite, body frame; any scale).

    Exact, not stepped (Landau & Lifshitz, Mechanics §37): in the principal frame the angular
    velocity is the Jacobi elliptic solution of Euler's equations (``scipy.special.ellipj``), so
    the energy and ``|L|`` are those of the initial state at every time; the attitude is the
    Euler angles of the body about the fixed angular momentum — ``θ`` and ``ψ`` from the body's
    ``L`` at once, the precession ``φ`` as the integral of ``L (I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²)``
    over one period of the motion by Gauss–Legendre quadrature, then by periodicity — so ``L`` is
    fixed in the inertial frame to round-off over days. ``return_omega``: also ``ω (T, 3)`` in
    the body frame (rad/s)."""
    from scipy.spatial.transform import Rotation  # heavy: scipy.spatial, only for torque_free()

    I_b = np.asarray(inertia_kg_m2, dtype=np.float64)
    if I_b.shape != (3, 3) or not np.isfinite(I_b).all() or not np.allclose(I_b, I_b.T, rtol=1e-12, atol=0):
        raise FieldError("attitude.inertia_kg_m2", "expected a finite symmetric (3, 3) inertia tensor")
    moments, V = np.linalg.eigh(I_b)
    if not moments[0] > 0:
        raise FieldError("attitude.inertia_kg_m2", f"principal moments must be > 0, got {moments}")
    if moments[2] > moments[0] + moments[1] + 1e-9 * moments[2]:
        raise FieldError("attitude.inertia_kg_m2", f"no rigid body has these principal moments {moments} "
                                                   "(each must be at most the sum of the other two)")
    if np.linalg.det(V) < 0:
        V[:, 0] = -V[:, 0]
    w0 = np.asarray(omega0_rad_s, dtype=np.float64).reshape(3)
    if not np.isfinite(w0).all():
        raise FieldError("attitude.omega0_rad_s", "expected a finite angular velocity (3,) in rad/s")
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    F0 = quaternion_frames(q0, "attitude.q0")
    wp = V.T @ w0  # principal components
    Ip = moments / moments.max()  # the motion depends on the inertia's ratios only
    Lp = Ip * wp
    L = float(np.linalg.norm(Lp))
    if L < 1e-300:  # at rest
        out = np.repeat(F0[None], len(t), axis=0)
        return (out, np.zeros((len(t), 3))) if return_omega else out
    mo = euler_solution(Ip, wp)
    if mo is None:  # a steady spin about a principal axis: a rotation at a constant rate
        R = Rotation.from_matrix(F0.T) * Rotation.from_rotvec(np.outer(t, w0))
        out = np.swapaxes(R.as_matrix(), -1, -2)
        return (out, np.repeat(w0[None], len(t), axis=0)) if return_omega else out
    omega = omega_of(mo, t, mo["sign"])
    theta, psi = nutation(Ip, omega, L)
    th0, ps0 = nutation(Ip, wp[None], L)
    # the inertial frame with z along L, and the precession angle's start from the initial attitude
    L_in = F0.T @ (V @ (moments * wp))
    ez = L_in / np.linalg.norm(L_in)
    ex = np.cross([0.0, 0.0, 1.0] if abs(ez[2]) < 0.9 else [1.0, 0.0, 0.0], ez)
    ex /= np.linalg.norm(ex)
    M = np.stack([ex, np.cross(ez, ex), ez])
    P0 = V.T @ F0
    X = rot_x3(th0)[0].T @ rot_z(ps0)[0].T @ P0 @ M.T  # = R_z(φ₀)
    phi = np.arctan2(X[0, 1], X[0, 0]) + _precession(mo, Ip, L, t)
    P = rot_z(psi) @ rot_x3(theta) @ rot_z(phi) @ M
    out = V @ P
    return (out, omega @ V.T) if return_omega else out


def rot_x3(a: np.ndarray) -> np.ndarray:
    """Passive rotations about x by ``a (T,)``: ``(T, 3, 3)``."""
    a = np.atleast_1d(a)
    c, s_ = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, s_], -1), np.stack([z, -s_, c], -1)], -2)


def nutation(Ip: np.ndarray, omega: np.ndarray, L: float) -> tuple[np.ndarray, np.ndarray]:
    """Euler angles θ, ψ of the body about ``L`` from the principal ``ω (T, 3)``: the body's
    ``L = L (sin θ sin ψ, sin θ cos ψ, cos θ)``."""
    Lb = Ip * omega
    return np.arccos(np.clip(Lb[:, 2] / L, -1, 1)), np.arctan2(Lb[:, 0], Lb[:, 1])


def _motion(Ip: np.ndarray, wp: np.ndarray) -> dict | None:
    """The elliptic solution's constants: amplitudes, rate, modulus, phase, the axis order."""
    from scipy.special import ellipkinc  # heavy: scipy.special, only for _motion()

    E2 = float(np.sum(Ip * wp ** 2))
    L2 = float(np.sum((Ip * wp) ** 2))
    A, B, C = Ip
    order = [0, 1, 2] if L2 >= E2 * B else [2, 1, 0]  # around the major axis, or the minor one
    a_, b_, c_ = Ip[order]
    amp = np.array([(E2 * c_ - L2) / (a_ * (c_ - a_)) if c_ != a_ else 0.0,
                    (E2 * c_ - L2) / (b_ * (c_ - b_)) if c_ != b_ else 0.0,
                    (L2 - E2 * a_) / (c_ * (c_ - a_)) if c_ != a_ else 0.0])
    amp = np.sqrt(np.clip(amp, 0, None))
    if amp[0] <= 1e-12 * np.abs(wp).max() and amp[1] <= 1e-12 * np.abs(wp).max():
        return None  # steady spin about the principal axis order[2]
    lam = np.sqrt(abs((c_ - b_) * (L2 - E2 * a_) / (a_ * b_ * c_)))
    den = (c_ - b_) * (L2 - E2 * a_)
    m = 0.0 if den == 0 else float(np.clip((b_ - a_) * (E2 * c_ - L2) / den, 0.0, 1.0))
    w = wp[order]
    am0 = np.arctan2(w[1] / amp[1] if amp[1] > 0 else 0.0, w[0] / amp[0] if amp[0] > 0 else 1.0)
    tau0 = float(ellipkinc(am0, m))
    s3 = 1.0 if w[2] >= 0 else -1.0
    return {"order": order, "amp": amp, "lam": lam, "m": m, "tau0": tau0, "s3": s3, "I": Ip[order]}


def omega_of(mo: dict, t: np.ndarray, sign: float) -> np.ndarray:
    """The body angular velocity ``(T, 3)`` in rad/s at times ``t (T,)`` s of the elliptic
    solution ``mo`` (:func:`_motion`; ``sign``: the direction of its phase)."""
    from scipy.special import ellipj  # heavy: scipy.special, only for omega_of()

    sn, cn, dn, _ = ellipj(sign * mo["lam"] * t + mo["tau0"], mo["m"])
    amp, order = mo["amp"], mo["order"]
    out = np.empty((len(cn), 3), dtype=np.result_type(cn, amp))  # columns written in place: no stack
    out[:, order[0]] = amp[0] * cn
    out[:, order[1]] = amp[1] * sn
    out[:, order[2]] = mo["s3"] * amp[2] * dn
    return out


def euler_solution(Ip: np.ndarray, wp: np.ndarray) -> dict | None:
    """The elliptic solution of Euler's equations from the principal ``ω₀`` (:func:`_motion`),
    with ``sign``: the direction of the elliptic phase whose derivative at 0 satisfies Euler's
    equations. ``None`` for a steady spin."""
    mo = _motion(Ip, wp)
    if mo is None:
        return None
    A, B, C = Ip
    p, q, r = wp
    rhs = np.array([(B - C) * q * r / A, (C - A) * r * p / B, (A - B) * p * q / C])
    h = 1e-6 / max(mo["lam"], 1e-300)
    errs = []
    for sign in (1.0, -1.0):
        w = omega_of(mo, np.array([h, -h]), sign)  # elementwise: the same numbers as one call each
        d = (w[0] - w[1]) / (2 * h)
        errs.append(np.abs(d - rhs).sum())
    mo["sign"] = 1.0 if errs[0] <= errs[1] else -1.0
    return mo


def _precession(mo: dict, Ip: np.ndarray, L: float, t: np.ndarray, nodes: int = 64,
                pieces: int = 256) -> np.ndarray:
    """``∫₀ᵗ L (I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²) dt'`` for every ``t``: Gauss–Legendre over
    ``pieces`` equal parts of the motion's period (its integrand's, ``2K(m)/λ``), then whole
    periods and the rest."""
    from scipy.special import ellipk  # heavy: scipy.special, only for _precession()

    A, B, _ = Ip
    period = 2 * float(ellipk(mo["m"])) / mo["lam"] if mo["m"] < 1 else np.inf

    def rate(tt: np.ndarray) -> np.ndarray:
        w = omega_of(mo, tt, mo["sign"])
        num = A * w[:, 0] ** 2 + B * w[:, 1] ** 2
        den = A ** 2 * w[:, 0] ** 2 + B ** 2 * w[:, 1] ** 2
        return L * num / np.maximum(den, 1e-300)

    x, wts = np.polynomial.legendre.leggauss(nodes)

    def integral(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # over [a, b], elementwise, one GL rule
        mid, half = (a + b) / 2, (b - a) / 2
        vals = rate((mid[:, None] + half[:, None] * x[None]).reshape(-1)).reshape(len(a), nodes)
        return half * (vals @ wts)

    if not np.isfinite(period):  # the separatrix: no period; integrate from 0 in pieces
        edges = np.linspace(0.0, max(float(np.abs(t).max()), 1e-9), pieces * 64 + 1)
        cum = np.concatenate([[0.0], np.cumsum(integral(edges[:-1], edges[1:]))])
        k = np.clip(np.searchsorted(edges, np.abs(t), side="right") - 1, 0, len(edges) - 2)
        return np.sign(t) * (cum[k] + integral(edges[k], np.abs(t)))
    edges = np.linspace(0.0, period, pieces + 1)
    cum = np.concatenate([[0.0], np.cumsum(integral(edges[:-1], edges[1:]))])
    n, rest = np.divmod(t, period)
    k = np.clip(np.searchsorted(edges, rest, side="right") - 1, 0, pieces - 1)
    return n * cum[-1] + cum[k] + integral(edges[k], rest)
