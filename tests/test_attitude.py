"""Issue 23: attitude models against independent references (scipy's integrator and rotations,
the axisymmetric top's closed form, the asteroid pole convention written out)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from cssat._checks import FieldError

I_TRIAXIAL = np.array([[3.0, 0.2, 0.0], [0.2, 4.0, -0.1], [0.0, -0.1, 5.0]])  # not principal: rotated axes


def _integrate(I, R0, w0, t):
    """Euler's equations and dR/dt = R [ω]× by DOP853 at rtol 1e-12 (the independent reference)."""
    def rhs(_, y):
        R, om = y[:9].reshape(3, 3), y[9:]
        wx = np.array([[0, -om[2], om[1]], [om[2], 0, -om[0]], [-om[1], om[0], 0]])
        return np.concatenate([(R @ wx).ravel(), np.linalg.solve(I, np.cross(I @ om, om))])

    sol = solve_ivp(rhs, (0, t[-1]), np.concatenate([R0.ravel(), w0]), method="DOP853", rtol=1e-12, atol=1e-14, t_eval=t)
    return sol.y[:9].T.reshape(-1, 3, 3), sol.y[9:].T


@pytest.mark.parametrize("w0", [[0.05, 0.02, -0.03], [0.01, 0.06, 0.002], [-0.05, 0.001, 0.004]],
                         ids=["major-axis", "intermediate-start", "minor-axis"])
def test_torque_free_matches_a_numerical_integration(w0):
    from cssat.scene.attitude import torque_free

    R0 = Rotation.from_euler("xyz", [0.3, -0.2, 1.0])
    t = np.linspace(0.0, 3600.0, 13)
    F, w = torque_free(I_TRIAXIAL, R0.as_quat(), np.array(w0), t, return_omega=True)
    Rn, wn = _integrate(I_TRIAXIAL, R0.as_matrix(), np.array(w0), t)
    assert np.abs(F - np.swapaxes(Rn, 1, 2)).max() < 1e-9  # frames' rows = Rᵀ
    assert np.abs(w - wn).max() < 1e-11


def test_torque_free_conserves_energy_and_momentum_over_days():
    from cssat.scene.attitude import torque_free

    q0 = Rotation.from_euler("zyx", [10, 20, 30], degrees=True).as_quat()
    w0 = np.array([0.04, -0.03, 0.05])
    t = np.sort(np.random.default_rng(0).uniform(0, 3 * 86400.0, 2000))  # three days, irregular
    F, w = torque_free(I_TRIAXIAL, q0, w0, t, return_omega=True)
    E = 0.5 * np.einsum("ti,ij,tj->t", w, I_TRIAXIAL, w)
    L = np.einsum("tji,tj->ti", F, w @ I_TRIAXIAL)  # inertial: Fᵀ (I ω)
    L0 = Rotation.from_quat(q0).apply(I_TRIAXIAL @ w0)
    assert np.abs(E / (0.5 * w0 @ I_TRIAXIAL @ w0) - 1).max() < 1e-9
    assert np.abs(L - L0).max() / np.linalg.norm(L0) < 1e-9
    assert np.allclose(F @ np.swapaxes(F, 1, 2), np.eye(3), atol=1e-12)


def test_an_axisymmetric_top_precesses_regularly():
    """I = diag(A, A, C): R(t) = Rot(L̂, |L| t / A) R₀ Rot(ẑ, −Ω t), Ω = (C − A) ω₃ / A."""
    from cssat.scene.attitude import torque_free

    A, C = 2.0, 3.5
    I = np.diag([A, A, C])
    R0 = Rotation.from_rotvec([0.4, -0.1, 0.7])
    w0 = np.array([0.03, -0.01, 0.08])
    t = np.linspace(0, 20000.0, 41)
    F = torque_free(I, R0.as_quat(), w0, t)
    L_in = R0.apply(I @ w0)
    Lmag = np.linalg.norm(L_in)
    Omega = (C - A) * w0[2] / A
    expect = (Rotation.from_rotvec(np.outer(t * Lmag / A, L_in / Lmag)) * R0
              * Rotation.from_rotvec(np.outer(-Omega * t, [0, 0, 1]))).as_matrix()
    assert np.abs(F - np.swapaxes(expect, 1, 2)).max() < 1e-9


