"""The spin state of a tumbling object — a torque-free rigid body in non-principal-axis rotation
— and its EGI from a light curve (issue 24, point 4; Kaasalainen 2001, Pravec et al. 2005).

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

from cssat._checks import FieldError, float_param, int_param

__all__ = ["TumblingState", "TumblingSolution", "tumbling_rates", "estimate_tumbling", "torque_free_invariants"]


def _solution(i1: float, i2: float, alpha: float):
    from cssat.scene.attitude import _euler_solution

    Ip = np.array([i1, i2, 1.0])
    wp = np.array([math.sin(alpha), 0.0, math.cos(alpha)]) / Ip
    return Ip, wp, _euler_solution(Ip, wp)


def tumbling_rates(i1: float, i2: float, alpha_rad: float, *, n: int = 256) -> tuple[float, float]:
    """``(f_ω, f_φ)`` in Hz of the torque-free motion with moments ``(i₁, i₂, 1)`` whose body
    angular momentum crosses ``(sin α, 0, cos α)``, per rad/s of ``|L|/I₃``: ``f_ω = λ/(4K(m))``
    (Euler's Jacobi solution) and the mean of the precession rate
    ``φ̇ = |L| (I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²)`` (Landau & Lifshitz §37) over its period
    ``2K/λ`` by the trapezoid rule (spectrally accurate for a periodic integrand) over ``2π``.
    ``(nan, nan)`` on the separatrix or at a steady spin."""
    from scipy.special import ellipk

    from cssat.scene.attitude import _omega_of

    Ip, _, mo = _solution(i1, i2, alpha_rad)
    if mo is None or not mo["m"] < 1.0 - 1e-12 or mo["lam"] <= 0:
        return math.nan, math.nan
    K = float(ellipk(mo["m"]))
    half = 2 * K / mo["lam"]
    w = _omega_of(mo, np.arange(n) * (half / n), mo["sign"])
    num = Ip[0] * w[:, 0] ** 2 + Ip[1] * w[:, 1] ** 2
    den = Ip[0] ** 2 * w[:, 0] ** 2 + Ip[1] ** 2 * w[:, 1] ** 2
    return 1.0 / (2 * half), float(np.mean(num / np.maximum(den, 1e-300))) / (2 * math.pi)


def torque_free_invariants(inertia_kg_m2: Any, q0: Any, omega0_rad_s: Any, frame: str = "ecliptic") -> dict[str, Any]:
    """What a light curve can give of a torque-free motion (:func:`~cssat.scene.attitude.torque_free`'s
    initial state: inertia tensor ``(3, 3)`` or moments ``(3,)``, ``q0`` [x, y, z, w] body →
    inertial, ``omega0_rad_s`` in the body frame): ``i1``, ``i2`` (moments over the largest),
    ``f_omega_hz``, ``f_phi_hz``, the direction of ``L`` (``L_lon_deg``, ``L_lat_deg`` in
    ``frame``), ``alpha`` (rad) and ``short_axis`` — the numbers :func:`estimate_tumbling` estimates.
    ``None`` for a steady spin."""
    from cssat.scene.attitude import OBLIQUITY_DEG, _rx3, quaternion_frames

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
        L_in = _rx3(np.radians(OBLIQUITY_DEG))[0] @ L_in
    return {"i1": float(Ip[0]), "i2": float(Ip[1]), "f_omega_hz": L * fw, "f_phi_hz": L * fp, "alpha": alpha,
            "L_lon_deg": math.degrees(math.atan2(L_in[1], L_in[0])), "L_lat_deg": math.degrees(math.asin(np.clip(L_in[2], -1, 1))),
            "short_axis": bool(float(np.sum(Lb ** 2)) >= float(np.sum(Ip * wp ** 2)) * Ip[1])}


def _ratio_roots(i1: float, i2: float, ratio: float, grid: np.ndarray, n_rates: int, xtol: float) -> list[float]:
    """The ``α`` on ``grid``'s brackets where ``f_φ/f_ω = ratio`` for moments ``(i₁, i₂, 1)``
    (``tumbling_rates`` on ``n_rates`` points; a jump of the ratio across a bracket is no root)."""
    from scipy.optimize import brentq

    def g(a):
        fw, fp = tumbling_rates(i1, i2, a, n=n_rates)
        return fp / fw - ratio if fw == fw else math.nan

    vals = [g(a) for a in grid]
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
        self.lon_deg, self.lat_deg, self.phi0_deg = float(lon_deg), float(lat_deg), float(phi0_deg)
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
        from cssat.inversion.spin import _pole_rotation
        from cssat.scene.attitude import _rz

        tau = np.asarray(times_s, dtype=np.float64).reshape(-1) - self.t_ref_s + self.t0_s
        return self.motion(tau) @ (_rz(np.float64(math.radians(self.phi0_deg))) @ _pole_rotation(self.lon_deg, self.lat_deg, self.frame))

    def motion(self, tau: np.ndarray) -> np.ndarray:
        """``B(τ) (T, 3, 3)``: the L-frame (z along ``L``) to the body, from the x–z crossing at
        ``τ = 0`` — :func:`~cssat.scene.attitude.torque_free`'s Euler angles (``θ``, ``ψ``
        exact from the Jacobi solution), the precession ``φ`` by its mean rate plus its periodic
        part tabulated on ``n_table`` points of one period (Simpson, linear interpolation:
        1e-9 rad; the tests hold it to ``torque_free``)."""
        from cssat.scene.attitude import _nutation, _omega_of, _rx3, _ry, _rz

        Ip, _, mo = _solution(self.i1, self.i2, self.alpha)
        if mo is None:
            raise FieldError("alpha", "a steady spin is no tumbling motion")
        s = self.L_rate * np.asarray(tau, dtype=np.float64).reshape(-1)  # the motion at |L| = 1 in scaled time
        w = _omega_of(mo, s, mo["sign"])
        theta, psi = _nutation(Ip, w, 1.0)
        phi = _precession_table(mo, Ip)(s)
        X = _rx3(self.alpha)[0].T @ _rz(np.float64(math.pi / 2)).T @ _ry(-self.alpha)  # body +z of the L-frame to (sin α, 0, cos α)
        phi = phi + math.atan2(X[0, 1], X[0, 0])
        return _rz(psi) @ _rx3(theta) @ _rz(phi)

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
    from scipy.integrate import cumulative_simpson
    from scipy.special import ellipk

    from cssat.scene.attitude import _omega_of

    half = 2 * float(ellipk(mo["m"])) / mo["lam"]
    grid = np.linspace(0.0, half, n_table + 1)
    w = _omega_of(mo, grid, mo["sign"])
    rate = (Ip[0] * w[:, 0] ** 2 + Ip[1] * w[:, 1] ** 2) / np.maximum(Ip[0] ** 2 * w[:, 0] ** 2 + Ip[1] ** 2 * w[:, 1] ** 2, 1e-300)
    cum = cumulative_simpson(rate, x=grid, initial=0.0)

    def phi(s: np.ndarray) -> np.ndarray:
        n, rest = np.divmod(s, half)
        return n * cum[-1] + np.interp(rest, grid, cum)

    return phi


# --- the search ---------------------------------------------------------------------------------

class TumblingSolution:
    """What :func:`estimate_tumbling` returns: ``state`` (:class:`TumblingState`, the body frame
    its principal frame), ``normals (K, 3)``/``areas (K,)`` (the EGI in that frame, those with
    area), ``chi2``, ``reduced_chi2``, ``residual (T,)`` (flux − fit on every sample), ``errors``
    (1σ of ``i1, i2, P_omega_s, P_phi_s, t0_s, L_lon_deg, L_lat_deg, phi0_deg`` and
    ``L_err_deg``, the angular 1σ of ``L``: the formal Gauss–Newton 1σ on the state and the
    support's areas, scaled by the reduced χ² when above 1, added in quadrature to the shift of the
    fit on a grid of normals turned at random — ``formal_L_err_deg``, ``grid_L_shift_deg``), ``lattice_hz`` (the light curve's two fundamental
    frequencies the search started from), ``frequency_pairs`` (the ``(P_ω, P_φ)`` hypotheses
    searched), ``alternatives`` (other refined minima with
    ``delta_chi2`` in units of the reduced χ² and ``separation_deg`` of their ``L``) and
    ``ambiguous`` (one of them within Δχ² < 9 and more than 10° away)."""

    def __init__(self, **kw: Any):
        self.__dict__.update(kw)

    def frames(self, times_s: Any) -> np.ndarray:
        return self.state.frames(times_s)

    def predict(self, times_s: Any, sun: Any, obs: Any) -> np.ndarray:
        """The fitted light curve ``(T,)`` at ``times_s`` for inertial ``sun``/``obs (T, 3)``."""
        from cssat.inversion.egi import egi_operator
        from cssat.scene.attitude import to_body

        R = self.frames(times_s)
        G = egi_operator(to_body(R, np.asarray(sun, dtype=np.float64)), to_body(R, np.asarray(obs, dtype=np.float64)),
                         self.normals, self.brdf).matrix().numpy()
        return G @ self.areas

    def describe(self) -> dict[str, Any]:
        out = self.state.describe()
        out.update(tumble_chi2=self.chi2, tumble_reduced_chi2=self.reduced_chi2, tumble_ambiguous=self.ambiguous,
                   **{f"tumble_err_{k}": v for k, v in self.errors.items()})
        return out

    def __repr__(self) -> str:
        s = self.state
        return (f"TumblingSolution(L ({s.lon_deg:.2f}°, {s.lat_deg:.2f}°) ± {self.errors['L_err_deg']:.2g}°, "
                f"P_ω {1 / s.f_omega_hz:.4f} s, P_φ {1 / s.f_phi_hz:.4f} s, I₁/I₃ {s.i1:.3f}, I₂/I₃ {s.i2:.3f}, "
                f"{'SAM' if s.short_axis else 'LAM'}, reduced χ² {self.reduced_chi2:.3g})")


class _TFit:
    """The EGI fit's χ² of a :class:`TumblingState` on a subset of samples and a grid of normals."""

    def __init__(self, t, y, w, S, O, normals, brdf):
        self.t, self.y, self.w, self.S, self.O, self.N, self.brdf = t, y, w, S, O, normals, brdf
        self.yw = y * w

    def G(self, sb: np.ndarray, ob: np.ndarray) -> np.ndarray:
        """``(..., T, K)`` for body-frame ``sb``, ``ob (..., T, 3)``."""
        from cssat.inversion.egi import geometry_matrix

        return geometry_matrix(sb, ob, self.N, self.brdf)

    def matrix(self, state: TumblingState) -> np.ndarray:
        from cssat.scene.attitude import to_body

        R = state.frames(self.t)
        return self.G(to_body(R, self.S), to_body(R, self.O))

    def nnls(self, G: np.ndarray) -> tuple[np.ndarray, float]:
        from cssat.inversion.spin import _weighted_nnls

        return _weighted_nnls(G, self.w, self.yw)

    def solve(self, state: TumblingState) -> tuple[np.ndarray, float]:
        return self.nnls(self.matrix(state))


