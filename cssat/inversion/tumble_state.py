"""The spin state of a tumbling object — a torque-free rigid body in non-principal-axis rotation
(Kaasalainen 2001): its parametrisation, its motion, its two frequencies, the
invariants of a torque-free initial state, and the EGI fit of its light curve (:class:`_TFit`).
Its search from a light curve is :func:`cssat.inversion.tumble.estimate_tumbling`.

The state (:class:`TumblingState`): the principal moments ``(I₁, I₂, I₃)/I₃ = (i₁, i₂, 1)``
(``i₁ ≤ i₂ ≤ 1 ≤ i₁ + i₂``), the direction of the angular momentum ``L`` (ecliptic λ, β or
equatorial α, δ), the two frequencies of the motion — ``f_ω`` of the angular velocity in the
body (``P_ω = 4K(m)/λ``, the period of Euler's equations' Jacobi solution) and ``f_φ`` the mean
precession rate of the body about ``L`` — and two phases: ``t₀`` (where on its polhode the body
is at the epoch) and ``φ₀`` (its turn about ``L``). The motion is parametrised by the polhode's
crossing of the principal x–z plane, ``L_body = |L| (sin α, 0, cos α)`` (``α < α_sep``: short-axis
mode, about the axis of the largest moment; above: long-axis mode), reached at ``τ = 0``; the
body frame at time ``t`` is

    ``R(t) = B(t − t_ref + t₀) R_z(φ₀) M(λ, β)``,

``M`` the rotation taking ``L`` to +z (:func:`~cssat.scene.attitude.spin_frame` at zero phase),
``B(τ)`` the exact torque-free motion (:func:`~cssat.scene.attitude.torque_free`) from
``R_y(−α)`` with ``ω = |L| L̂_body / I``. The moments' common scale is not observable (only their
ratios enter), nor are the body's 180° turns about its principal axes (they keep the inertia
and the EGI absorbs them): ``α ∈ (0°, 90°)`` covers every motion. ``(f_ω, f_φ)`` and ``(i₁, i₂)``
fix ``α`` (the ratio ``f_φ/f_ω`` is a function of ``α`` for given moments) and ``|L|``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.scene.attitude import OBLIQUITY_DEG, euler_solution, nutation, omega_of, rot_x3, rot_y, rot_z, quaternion_frames, to_body

__all__ = ["TumblingState", "tumbling_rates", "torque_free_invariants"]


def _solution(i1: float, i2: float, alpha: float):
    Ip = np.array([i1, i2, 1.0])
    wp = np.array([math.sin(alpha), 0.0, math.cos(alpha)]) / Ip
    return Ip, wp, euler_solution(Ip, wp)


def tumbling_rates(i1: float, i2: float, alpha_rad: float, *, n: int = 256) -> tuple[float, float]:
    """``(f_ω, f_φ)`` in Hz of the torque-free motion with moments ``(i₁, i₂, 1)`` whose body
    angular momentum crosses ``(sin α, 0, cos α)``, per rad/s of ``|L|/I₃``: ``f_ω = λ/(4K(m))``
    (Euler's Jacobi solution) and the mean of the precession rate
    ``φ̇ = |L| (I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²)`` (Landau & Lifshitz §37) over its period
    ``2K/λ`` by the trapezoid rule (spectrally accurate for a periodic integrand) over ``2π``.
    ``(nan, nan)`` on the separatrix or at a steady spin."""
    from scipy.special import ellipk  # heavy: scipy.special, only for tumbling_rates()

    Ip, _, mo = _solution(i1, i2, alpha_rad)
    if mo is None or not mo["m"] < 1.0 - 1e-12 or mo["lam"] <= 0:
        return math.nan, math.nan
    K = float(ellipk(mo["m"]))
    half = 2 * K / mo["lam"]
    w = omega_of(mo, np.arange(n) * (half / n), mo["sign"])
    num = Ip[0] * w[:, 0] ** 2 + Ip[1] * w[:, 1] ** 2
    den = Ip[0] ** 2 * w[:, 0] ** 2 + Ip[1] ** 2 * w[:, 1] ** 2
    return 1.0 / (2 * half), float(np.mean(num / np.maximum(den, 1e-300))) / (2 * math.pi)


def torque_free_invariants(inertia_kg_m2: Any, q0: Any, omega0_rad_s: Any, frame: str = "ecliptic") -> dict[str, Any]:
    """What a light curve can give of a torque-free motion (:func:`~cssat.scene.attitude.torque_free`'s
    initial state: inertia tensor ``(3, 3)`` or moments ``(3,)``, ``q0`` [x, y, z, w] body →
    inertial, ``omega0_rad_s`` in the body frame): ``i1``, ``i2`` (moments over the largest),
    ``f_omega_hz``, ``f_phi_hz``, the direction of ``L`` (``L_lon_deg``, ``L_lat_deg`` in
    ``frame``), ``alpha`` (rad) and ``short_axis`` — the numbers
    :func:`~cssat.inversion.tumble.estimate_tumbling` estimates.
    ``None`` for a steady spin."""
    I = np.asarray(inertia_kg_m2, dtype=np.float64)
    I = np.diag(I) if I.shape == (3,) else I
    moments, V = np.linalg.eigh(I)
    if np.linalg.det(V) < 0:
        V[:, 0] = -V[:, 0]
    Ip = moments / moments.max()
    wp = V.T @ np.asarray(omega0_rad_s, dtype=np.float64).reshape(3)
    Lb = Ip * wp
    L = float(np.linalg.norm(Lb))
    if L == 0:
        return None
    e2 = float(np.sum(Ip * wp ** 2)) / L ** 2  # 2E I₃/|L|², in [1, 1/i₁]
    if Ip[0] >= 1.0 or e2 <= 1.0 + 1e-12:
        return None
    alpha = math.asin(math.sqrt(min(max((e2 - 1.0) / (1.0 / Ip[0] - 1.0), 0.0), 1.0)))
    fw, fp = tumbling_rates(Ip[0], Ip[1], alpha)
    if fw != fw:
        return None
    L_in = quaternion_frames(np.asarray(q0, dtype=np.float64)).T @ (V @ Lb)
    L_in /= np.linalg.norm(L_in)
    if frame == "ecliptic":
        L_in = rot_x3(np.radians(OBLIQUITY_DEG))[0] @ L_in
    return {"i1": float(Ip[0]), "i2": float(Ip[1]), "f_omega_hz": L * fw, "f_phi_hz": L * fp, "alpha": alpha,
            "L_lon_deg": math.degrees(math.atan2(L_in[1], L_in[0])),
            "L_lat_deg": math.degrees(math.asin(np.clip(L_in[2], -1, 1))),
            "short_axis": bool(float(np.sum(Lb ** 2)) >= float(np.sum(Ip * wp ** 2)) * Ip[1])}


def _rate_ratios(i1: float, i2: float, alphas: np.ndarray, n: int) -> np.ndarray:
    """``f_φ/f_ω (K,)`` of :func:`tumbling_rates` at each of ``alphas (K,)`` at once (nan where
    it gives nan): the same Jacobi solution (:func:`~cssat.scene.attitude._motion`) for every
    ``α`` in one array pass — equal to the one-by-one ratio to rounding (the phase taken forward:
    over a whole period the mean does not depend on its direction); for a grid's signs, not a root."""
    from scipy.special import ellipj, ellipk, ellipkinc  # heavy: scipy.special, only for _rate_ratios()

    Ip = np.array([i1, i2, 1.0])
    al = np.asarray(alphas, dtype=np.float64)
    wp = np.stack([np.sin(al), np.zeros_like(al), np.cos(al)], 1) / Ip  # (K, 3): L's body direction (sin α, 0, cos α)
    E2, L2 = (Ip * wp ** 2).sum(1), ((Ip * wp) ** 2).sum(1)
    major = L2 >= E2 * Ip[1]  # about the major axis (order 0, 1, 2) or the minor one (2, 1, 0)
    a_, b_, c_ = np.where(major, Ip[0], Ip[2]), Ip[1], np.where(major, Ip[2], Ip[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        amp0 = np.sqrt(np.clip(np.where(c_ != a_, (E2 * c_ - L2) / (a_ * (c_ - a_)), 0.0), 0, None))
        amp1 = np.sqrt(np.clip(np.where(c_ != b_, (E2 * c_ - L2) / (b_ * (c_ - b_)), 0.0), 0, None))
        amp2 = np.sqrt(np.clip(np.where(c_ != a_, (L2 - E2 * a_) / (c_ * (c_ - a_)), 0.0), 0, None))
        lam = np.sqrt(np.abs((c_ - b_) * (L2 - E2 * a_) / (a_ * b_ * c_)))
        den = (c_ - b_) * (L2 - E2 * a_)
        m = np.where(den == 0, 0.0, np.clip((b_ - a_) * (E2 * c_ - L2) / den, 0.0, 1.0))
        w0, w2 = np.where(major, wp[:, 0], wp[:, 2]), np.where(major, wp[:, 2], wp[:, 0])
        am0 = np.arctan2(0.0, np.where(amp0 > 0, w0 / amp0, 1.0))  # ω's middle component is 0 at α's crossing
        tiny = 1e-12 * np.abs(wp).max(1)
        ok = ~((amp0 <= tiny) & (amp1 <= tiny)) & (m < 1.0 - 1e-12) & (lam > 0)  # not a steady spin, not the separatrix
        m_ok, lam_ok = np.where(ok, m, 0.0), np.where(ok, lam, 1.0)
        half = 2 * ellipk(m_ok) / lam_ok
        u = lam_ok[:, None] * (np.arange(n) * (half / n)[:, None]) + ellipkinc(am0, m_ok)[:, None]
        sn, cn, dn, _ = ellipj(u, m_ok[:, None])
        wx = np.where(major[:, None], amp0[:, None] * cn, np.where(w2 >= 0, 1.0, -1.0)[:, None] * amp2[:, None] * dn)
        wy = amp1[:, None] * sn
        rate = (Ip[0] * wx ** 2 + Ip[1] * wy ** 2) / np.maximum(Ip[0] ** 2 * wx ** 2 + Ip[1] ** 2 * wy ** 2, 1e-300)
        fp = rate.mean(1) / (2 * math.pi)
        return np.where(ok, fp * 2 * half, math.nan)  # f_ω = 1 / (2 half)


def _ratio_roots(i1: float, i2: float, ratio: float, grid: np.ndarray, n_rates: int, xtol: float) -> list[float]:
    """The ``α`` on ``grid``'s brackets where ``f_φ/f_ω = ratio`` for moments ``(i₁, i₂, 1)``
    (``tumbling_rates`` on ``n_rates`` points; a jump of the ratio across a bracket is no root):
    the grid's ratios at once (:func:`_rate_ratios`), each bracket's root by Brent's method on
    :func:`tumbling_rates` one ``α`` at a time."""
    from scipy.optimize import brentq  # heavy: scipy.optimize, only for _ratio_roots()

    def g(a):
        fw, fp = tumbling_rates(i1, i2, a, n=n_rates)
        return fp / fw - ratio if fw == fw else math.nan

    vals = list(_rate_ratios(i1, i2, grid, n_rates) - ratio)
    roots = []
    for k in range(len(grid) - 1):
        a, b = vals[k], vals[k + 1]
        if np.isfinite(a) and np.isfinite(b) and a * b <= 0 and abs(a - b) < 10 * max(abs(ratio), 1.0):
            roots.append(brentq(g, grid[k], grid[k + 1], xtol=xtol) if a * b < 0 else grid[k] if a == 0 else grid[k + 1])
    return roots


def _alpha_roots(i1: float, i2: float, ratio: float, n: int = 72) -> list[float]:
    """Every ``α ∈ (0, π/2)`` with ``f_φ/f_ω = ratio`` for moments ``(i₁, i₂, 1)``."""
    return _ratio_roots(i1, i2, ratio, np.linspace(0.2, 89.8, n) * math.pi / 180, 256, 1e-13)


class TumblingState:
    """One torque-free motion (module docstring): ``i1``, ``i2`` (moments over the largest),
    ``alpha`` (rad), ``f_omega_hz``, ``f_phi_hz``, ``t0_s``, ``lon_deg``, ``lat_deg``
    (the direction of ``L``), ``phi0_deg``, ``t_ref_s`` (the epoch of the phases), ``frame``."""

    def __init__(self, i1: float, i2: float, alpha: float, f_omega_hz: float, f_phi_hz: float, t0_s: float,
                 lon_deg: float, lat_deg: float, phi0_deg: float, t_ref_s: float = 0.0, frame: str = "ecliptic"):
        self.i1, self.i2, self.alpha = float(i1), float(i2), float(alpha)
        self.f_omega_hz, self.f_phi_hz, self.t0_s = float(f_omega_hz), float(f_phi_hz), float(t0_s)
        lon = float(lon_deg)
        if not -180.0 <= lon <= 180.0:  # a refinement's longitude runs on freely: the same direction, wrapped
            lon = (lon + 180.0) % 360.0 - 180.0
        self.lon_deg, self.lat_deg, self.phi0_deg = lon, float(lat_deg), float(phi0_deg)
        self.t_ref_s, self.frame = float(t_ref_s), frame

    @property
    def L_rate(self) -> float:
        """``|L|/I₃`` (rad/s)."""
        return self.f_omega_hz / tumbling_rates(self.i1, self.i2, self.alpha)[0]

    @property
    def inertia(self) -> np.ndarray:
        return np.array([self.i1, self.i2, 1.0])

    def frames(self, times_s: Any) -> np.ndarray:
        """Body (principal) frames ``(T, 3, 3)`` at ``times_s`` (``v_body = R v_inertial``)."""
        from cssat.inversion.spin_search import _pole_rotation  # heavy: cssat.inversion.spin_search imports the EGI grid (torch)

        tau = np.asarray(times_s, dtype=np.float64).reshape(-1) - self.t_ref_s + self.t0_s
        return self.motion(tau) @ (rot_z(np.float64(math.radians(self.phi0_deg)))
                                   @ _pole_rotation(self.lon_deg, self.lat_deg, self.frame))

    def twin(self) -> TumblingState | None:
        """The same motion with the body turned 180° about its circulation axis (the largest
        moment's in a short-axis mode, the smallest's in a long-axis one): that turn leaves the
        inertia tensor unchanged and maps the polhode onto itself half a period of ``ω`` on, so
        ``frames'(t) = R_π frames(t)`` with ``t₀' = t₀ + 1/(2 f_ω)`` and the precession phase
        ``φ₀'`` solved for. Both describe one motion in space; an EGI on a fixed grid of body
        normals fits one of them better (the other's EGI is the grid turned). ``None`` when no
        single ``φ₀'`` matches (to 1e-6 at three times)."""
        _, _, mo = _solution(self.i1, self.i2, self.alpha)
        if mo is None:
            return None
        axis = int(mo["order"][2])
        turn = np.diag([-1.0, -1.0, -1.0])
        turn[axis, axis] = 1.0  # 180° about the circulation axis
        half = 0.5 / self.f_omega_hz
        taus = self.t0_s + np.array([0.0, 0.37, 0.81]) / self.f_omega_hz
        A = (np.einsum("tji,jk,tkl->til", self.motion(taus + half), turn, self.motion(taus))
             @ rot_z(np.float64(math.radians(self.phi0_deg))))  # rot_z(φ₀') at each time
        if not np.allclose(A, A[0], atol=1e-6) or abs(A[0, 2, 2] - 1.0) > 1e-6:
            return None
        phi0 = math.degrees(math.atan2(A[0, 0, 1], A[0, 0, 0]))  # rot_z is passive: [[c, s, 0], [-s, c, 0], [0, 0, 1]]
        return TumblingState(self.i1, self.i2, self.alpha, self.f_omega_hz, self.f_phi_hz, self.t0_s + half, self.lon_deg,
                             self.lat_deg, phi0 % 360.0, self.t_ref_s, self.frame)

    def motion(self, tau: np.ndarray) -> np.ndarray:
        """``B(τ) (T, 3, 3)``: the L-frame (z along ``L``) to the body, from the x–z crossing at
        ``τ = 0`` — :func:`~cssat.scene.attitude.torque_free`'s Euler angles (``θ``, ``ψ``
        exact from the Jacobi solution), the precession ``φ`` by its mean rate plus its periodic
        part tabulated on ``n_table`` points of one period (Simpson, linear interpolation:
        1e-9 rad; the tests hold it to ``torque_free``)."""
        Ip, _, mo = _solution(self.i1, self.i2, self.alpha)
        if mo is None:
            raise FieldError("alpha", "a steady spin is no tumbling motion")
        s = self.L_rate * np.asarray(tau, dtype=np.float64).reshape(-1)  # the motion at |L| = 1 in scaled time
        w = omega_of(mo, s, mo["sign"])
        theta, psi = nutation(Ip, w, 1.0)
        phi = _precession_table(mo, Ip)(s)
        # body +z of the L-frame to (sin α, 0, cos α)
        X = rot_x3(self.alpha)[0].T @ rot_z(np.float64(math.pi / 2)).T @ rot_y(-self.alpha)
        phi = phi + math.atan2(X[0, 1], X[0, 0])
        return rot_z(psi) @ rot_x3(theta) @ rot_z(phi)

    def describe(self) -> dict[str, float]:
        return {"tumble_i1": self.i1, "tumble_i2": self.i2, "tumble_alpha_deg": math.degrees(self.alpha),
                "tumble_P_omega_s": 1 / self.f_omega_hz, "tumble_P_phi_s": 1 / self.f_phi_hz,
                "tumble_L_lon_deg": self.lon_deg, "tumble_L_lat_deg": self.lat_deg, "tumble_t0_s": self.t0_s,
                "tumble_phi0_deg": self.phi0_deg, "tumble_mode": "SAM" if self.short_axis else "LAM"}

    @property
    def short_axis(self) -> bool:
        """A short-axis mode (the body circulates about the axis of the largest moment)."""
        Ip, wp, _ = _solution(self.i1, self.i2, self.alpha)
        return float(np.sum((Ip * wp) ** 2)) >= float(np.sum(Ip * wp ** 2)) * Ip[1]

    def vector(self) -> np.ndarray:
        return np.array([self.i1, self.i2, self.f_omega_hz, self.f_phi_hz, self.t0_s, self.lon_deg, self.lat_deg,
                         self.phi0_deg])

    @classmethod
    def from_vector(cls, x: Any, alpha_hint: float, t_ref_s: float, frame: str) -> TumblingState | None:
        """The state of ``x = (i₁, i₂, f_ω, f_φ, t₀, λ, β, φ₀)``, ``α`` the root of the ratio
        nearest ``alpha_hint``; ``None`` when no motion has those numbers."""
        i1, i2, fw, fp = (float(v) for v in x[:4])
        if not (0.05 < i1 <= i2 <= 1.0 and i1 + i2 >= 1.0 and fw > 0 and fp > 0 and -90.0 <= x[6] <= 90.0):
            return None
        a = _alpha_near(i1, i2, fp / fw, alpha_hint)
        if a is None:
            return None
        return cls(i1, i2, a, fw, fp, x[4], x[5], x[6], x[7], t_ref_s, frame)


def _alpha_near(i1, i2, ratio, hint, width=math.radians(4.0)):
    """The root of :func:`_ratio_roots` nearest ``hint`` within ``width`` (``None``: none)."""
    grid = np.linspace(max(hint - width, 1e-4), min(hint + width, math.pi / 2 - 1e-4), 9)
    return min(_ratio_roots(i1, i2, ratio, grid, 128, 1e-14), key=lambda r: abs(r - hint), default=None)


def _precession_table(mo: dict, Ip: np.ndarray, n_table: int = 2048):
    """``Φ(s) = ∫₀ˢ (I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²) ds'`` at ``|L| = 1``: whole periods of the
    integrand (``2K/λ``) times their integral plus a tabulated part (Simpson on ``n_table``
    intervals, cumulative; linear interpolation)."""
    from scipy.integrate import cumulative_simpson  # heavy: scipy.integrate, only for _precession_table()
    from scipy.special import ellipk  # heavy: scipy.special, only for _precession_table()

    half = 2 * float(ellipk(mo["m"])) / mo["lam"]
    grid = np.linspace(0.0, half, n_table + 1)
    w = omega_of(mo, grid, mo["sign"])
    rate = ((Ip[0] * w[:, 0] ** 2 + Ip[1] * w[:, 1] ** 2)
            / np.maximum(Ip[0] ** 2 * w[:, 0] ** 2 + Ip[1] ** 2 * w[:, 1] ** 2, 1e-300))
    cum = cumulative_simpson(rate, x=grid, initial=0.0)

    def phi(s: np.ndarray) -> np.ndarray:
        n, rest = np.divmod(s, half)
        return n * cum[-1] + np.interp(rest, grid, cum)

    return phi


class _TFit:
    """The EGI fit's χ² of a :class:`TumblingState` on a subset of samples and a grid of normals."""

    def __init__(self, t, y, w, S, O, normals, brdf):
        self.t, self.y, self.w, self.S, self.O, self.N, self.brdf = t, y, w, S, O, normals, brdf
        self.yw = y * w

    @classmethod
    def spread(cls, samples: tuple, mask: np.ndarray, n: int, normals: np.ndarray, brdf: Any) -> _TFit:
        """The fit on at most ``n`` of the samples in ``mask (T,)``, spread evenly over them;
        ``samples = (t (T,), y (T,), w (T,), S (T, 3), O (T, 3))``."""
        t, y, w, S, O = samples
        idx = np.flatnonzero(mask)
        idx = idx[np.unique(np.linspace(0, len(idx) - 1, min(n, len(idx))).round().astype(int))]
        return cls(t[idx], y[idx], w[idx], S[idx], O[idx], normals, brdf)

    def G(self, sb: np.ndarray, ob: np.ndarray) -> np.ndarray:
        """``(..., T, K)`` for body-frame ``sb``, ``ob (..., T, 3)``."""
        from cssat.inversion.egi import geometry_matrix  # heavy: cssat.inversion.egi imports torch

        return geometry_matrix(sb, ob, self.N, self.brdf)

    def matrix(self, state: TumblingState) -> np.ndarray:
        R = state.frames(self.t)
        return self.G(to_body(R, self.S), to_body(R, self.O))

    def nnls(self, G: np.ndarray) -> tuple[np.ndarray, float]:
        from cssat.inversion.spin import _weighted_nnls  # heavy: cssat.inversion.spin imports torch

        return _weighted_nnls(G, self.w, self.yw)

    def solve(self, state: TumblingState) -> tuple[np.ndarray, float]:
        return self.nnls(self.matrix(state))
