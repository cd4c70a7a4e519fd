"""The tumbling search's coarse stage (:func:`cssat.inversion.tumble.estimate_tumbling`, steps 1–2):
the frequency pairs ``(f_ω, f_φ)`` a light curve's lattice allows, their screening, the grid of
moments × directions of ``L`` × phases scored by NNLS on the first arc, and the distinct starts it
hands to the refinement (:mod:`cssat.inversion.tumble_fit`)."""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.inversion.tumble_state import TumblingState, _alpha_roots, _TFit, tumbling_rates
from cssat.scene.attitude import rot_z

log = logging.getLogger("cssat")


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


def _given_pairs(periods_s: Any) -> tuple[np.ndarray, list[tuple[float, float]]]:
    """The lattice ``(2,)`` in Hz and its one pair ``(f_ω, f_φ)`` from ``periods_s = (P_ω, P_φ)``."""
    p = np.asarray(periods_s, dtype=np.float64).reshape(-1)
    if p.shape != (2,) or not np.all(np.isfinite(p) & (p > 0)):
        raise FieldError("periods_s", f"expected (P_omega, P_phi) in seconds, both > 0, got {periods_s!r}")
    lattice = 1.0 / p
    return lattice, [(float(lattice[0]), float(lattice[1]))]


def _lattice_pairs(t: np.ndarray, y: np.ndarray, w: np.ndarray, sig: np.ndarray | None, t_ref: float, grid_I: np.ndarray,
                   min_period_s: float, max_period_s: float, max_ratio: float,
                   n_prerank: int) -> tuple[np.ndarray, list[tuple[float, float]]]:
    """The light curve's lattice ``(2,)`` in Hz (:func:`~cssat.inversion.estimate_tumbling_periods` on
    the first arc's ``t, y (T,)``, weights ``w = 1/σ``, ``sig`` its 1σ or ``None``) and the pairs
    ``(f_ω, f_φ)`` in it (:func:`_candidates`) that the moments of ``grid_I (M, 2)`` reach, both
    periods above ``min_period_s``; more than ``n_prerank`` are ranked by the χ² of the 2-D Fourier
    series of order 3 in their basis and the ``n_prerank`` best kept."""
    from cssat.inversion.frequencies import estimate_tumbling_periods  # heavy: cssat.inversion.frequencies imports torch

    tp = estimate_tumbling_periods(t, y, sigma=sig, min_period_s=min_period_s, max_period_s=max_period_s, order=4)
    lattice = tp["frequencies_hz"]
    if not np.all(np.isfinite(lattice)):
        raise FieldError("min_period_s", f"the first arc ({float(np.ptp(t)):.6g} s) holds no two frequencies with periods in "
                                         f"[{min_period_s:g}, {max_period_s:g}] s: give periods the arc resolves, a longer "
                                         "arc_s, or periods_s")
    rhos = [fp / fw for i1, i2 in grid_I for fw, fp in (tumbling_rates(i1, i2, a) for a in np.radians(np.linspace(0.5, 89.5, 30)))
            if fw == fw]
    f_max = 1.0 / float_param(min_period_s, "min_period_s", 0.0, open_lo=True)
    pairs = [(fw, fp) for fw, fp in _candidates(float(lattice[0]), float(lattice[1]), min(rhos),
                                                min(max(rhos), float_param(max_ratio, "max_ratio", 1.0)), max_coef=1)
             if fw <= f_max and fp <= f_max]
    if not pairs:
        raise FieldError("periods_s", f"no pair of the light curve's frequencies {lattice} is a torque-free motion of the "
                                      "inertia grid")
    if len(pairs) > n_prerank:  # the light curve's power at low orders of each basis: the physical one is compact
        from cssat.inversion.frequencies import _chi2_2d, _lattice  # heavy: cssat.inversion.frequencies imports torch

        jk = _lattice(3)
        ta = t - t_ref
        c3 = [_chi2_2d(ta, y, w, fw, fp, jk) for fw, fp in pairs]
        pairs = [pairs[i] for i in np.argsort(c3)[:n_prerank]]
    return lattice, pairs