def _candidates(f1: float, f2: float, ratio_lo: float, ratio_hi: float, max_coef: int = 2) -> list[tuple[float, float]]:
    """Pairs ``(f_ω, f_φ)`` spanning the lattice of ``f₁, f₂``: ``f_ω = a f₁ + b f₂ > 0`` primitive
    with ``|a|, |b| ≤ max_coef``, ``f_φ`` any complement ``c f₁ + d f₂`` (``ad − bc = ±1``) shifted by
    whole ``f_ω`` so that ``ratio_lo ≤ f_φ/f_ω ≤ ratio_hi``; each pair once."""
    out: list[tuple[float, float]] = []
    for a in range(-max_coef, max_coef + 1):
        for b in range(-max_coef, max_coef + 1):
            if math.gcd(a, b) != 1:
                continue
            fw = a * f1 + b * f2
            if fw <= 0:
                continue
            # a complement (c, d) with a d − b c = 1
            c, d = next((c, d) for c in range(-3, 4) for d in range(-3, 4) if a * d - b * c == 1)
            for fc in (c * f1 + d * f2, -(c * f1 + d * f2)):  # both orientations: ad − bc = +1 and −1
                for k in range(math.ceil(ratio_lo - fc / fw), math.floor(ratio_hi - fc / fw) + 1):
                    fp = fc + k * fw
                    if fp > 0 and all(abs(fw - u) > 1e-9 * fw or abs(fp - v) > 1e-9 * fp for u, v in out):
                        out.append((fw, fp))
    return out