def test_a_steady_spin_and_rest():
    from cssat.scene.attitude import torque_free

    I = np.diag([1.0, 2.0, 3.0])
    q0 = Rotation.from_euler("x", 30, degrees=True).as_quat()
    t = np.array([0.0, 10.0, 25.0])
    F = torque_free(I, q0, [0.0, 0.0, 0.1], t)  # about the major axis: a rotation at a constant rate
    expect = (Rotation.from_quat(q0) * Rotation.from_rotvec(np.outer(t, [0, 0, 0.1]))).as_matrix()
    assert np.abs(F - np.swapaxes(expect, 1, 2)).max() < 1e-12
    assert np.allclose(torque_free(I, q0, [0, 0, 0], t), Rotation.from_quat(q0).as_matrix().T)


@pytest.mark.parametrize("inertia, q0, field", [
    (np.array([[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]), [0, 0, 0, 1], "attitude.inertia_kg_m2"),
    (np.diag([1.0, -1.0, 1.0]), [0, 0, 0, 1], "attitude.inertia_kg_m2"),
    (np.diag([1.0, 1.0, 3.0]), [0, 0, 0, 1], "attitude.inertia_kg_m2"),  # 3 > 1 + 1: no such body
    (np.diag([1.0, 2.0, 2.5]), [0, 0, 0, 0], "attitude.q0"),
])
def test_bad_tumbling_states_name_their_field(inertia, q0, field):
    from cssat.scene.attitude import torque_free

    with pytest.raises(FieldError) as err:
        torque_free(inertia, q0, [0.1, 0, 0], [0.0, 1.0])
    assert err.value.field == field


def test_quaternion_frames_are_the_textbook_matrix():
    from cssat.scene.attitude import quaternion_frames

    rng = np.random.default_rng(3)
    for q in rng.normal(size=(5, 4)):
        x, y, z, w = q / np.linalg.norm(q)
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])  # body → inertial
        assert np.allclose(quaternion_frames(q), R.T, atol=1e-14)


def test_a_spinning_body_follows_the_asteroid_convention():
    from cssat.scene.attitude import OBLIQUITY_DEG, spin_frame

    eps = np.radians(OBLIQUITY_DEG)
    # the pole (λ, β) in GCRS, written out: ecliptic (cos β cos λ, cos β sin λ, sin β) tilted by ε about x
    lam, beta = np.radians(250.0), np.radians(-35.0)
    p_ecl = np.array([np.cos(beta) * np.cos(lam), np.cos(beta) * np.sin(lam), np.sin(beta)])
    p_eq = np.array([p_ecl[0], np.cos(eps) * p_ecl[1] - np.sin(eps) * p_ecl[2], np.sin(eps) * p_ecl[1] + np.cos(eps) * p_ecl[2]])
    P = 7200.0
    t = np.array([0.0, P / 4, P, 10 * P + 123.0, 123.0])
    F = spin_frame(t, 250.0, -35.0, P, phase_deg=40.0)
    assert np.allclose(F @ p_eq, [0, 0, 1], atol=1e-14)  # the spin axis is body +z
    assert np.allclose(F[0], F[2], atol=1e-12) and np.allclose(F[3], F[4], atol=1e-9)  # periodic
    assert np.dot(F[0][0], F[1][0]) == pytest.approx(0.0, abs=1e-12)  # a quarter turn: the x axes ⟂
    # prograde: body x turns towards body y about the pole (right hand)
    assert np.dot(np.cross(F[0][0], F[1][0]), p_eq) > 0.99
    eq = spin_frame(t, 80.0, 60.0, P, frame="equatorial")
    ra, dec = np.radians(80.0), np.radians(60.0)
    assert np.allclose(eq @ [np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], [0, 0, 1], atol=1e-14)


def test_user_quaternions_are_slerped():
    from cssat.scene.attitude import interpolated_frames, quaternion_frames

    q = Rotation.from_euler("z", [[0], [90], [180]], degrees=True).as_quat()
    knots = np.array([0.0, 100.0, 200.0])
    F = interpolated_frames(np.array([0.0, 50.0, 100.0, 150.0]), knots, q)
    assert np.allclose(F[0], quaternion_frames(q[0]), atol=1e-14) and np.allclose(F[2], quaternion_frames(q[1]), atol=1e-14)
    assert np.allclose(F[1], Rotation.from_euler("z", 45, degrees=True).as_matrix().T, atol=1e-14)
    assert np.allclose(F[3], Rotation.from_euler("z", 135, degrees=True).as_matrix().T, atol=1e-14)
    with pytest.raises(FieldError, match="extrapolate"):
        interpolated_frames(np.array([250.0]), knots, q)
    with pytest.raises(FieldError, match="increase"):
        interpolated_frames(np.array([50.0]), np.array([0.0, 100.0, 50.0]), q)