class _CoarseGrid:
    """The coarse search on ``fit`` (the first arc): ``n_t0`` polhode phases × ``n_phi`` precession
    phases for each moment, frequency pair, root ``α`` and direction of ``L``, each scored by NNLS."""

    def __init__(self, fit: _TFit, n_t0: int, n_phi: int, t_ref: float, frame: str):
        self.fit, self.n_t0, self.n_phi, self.t_ref, self.frame = fit, n_t0, n_phi, t_ref, frame
        self.phis = np.arange(n_phi) * (360.0 / n_phi)
        self.Rphi = rot_z(np.radians(self.phis))  # (n_phi, 3, 3)

    def scan(self, moments: Any, pairs: list[tuple[float, float]], n_dirs: int) -> list[tuple]:
        """Each moment of ``moments (M, 2)`` and each of ``n_dirs`` directions of ``L`` (a Fibonacci
        grid): its best ``(chi2, vector (8,), alpha, moment index)`` over ``pairs``, the roots ``α``
        and the phases."""
        from cssat.inversion.egi import fibonacci_sphere  # heavy: cssat.inversion.egi imports torch
        from cssat.inversion.spin_search import _pole_rotation  # heavy: cssat.inversion.spin_search imports the EGI grid (torch)

        coarse, Rphi, n_t0, t_ref = self.fit, self.Rphi, self.n_t0, self.t_ref
        poles = fibonacci_sphere(n_dirs).numpy()
        pole_ll = np.stack([np.degrees(np.arctan2(poles[:, 1], poles[:, 0])),
                            np.degrees(np.arcsin(np.clip(poles[:, 2], -1, 1)))], 1)
        Ms = [_pole_rotation(lo, la, self.frame) for lo, la in pole_ll]
        SL = [np.einsum("pij,tj->pti", Rphi, coarse.S @ M.T) for M in Ms]  # (n_phi, T, 3) in the L-frame
        OL = [np.einsum("pij,tj->pti", Rphi, coarse.O @ M.T) for M in Ms]
        out = []
        for k, (i1, i2) in enumerate(moments):
            per_pole: list[tuple] = [(np.inf, None, None, k)] * n_dirs
            for fw, fp in pairs:
                for alpha in _alpha_roots(i1, i2, fp / fw, n=48):
                    st = TumblingState(i1, i2, alpha, fw, fp, 0.0, 0.0, 90.0, 0.0, t_ref, self.frame)
                    t0s = np.arange(n_t0) / (n_t0 * fw)
                    B = np.stack([st.motion(coarse.t - t_ref + t0) for t0 in t0s])  # (n_t0, T, 3, 3)
                    for j, (lo, la) in enumerate(pole_ll):
                        G = coarse.G(np.einsum("atij,ptj->apti", B, SL[j]), np.einsum("atij,ptj->apti", B, OL[j]))
                        for a_ in range(n_t0):
                            for p_ in range(self.n_phi):
                                c = coarse.nnls(G[a_, p_])[1]
                                if c < per_pole[j][0]:
                                    per_pole[j] = (c, np.array([i1, i2, fw, fp, t0s[a_], lo, la, self.phis[p_]]), alpha, k)
            out += [r for r in per_pole if r[1] is not None]
        return out

    def screen(self, grid_I: np.ndarray, pairs: list[tuple[float, float]], n_pairs: int, screen_moments: int,
               screen_poles: int, clock: float) -> list[tuple[float, float]]:
        """The ``n_pairs`` best of ``pairs``, each scored on ``screen_moments`` moments spread over
        ``grid_I`` and ``screen_poles`` directions (``clock``: the search's start, for the log)."""
        few = grid_I[np.unique(np.linspace(0, len(grid_I) - 1, min(int_param(screen_moments, "screen_moments", 1),
                                                                  len(grid_I))).round().astype(int))]
        score = []
        for pair in pairs:
            r = self.scan(few, [pair], int_param(screen_poles, "screen_poles", 1))
            score.append(min((q[0] for q in r), default=np.inf))
        order = np.argsort(score)
        log.info("estimate_tumbling: %d frequency pairs screened, %.1f s; kept %s", len(pairs), time.perf_counter() - clock,
                 [(round(1 / pairs[i][0], 2), round(1 / pairs[i][1], 2)) for i in order[:n_pairs]])
        return [pairs[i] for i in order[:n_pairs] if np.isfinite(score[i])]


def _distinct_starts(table: list[tuple], n_poles: int, n_screen: int) -> list[tuple]:
    """At most ``n_screen`` starts from the coarse ``table`` (sorted by χ²): the best of each moment,
    then others, at most two per moment and distinct in ``L`` (1.5× the pole grid's spacing)."""
    from cssat.inversion.spin import _separation_deg  # heavy: cssat.inversion.spin imports torch

    spacing = math.degrees(math.sqrt(4 * math.pi / n_poles))
    starts: list[tuple] = []  # the best of each moment, then others, distinct in L within a moment
    for r in table:
        same = [q for q in starts if q[3] == r[3]]
        if len(same) < 2 and all(_separation_deg(tuple(r[1][5:7]), tuple(q[1][5:7])) > 1.5 * spacing for q in same):
            starts.append(r)
        if len(starts) == n_screen:
            break
    return starts