#: the moments ``(I₁/I₃, I₂/I₃)`` the coarse search starts from: the rigid-body triangle
#: ``i₁ ≤ i₂ ≤ 1 ≤ i₁ + i₂`` in steps of 0.1 (``i₁ ≥ 0.25``)
INERTIA_GRID = tuple((round(i1, 2), round(i2, 2)) for i2 in (0.55, 0.65, 0.75, 0.85, 0.95)
                     for i1 in np.arange(0.25, 0.96, 0.1) if i1 <= i2 + 1e-9 and i1 + i2 >= 1 - 1e-9)


def estimate_tumbling(times_s: Any, flux: Any, sun: Any, obs: Any, *, sigma: Any = None, brdf: Any = None,
                      frame: str = "ecliptic", periods_s: Any = None, min_period_s: float = 60.0,
                      max_period_s: float = 3000.0, arc_s: float = 3600.0, inertia_grid: Any = INERTIA_GRID,
                      max_ratio: float = 8.0, n_poles: int = 40, n_t0: int = 6, n_phi: int = 8, n_prerank: int = 16, n_pairs: int = 3, screen_moments: int = 6, screen_poles: int = 20, n_screen: int = 24, n_starts: int = 8,
                      n_refine: int = 4, coarse_normals: int = 64, coarse_samples: int = 160, mid_normals: int = 150,
                      mid_samples: int = 400, n_normals: int = 600, max_samples: int = 1200, growth: float = 3.0,
                      max_fev: int = 200, screen_fev: int = 30, final_fev: int = 60) -> TumblingSolution:
    """The torque-free tumbling state (:class:`TumblingState`) and EGI of an object from its light
    curve ``flux (T,)`` at ``times_s (T,)``, the Sun and observer directions ``sun``, ``obs (T, 3)``
    (inertial unit vectors from the object), ``sigma`` its 1σ, ``brdf`` (default Lambert): the
    tumbling inversion of Kaasalainen (2001) with the EGI model of
    :func:`~cssat.inversion.egi_operator` (no shadowing), scored by the NNLS EGI fit's χ².

    1. The light curve's frequency lattice: ``periods_s = (P_ω, P_φ)`` given, or the two
       fundamental frequencies of :func:`~cssat.inversion.estimate_tumbling_periods` on the first
       ``arc_s`` seconds (over one short arc the geometry barely changes, so the 2-D Fourier
       series holds; its ``f_φ`` is the synodic one). Which lattice vectors are ``f_ω`` and
       ``f_φ`` is not known: the pairs of :func:`_candidates` (``f_ω`` a primitive vector with
       coefficients ≤ 1, ``f_φ = `` a complement shifted by whole ``f_ω``, the ratio within what
       the inertia grid's motions reach and ``max_ratio``, both periods above ``min_period_s``)
       are ranked by the χ² of the 2-D Fourier series of order 3 in their basis (in the physical
       basis the light curve's power sits at low orders: 2f_φ, 2f_φ ± f_ω, …) and the
       ``n_prerank`` best kept.
    2. Coarse search on that arc (``coarse_samples`` samples, ``coarse_normals`` normals): when
       there are more than ``n_pairs`` pairs, each is first scored on ``screen_moments`` moments
       of the grid spread over it and ``screen_poles`` directions, and the ``n_pairs`` best kept; then for each moment of
       ``inertia_grid`` (default :data:`INERTIA_GRID`, 27 points) and each pair, every ``α``
       with that frequency ratio, and a grid of ``n_poles`` directions of ``L`` × ``n_t0``
       polhode phases × ``n_phi`` precession phases, each scored by NNLS.
    3. The best start of each moment and direction (two distinct directions per moment, at most
       ``n_screen``) refined by a few (``screen_fev``) steps of Levenberg–Marquardt (trust-region
       reflective, the EGI re-solved by NNLS at each step: variable projection) in all eight
       numbers ``(i₁, i₂, f_ω, f_φ, t₀, λ, β, φ₀)`` on ``mid_samples`` samples and
       ``mid_normals`` normals; the ``n_starts`` best refined fully (``max_fev``); the
       ``n_refine`` best carried to arcs ``growth`` times longer (a continuation in time: the phases
       stay coherent while the span grows) up to every sample, then fitted on ``max_samples``
       samples and ``n_normals`` normals (``final_fev``).
    4. 1σ by Gauss–Newton and the EGI grid's bias (:class:`TumblingSolution`).

    Assumptions: torque-free rigid rotation (no damping, no torques) over the span, a convex body
    (no self-shadowing), one BRDF shape, samples dense enough to resolve the light curve's
    harmonics (seconds, not minutes: a 30 s cadence aliases a 200 s tumbler's glints).
    """
    from cssat._checks import choice_param
    from cssat.inversion.egi import fibonacci_sphere
    from cssat.inversion.frequencies import estimate_tumbling_periods
    from cssat.inversion.spin import _check_light_curve, _pole_rotation, _separation_deg
    from cssat.scene.attitude import _rz

    import logging
    import time

    log = logging.getLogger("cssat")
    clock = time.perf_counter()
    frame = choice_param(frame, "frame", ("ecliptic", "equatorial"))
    t, y, S, O, w, sig = _check_light_curve(times_s, flux, sun, obs, sigma)
    T = len(t)
    t_ref = float(t[0])
    span = float(t[-1] - t[0])
    arc_s = float_param(arc_s, "arc_s", 0.0, open_lo=True)
    grid_I = np.asarray(inertia_grid, dtype=np.float64).reshape(-1, 2)
    if not np.all((grid_I[:, 0] > 0) & (grid_I[:, 0] <= grid_I[:, 1]) & (grid_I[:, 1] <= 1) & (grid_I.sum(1) >= 1)):
        raise FieldError("inertia_grid", "each (I1/I3, I2/I3) needs 0 < I1/I3 <= I2/I3 <= 1 <= I1/I3 + I2/I3")
    n_poles, n_t0, n_phi, n_starts, n_refine = (int_param(v, k, 1) for v, k in (
        (n_poles, "n_poles"), (n_t0, "n_t0"), (n_phi, "n_phi"), (n_starts, "n_starts"), (n_refine, "n_refine")))

    def subset(mask, n):
        idx = np.flatnonzero(mask)
        idx = idx[np.unique(np.linspace(0, len(idx) - 1, min(n, len(idx))).round().astype(int))]
        return t[idx], y[idx], w[idx], S[idx], O[idx]

    arc = t <= t_ref + arc_s
    if arc.sum() < 16:
        raise FieldError("arc_s", f"the first arc ({arc_s:g} s) holds {int(arc.sum())} samples: at least 16 are needed")
    # 1. the lattice
    if periods_s is not None:
        p = np.asarray(periods_s, dtype=np.float64).reshape(-1)
        if p.shape != (2,) or not np.all(np.isfinite(p) & (p > 0)):
            raise FieldError("periods_s", f"expected (P_omega, P_phi) in seconds, both > 0, got {periods_s!r}")
        lattice = 1.0 / p
        pairs = [(float(lattice[0]), float(lattice[1]))]
    else:
        tp = estimate_tumbling_periods(t[arc], y[arc], sigma=None if sig is None else sig[arc], min_period_s=min_period_s,
                                       max_period_s=max_period_s, order=4)
        lattice = tp["frequencies_hz"]
        rhos = [fp / fw for i1, i2 in grid_I for fw, fp in (tumbling_rates(i1, i2, a) for a in np.radians(np.linspace(0.5, 89.5, 30)))
                if fw == fw]
        f_max = 1.0 / float_param(min_period_s, "min_period_s", 0.0, open_lo=True)
        pairs = [(fw, fp) for fw, fp in _candidates(float(lattice[0]), float(lattice[1]), min(rhos),
                                                    min(max(rhos), float_param(max_ratio, "max_ratio", 1.0)), max_coef=1)
                 if fw <= f_max and fp <= f_max]
        if not pairs:
            raise FieldError("periods_s", f"no pair of the light curve's frequencies {lattice} is a torque-free motion of the inertia grid")
        if len(pairs) > n_prerank:  # the light curve's power at low orders of each basis: the physical one is compact
            from cssat.inversion.frequencies import _chi2_2d, _lattice

            jk = _lattice(3)
            ta = t[arc] - t_ref
            c3 = [_chi2_2d(ta, y[arc], w[arc], fw, fp, jk) for fw, fp in pairs]
            pairs = [pairs[i] for i in np.argsort(c3)[:n_prerank]]
    # 2. the coarse search on the first arc
    coarse = _TFit(*subset(arc, int_param(coarse_samples, "coarse_samples", 16)),
                   fibonacci_sphere(int_param(coarse_normals, "coarse_normals", 8)).numpy(), brdf)
    phis = np.arange(n_phi) * (360.0 / n_phi)
    Rphi = _rz(np.radians(phis))  # (n_phi, 3, 3)
    def scan(moments, pairs_, n_dirs):
        """Each moment and direction of ``L``: its best ``(chi2, vector, alpha, moment index)``."""
        poles = fibonacci_sphere(n_dirs).numpy()
        pole_ll = np.stack([np.degrees(np.arctan2(poles[:, 1], poles[:, 0])),
                            np.degrees(np.arcsin(np.clip(poles[:, 2], -1, 1)))], 1)
        Ms = [_pole_rotation(lo, la, frame) for lo, la in pole_ll]
        SL = [np.einsum("pij,tj->pti", Rphi, coarse.S @ M.T) for M in Ms]  # (n_phi, T, 3) in the L-frame
        OL = [np.einsum("pij,tj->pti", Rphi, coarse.O @ M.T) for M in Ms]
        out = []
        for k, (i1, i2) in enumerate(moments):
            per_pole: list[tuple] = [(np.inf, None, None, k)] * n_dirs
            for fw, fp in pairs_:
                for alpha in _alpha_roots(i1, i2, fp / fw, n=48):
                    st = TumblingState(i1, i2, alpha, fw, fp, 0.0, 0.0, 90.0, 0.0, t_ref, frame)
                    t0s = np.arange(n_t0) / (n_t0 * fw)
                    B = np.stack([st.motion(coarse.t - t_ref + t0) for t0 in t0s])  # (n_t0, T, 3, 3)
                    for j, (lo, la) in enumerate(pole_ll):
                        G = coarse.G(np.einsum("atij,ptj->apti", B, SL[j]), np.einsum("atij,ptj->apti", B, OL[j]))
                        for a_ in range(n_t0):
                            for p_ in range(n_phi):
                                c = coarse.nnls(G[a_, p_])[1]
                                if c < per_pole[j][0]:
                                    per_pole[j] = (c, np.array([i1, i2, fw, fp, t0s[a_], lo, la, phis[p_]]), alpha, k)
            out += [r for r in per_pole if r[1] is not None]
        return out

    if len(pairs) > n_pairs:  # the lattice's pairs screened on four moments and half the directions
        few = grid_I[np.unique(np.linspace(0, len(grid_I) - 1, min(int_param(screen_moments, "screen_moments", 1),
                                                                  len(grid_I))).round().astype(int))]
        score = []
        for pair in pairs:
            r = scan(few, [pair], int_param(screen_poles, "screen_poles", 1))
            score.append(min((q[0] for q in r), default=np.inf))
        order = np.argsort(score)
        log.info("estimate_tumbling: %d frequency pairs screened, %.1f s; kept %s", len(pairs), time.perf_counter() - clock,
                 [(round(1 / pairs[i][0], 2), round(1 / pairs[i][1], 2)) for i in order[:n_pairs]])
        pairs = [pairs[i] for i in order[:n_pairs] if np.isfinite(score[i])]
    table = scan(grid_I, pairs, n_poles)
    if not table:
        raise FieldError("periods_s", "no torque-free motion of the inertia grid has these frequencies: give periods_s "
                                      "or widen inertia_grid / max_ratio")
    table.sort(key=lambda r: r[0])
    log.info("estimate_tumbling: %d frequency pairs, coarse search %.1f s", len(pairs), time.perf_counter() - clock)

    def refine(fit, x0, alpha0, span_s, maxfev=max_fev):
        """Levenberg–Marquardt (trust-region reflective) on the weighted residual, the EGI
        re-solved by NNLS at every step (variable projection); the moments as ``i₂ ∈ [½, 1]``
        and ``u ∈ [0, 1]``, ``i₁ = 1 − i₂ + u (2 i₂ − 1)``, so the rigid-body triangle is a box."""
        from scipy.optimize import least_squares

        scale = np.array([1.0, 1.0, 1 / (360 * span_s), 1 / (360 * span_s), 1 / (360 * x0[2]), 1.0, 1.0, 1.0])
        i1, i2 = x0[0], x0[1]
        u0 = (i1 - (1 - i2)) / max(2 * i2 - 1, 1e-12)
        z0 = np.concatenate([[min(max(u0, 0.0), 1.0), i2], np.zeros(6)])
        cache = {"alpha": alpha0}

        def state(z):
            u, j2 = z[0], z[1]
            x = np.concatenate([[1 - j2 + u * (2 * j2 - 1), j2], x0[2:] + z[2:] * scale[2:]])
            return x, TumblingState.from_vector(x, cache["alpha"], t_ref, frame)

        def resid(z):
            _, st = state(z)
            if st is None:
                return fit.yw * 10.0  # no motion has these numbers: far worse than any fit
            cache["alpha"] = st.alpha
            G = fit.matrix(st)
            a, _ = fit.nnls(G)
            return (G @ a) * fit.w - fit.yw

        lo = np.array([0.0, 0.5] + [-np.inf] * 6)
        hi = np.array([1.0, 1.0] + [np.inf] * 6)
        z0 = np.clip(z0, lo + 1e-9, hi - 1e-9)
        res = least_squares(resid, z0, bounds=(lo, hi), method="trf", diff_step=1e-4, x_scale=np.array([0.05, 0.05] + [1.0] * 6),
                            max_nfev=int(maxfev))
        x, st = state(res.x)
        return (float(2 * res.cost), x, st.alpha if st is not None else alpha0)

    spacing = math.degrees(math.sqrt(4 * math.pi / n_poles))
    starts: list[tuple] = []  # the best of each moment, then others, distinct in L within a moment
    for r in table:
        same = [q for q in starts if q[3] == r[3]]
        if len(same) < 2 and all(_separation_deg(tuple(r[1][5:7]), tuple(q[1][5:7])) > 1.5 * spacing for q in same):
            starts.append(r)
        if len(starts) == n_screen:
            break
    mid_N = fibonacci_sphere(int_param(mid_normals, "mid_normals", 16)).numpy()
    fine_N = fibonacci_sphere(int_param(n_normals, "n_normals", 16)).numpy()
    n_mid = int_param(mid_samples, "mid_samples", 16)
    arc_fit = _TFit(*subset(arc, n_mid), mid_N, brdf)
    screened = sorted((refine(arc_fit, q[1], q[2], arc_s, maxfev=screen_fev) for q in starts), key=lambda r: r[0])
    cur = sorted((refine(arc_fit, r[1], r[2], arc_s) for r in screened[:n_starts]), key=lambda r: r[0])[:n_refine]
    log.info("estimate_tumbling: %d starts refined on the first arc, %.1f s (best reduced chi2 %.3g)", len(starts),
             time.perf_counter() - clock, cur[0][0] / len(arc_fit.t))
    # 3. continuation: longer arcs, then every sample
    length = arc_s
    while length < span:
        length = min(length * float_param(growth, "growth", 1.0, open_lo=True), span)
        fit = _TFit(*subset(t <= t_ref + length, n_mid), mid_N, brdf)
        cur = sorted((refine(fit, r[1], r[2], length) for r in cur), key=lambda r: r[0])
        log.info("estimate_tumbling: arc %.0f s refined, %.1f s (best reduced chi2 %.3g)", length, time.perf_counter() - clock,
                 cur[0][0] / len(fit.t))
    final = _TFit(*subset(np.ones(T, bool), max_samples), fine_N, brdf)
    cur = sorted((refine(final, r[1], r[2], span, maxfev=final_fev)
                  for r in cur), key=lambda r: r[0])
    log.info("estimate_tumbling: final fit, %.1f s", time.perf_counter() - clock)
    chi2, x, alpha = cur[0]
    state = TumblingState.from_vector(x, alpha, t_ref, frame)
    state.lon_deg = float((state.lon_deg + 180.0) % 360.0 - 180.0)
    state.phi0_deg = float(state.phi0_deg % 360.0)
    a, chi2 = final.solve(state)
    # 4. 1σ: Gauss–Newton on the eight numbers and the support's areas
    sup = a > 1e-9 * max(float(a.max()), 1e-300)
    A = final.matrix(state) * final.w[:, None]
    h = np.array([1e-4, 1e-4, 1e-4 / (360 * span), 1e-4 / (360 * span), 1e-4 / (360 * x[2]), 1e-3, 1e-3, 1e-3])
    cols = []
    for i in range(8):
        hi, lo = x.copy(), x.copy()
        hi[i] += h[i]
        lo[i] -= h[i]
        s_hi, s_lo = (TumblingState.from_vector(v, state.alpha, t_ref, frame) for v in (hi, lo))
        if s_hi is None or s_lo is None:
            cols.append(np.zeros(len(final.t)))
            continue
        cols.append((final.matrix(s_hi) - final.matrix(s_lo)) @ a * final.w / (2 * h[i]))
    J = np.column_stack(cols + [A[:, sup]])
    dof = max(len(final.t) - J.shape[1], 1)
    red = chi2 / dof
    cov = np.linalg.pinv(J.T @ J)[:8, :8] * (max(red, 1.0) if sig is not None else red)
    e = np.sqrt(np.clip(np.diag(cov), 0, None))
    formal_L = float(np.hypot(e[6], math.cos(math.radians(state.lat_deg)) * e[5]))
    # the EGI grid's bias (it dominates at high SNR): the fit again on the grid of normals turned at random
    from scipy.spatial.transform import Rotation

    turned = _TFit(final.t, final.y, final.w, final.S, final.O, fine_N @ Rotation.random(random_state=0).as_matrix().T, brdf)
    _, xg, _ = refine(turned, x, state.alpha, span, maxfev=final_fev)
    shift = np.abs(xg - x)
    grid_L = _separation_deg((state.lon_deg, state.lat_deg), (float(xg[5]), float(xg[6])))
    errors = {"i1": np.hypot(e[0], shift[0]), "i2": np.hypot(e[1], shift[1]),
              "P_omega_s": np.hypot(e[2], shift[2]) / x[2] ** 2, "P_phi_s": np.hypot(e[3], shift[3]) / x[3] ** 2,
              "t0_s": np.hypot(e[4], shift[4]), "L_lon_deg": np.hypot(e[5], shift[5]), "L_lat_deg": np.hypot(e[6], shift[6]),
              "phi0_deg": np.hypot(e[7], shift[7]), "L_err_deg": float(np.hypot(formal_L, grid_L)),
              "formal_L_err_deg": formal_L, "grid_L_shift_deg": grid_L}
    alts = []
    for c2, x2, _ in cur[1:]:
        if any(_separation_deg((float(x2[5]), float(x2[6])), (float(v[5]), float(v[6]))) < 1.0
               and abs(x2[2] / v[2] - 1) < 1e-4 and abs(x2[3] / v[3] - 1) < 1e-4
               for v in [x] + [np.array([0, 0, 1 / q["P_omega_s"], 1 / q["P_phi_s"], 0, q["L_lon_deg"], q["L_lat_deg"], 0])
                               for q in alts]):
            continue  # the same minimum reached from another start
        alts.append({"L_lon_deg": float(x2[5]), "L_lat_deg": float(x2[6]), "P_omega_s": float(1 / x2[2]),
                     "P_phi_s": float(1 / x2[3]), "i1": float(x2[0]), "i2": float(x2[1]), "chi2": float(c2),
                     "delta_chi2": float((c2 - chi2) / max(red, 1e-300)),
                     "separation_deg": _separation_deg((state.lon_deg, state.lat_deg), (float(x2[5]), float(x2[6])))})
    full = _TFit(t, y, w, S, O, fine_N, brdf)
    resid = y - full.matrix(state) @ a
    return TumblingSolution(state=state, normals=fine_N[sup], areas=a[sup], chi2=float(chi2), reduced_chi2=float(red),
                            residual=resid, errors={k: float(v) for k, v in errors.items()}, lattice_hz=np.asarray(lattice),
                            frequency_pairs=[(1 / fw, 1 / fp) for fw, fp in pairs], alternatives=alts,
                            ambiguous=any(al["delta_chi2"] < 9 and al["separation_deg"] > 10 for al in alts), brdf=brdf,
                            coarse=[{"chi2": float(r[0]), "P_omega_s": float(1 / r[1][2]), "P_phi_s": float(1 / r[1][3]),
                                     "i1": float(r[1][0]), "i2": float(r[1][1])} for r in table[:20]])
