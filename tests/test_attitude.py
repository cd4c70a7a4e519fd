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


def test_the_nadir_object_is_the_papers_attitude_bit_for_bit():
    from cssat.optics import simulate_light_curve
    from cssat.scene import astra_like, make_scenario
    from cssat.scene.attitudes import Nadir

    sc = make_scenario(n_steps=50, step_s=600.0)
    a = simulate_light_curve(astra_like(), sc)
    b = simulate_light_curve(astra_like(), sc, attitude=Nadir())
    assert np.array_equal(a.facets.numpy(), b.facets.numpy()) and np.array_equal(a.sun, b.sun)


def test_an_inertially_fixed_body_sees_the_sun_and_observer_as_they_are_in_gcrs():
    from cssat.optics import simulate_light_curve
    from cssat.scene import astra_like, make_scenario
    from cssat.scene.attitudes import Inertial

    sc = make_scenario(n_steps=5, step_s=3600.0)
    q = Rotation.from_euler("z", 90, degrees=True).as_quat()  # body x = GCRS y
    lc = simulate_light_curve(astra_like(), sc, attitude=Inertial(q))
    assert np.allclose(lc.sun[:, 0], sc.sun_dir[:, 1], atol=1e-12) and np.allclose(lc.observer[:, 2], sc.obs_dir[:, 2], atol=1e-12)


def test_a_spinning_box_flashes_at_half_its_period():
    """A flat plate spinning about an axis in its plane: its Lambert brightness ∝ |cos| of the
    rotation angle for a fixed geometry, so the light curve repeats every half period."""
    from cssat.optics import simulate_light_curve
    from cssat.scene import box, make_scenario
    from cssat.scene.attitudes import Spin

    sc = make_scenario(start_utc="2020-04-01T21:00:00", n_steps=241, step_s=1.0)
    plate = box((4.0, 0.01, 4.0), cd=0.8, cs=0.0)  # thin in y: its faces' normals ±y spin about z
    flux = simulate_light_curve(plate, sc, shadows=False, attitude=Spin(20.0, 60.0, period_s=120.0)).flux.numpy()
    half = flux[60:] - flux[:-60]  # 60 s = half a period: the geometry drifts 0.25° meanwhile
    assert np.abs(half).max() < 0.05 * flux.max()
    assert flux.max() > 5 * np.percentile(flux, 20)  # it does flash


@pytest.mark.parametrize("option", ["nadir", "inertial", "spin", "tumbling", "quaternions"])
def test_every_attitude_option_runs_the_light_curve_experiment(tmp_path, option):
    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=lightcurve", f"attitude={option}", "scenario.n_steps=6",
                                                       "scenario.step_s=600", "render.size=8", "threads=1"])
    met = run_experiment(cfg, tmp_path)
    assert met["status"] == "ok" and met["attitude"] == option


def test_three_nights_of_irregular_stamps_with_a_tumbling_model(tmp_path):
    """The done-when case: a tumbling Astra-like model over three nights of irregular time
    stamps, from the API and from the command line (exit 0, the same curve)."""
    import subprocess
    import sys

    from cssat.data import ObservedLightCurve, write_light_curve
    from cssat.optics import simulate_light_curve
    from cssat.scene import astra_like, make_scenario
    from cssat.scene.attitudes import Tumbling

    rng = np.random.default_rng(5)
    t0 = np.datetime64("2020-04-01T19:00:00", "us")
    stamps = np.unique(np.concatenate([t0 + np.timedelta64(d, "D") + rng.uniform(0, 6 * 3600e6, 40).astype("timedelta64[us]")
                                       for d in range(3)]))
    tumble = Tumbling([3000.0, 4000.0, 5000.0], [0, 0, 0, 1], [0.01, 0.005, 0.02], epoch_utc="2020-04-01T19:00:00")
    # the light-curve experiment's model (conf/model/astra_like.yaml): its arrays track the Sun
    lc = simulate_light_curve(astra_like(array_tracking="sun"), make_scenario(times=stamps), attitude=tumble)
    assert lc.flux.shape == (len(stamps),) and float(lc.flux.std()) > 0.1 * float(lc.flux.mean())
    write_light_curve(tmp_path / "obs.csv", ObservedLightCurve(stamps, np.full(len(stamps), 10.0), None, "magnitude"))
    out = subprocess.run([sys.executable, "-m", "cssat.app", "experiment=lightcurve", f"observations={tmp_path / 'obs.csv'}",
                          "attitude=tumbling", "attitude.epoch_utc=2020-04-01T19:00:00", "render.size=8", "threads=1",
                          f"hydra.run.dir={tmp_path / 'run'}"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, (out.stdout + out.stderr)[-2000:]
    flux = np.load(tmp_path / "run" / "arrays.npz")["flux"]
    assert np.allclose(flux, lc.flux.numpy(), rtol=1e-12, atol=0)
