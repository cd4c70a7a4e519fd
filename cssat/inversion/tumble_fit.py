"""The tumbling search's refinement (:func:`cssat.inversion.tumble.estimate_tumbling`, steps 3–4):
Levenberg–Marquardt in the eight numbers of a :class:`~cssat.inversion.tumble_state.TumblingState`
with the EGI re-solved by NNLS at each step, the continuation from the first arc to every sample,
the solution's 1σ (Gauss–Newton and the EGI grid's bias) and its distinct alternatives."""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import numpy as np

from cssat._checks import float_param
from cssat.inversion.spin_errors import _refined, _separation_deg, _support, _turned, verdict_keys
from cssat.inversion.tumble_state import TumblingState, _TFit

log = logging.getLogger("cssat")


def _refine(fit: _TFit, x0: np.ndarray, alpha0: float, span_s: float, maxfev: int, t_ref: float,
            frame: str) -> tuple[float, np.ndarray, float]:
    """Levenberg–Marquardt (trust-region reflective) on the weighted residual, the EGI
    re-solved by NNLS at every step (variable projection); the moments as ``i₂ ∈ [½, 1]``
    and ``u ∈ [0, 1]``, ``i₁ = 1 − i₂ + u (2 i₂ − 1)``, so the rigid-body triangle is a box.
    From the state vector ``x0 (8,)`` (root ``alpha0``), the phases scaled to degrees over
    ``span_s`` seconds; at most ``maxfev`` evaluations. Returns ``(chi2, x (8,), alpha)``."""
    from scipy.optimize import least_squares  # heavy: scipy.optimize, only for _refine()

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


#: two refined minima of the first arc are one basin reached from two starts when their ``L`` lie
#: within this many degrees and both frequencies within :data:`SAME_CYCLES` turns over the arc
SAME_L_DEG = 10.0
SAME_CYCLES = 0.25


def _same_basin(x: np.ndarray, k: np.ndarray, span_s: float) -> bool:
    """Whether the states ``x``, ``k (8,)`` are one basin over ``span_s`` seconds: ``L`` within
    :data:`SAME_L_DEG`, both frequencies within :data:`SAME_CYCLES` turns over the span."""
    return (_separation_deg((float(x[5]), float(x[6])), (float(k[5]), float(k[6]))) < SAME_L_DEG
            and abs(x[2] - k[2]) * span_s < SAME_CYCLES and abs(x[3] - k[3]) * span_s < SAME_CYCLES)


def _distinct_minima(minima: list[tuple], n: int, arc_s: float) -> list[tuple]:
    """The minima to carry from the refined ``minima`` (``(chi2, x (8,), alpha)``, best first):
    the ``n`` best, and beside them the best of every other distinct basin until ``n`` basins
    are carried. A minimum whose ``L`` lies within :data:`SAME_L_DEG` of a better one's and whose
    frequencies ``f_ω``, ``f_φ`` both differ from its by less than :data:`SAME_CYCLES` turns over
    ``arc_s`` seconds (below the arc's resolution) is that basin again. Copies of one basin are
    kept among the ``n`` best (their continuations can part), but ``n`` copies of one basin
    would leave the others uncarried — a tumbler whose three best were one basin, the truth's
    fifth, was fitted at a mirror L 170° off. Best first; at most ``2n - 1``."""
    heads: list[int] = []  # the best minimum of each basin, best first
    for i, r in enumerate(minima):
        if not any(_same_basin(r[1], minima[h][1], arc_s) for h in heads):
            heads.append(i)
    return [minima[i] for i in sorted(set(range(min(n, len(minima)))) | set(heads[:n]))]


def _continuation(samples: tuple, cur: list[tuple], arc_s: float, growth: float, n_mid: int, mid_N: np.ndarray, brdf: Any,
                  max_fev: int, t_ref: float, frame: str, clock: float) -> list[tuple]:
    """The refined minima ``cur`` (``(chi2, x, alpha)``) carried from the first ``arc_s`` seconds
    to arcs ``growth`` times longer up to every sample of ``samples = (t, y, w, S, O)`` (``n_mid``
    samples of each arc, normals ``mid_N (K, 3)``): the phases stay coherent while the span grows."""
    t = samples[0]
    span = float(t[-1] - t[0])
    length = arc_s
    while length < span:
        length = min(length * float_param(growth, "growth", 1.0, open_lo=True), span)
        fit = _TFit.spread(samples, t <= t_ref + length, n_mid, mid_N, brdf)
        cur = sorted((_refine(fit, r[1], r[2], length, max_fev, t_ref, frame) for r in cur), key=lambda r: r[0])
        log.info("estimate_tumbling: arc %.0f s refined, %.1f s (best reduced chi2 %.3g)", length, time.perf_counter() - clock,
                 cur[0][0] / len(fit.t))
    return cur


#: the rescan's first stage: Levenberg–Marquardt steps from each phase start, and how many of
#: those starts are refined fully
REPHASE_FEV, REPHASE_KEEP = 10, 3


def _rephase(fit: _TFit, cur: list[tuple], n_t0: int, n_phi: int, max_fev: int, t_ref: float, frame: str) -> list[tuple]:
    """The continued minima ``cur`` (``(chi2, x (8,), alpha)`` on ``fit``: every sample's span,
    best first) and beside each the best minimum of its two phases searched again at that span,
    where that is lower: from ``n_t0 × n_phi`` starts — the polhode phase ``t₀`` on ``n_t0``
    steps of ``1/f_ω``, the precession phase ``φ₀`` on ``n_phi`` steps of a turn, the other six
    numbers the minimum's — :data:`REPHASE_FEV` steps of :func:`_refine`, the
    :data:`REPHASE_KEEP` best refined fully (``max_fev``). A minimum of the same basin
    (:func:`_same_basin`) as a better one of ``cur`` — a copy continued to the same place, whose
    phases the better one's scan covered — is not scanned again. Best first. The continuation
    carries the first arc's phases while its frequencies move (a tumbler's true side, carried
    19° off with P_φ 0.07 % off, was continued to the right periods
    but stopped 11° from its L; rescanned, it fitted below the mirror solution that was the
    answer). The rescanned minima are added, not swapped in: on this coarse fit a lower χ² can
    be a worse fit on the fine one, which decides."""
    span = float(fit.t[-1] - fit.t[0])
    out: list[tuple] = []
    for c, x, al in cur:
        if any(_same_basin(x, o[1], span) for o in out):  # a copy continued to the same place: scanned once
            out.append((c, x, al))
            continue
        starts = []
        for dt in np.arange(n_t0) / (n_t0 * x[2]):
            for dphi in np.arange(n_phi) * (360.0 / n_phi):
                x1 = x.copy()
                x1[4], x1[7] = x1[4] + dt, (x1[7] + dphi) % 360.0
                starts.append(_refine(fit, x1, al, span, REPHASE_FEV, t_ref, frame))
        starts.sort(key=lambda r: r[0])
        best = min((_refine(fit, r[1], r[2], span, max_fev, t_ref, frame) for r in starts[:REPHASE_KEEP]), key=lambda r: r[0])
        out.append((c, x, al))
        if best[0] < c:  # another minimum of the phases: carried beside the continued one (the fine fit decides)
            out.append(best)
    return sorted(out, key=lambda r: r[0])


def _best_motion(final: _TFit, cur: list[tuple], span: float, final_fev: int, t_ref: float,
                 frame: str) -> tuple[list[tuple], TumblingState]:
    """The refined minima ``cur`` (``(chi2, x, alpha)`` on ``final``, best first) kept where
    they are torque-free motions (a refinement can stop where no rigid body has its numbers) and
    the best one's state; where the best one's twin (:meth:`TumblingState.twin`: the body turned
    180° about its circulation axis — the same motion in space, whose EGI may sit better on the
    fixed grid of normals) fits better, the twin refined (or as it is, whichever is lower and a
    motion) replaces it. ``RuntimeError`` when no minimum is a motion."""
    keep = [(r, st) for r in cur for st in [TumblingState.from_vector(r[1], r[2], t_ref, frame)] if st is not None]
    if not keep:
        raise RuntimeError("estimate_tumbling: no refined minimum is a torque-free motion (the refinements ended where "
                           "no rigid body has those numbers): widen the search (n_starts, n_refine) or give periods_s")
    cur = [r for r, _ in keep]
    (chi2, _, _), state = keep[0]
    twin = state.twin()
    if twin is not None:
        _, c_twin = final.solve(twin)
        if c_twin < chi2:
            refined = _refine(final, twin.vector(), twin.alpha, span, final_fev, t_ref, frame)
            motions = [(r, st) for r in (refined, (float(c_twin), twin.vector(), twin.alpha))  # kept only as a motion
                       for st in [TumblingState.from_vector(r[1], r[2], t_ref, frame)] if st is not None]
            if motions:
                cur[0], state = min(motions, key=lambda m: m[0][0])
            log.info("estimate_tumbling: the twin motion fits better (chi2 %.6g -> %.6g)", chi2, cur[0][0])
    return cur, state


def _tumble_jacobian(fit: _TFit, state: TumblingState, x: np.ndarray, a: np.ndarray, sup: np.ndarray,
                     span: float) -> np.ndarray:
    """The whitened Jacobian ``(T, 8 + S)`` of the EGI model on ``fit``'s samples in the eight
    numbers ``x (8,)`` (central differences) and the support's ``S`` areas of ``a (K,)``."""
    t_ref, frame = state.t_ref_s, state.frame
    A = fit.matrix(state) * fit.w[:, None]
    h = np.array([1e-4, 1e-4, 1e-4 / (360 * span), 1e-4 / (360 * span), 1e-4 / (360 * x[2]), 1e-3, 1e-3, 1e-3])
    cols = []
    for i in range(8):
        hi, lo = x.copy(), x.copy()
        hi[i] += h[i]
        lo[i] -= h[i]
        s_hi, s_lo = (TumblingState.from_vector(v, state.alpha, t_ref, frame) for v in (hi, lo))
        if s_hi is None or s_lo is None:
            cols.append(np.zeros(len(fit.t)))
            continue
        cols.append((fit.matrix(s_hi) - fit.matrix(s_lo)) @ a * fit.w / (2 * h[i]))
    return np.column_stack(cols + [A[:, sup]])


def _check_tumble(final: _TFit, state: TumblingState, x: np.ndarray, a: np.ndarray, sup: np.ndarray, chi2: float,
                  span: float, sig: Any, heldout: Any) -> dict[str, Any]:
    """``estimate_tumbling``'s verdict on ``state`` with the EGI ``a`` (support ``sup``) fitted on
    ``final``: the ``heldout = (times_s, flux, sun, obs, sigma)`` data predicted and tested against
    the noise (:func:`~cssat.inversion.spin_errors.heldout_threshold`, :func:`~cssat.inversion.spin_errors.judge`),
    else the fitted samples' χ²: the keys ``verdict``, ``verdict_why``, ``heldout_chi2``,
    ``heldout_n``, ``heldout_threshold``."""
    from cssat.inversion.spin import _check_heldout  # heavy: cssat.inversion.spin imports torch

    J_fit = _tumble_jacobian(final, state, x, a, sup, span)
    held = None
    if heldout is not None and sig is not None:
        th, yh, Sh, Oh, wh = _check_heldout(heldout)
        fit_h = _TFit(th, yh, wh, Sh, Oh, final.N, final.brdf)
        held = ((yh - fit_h.matrix(state) @ a) * wh, _tumble_jacobian(fit_h, state, x, a, sup, span))
    return verdict_keys(J_fit, len(final.t), chi2, sig is not None, held, "the angular momentum's direction")


def _formal_errors(final: _TFit, state: TumblingState, x: np.ndarray, a: np.ndarray, chi2: float, span: float,
                   weighted: bool) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Gauss–Newton on the eight numbers ``x (8,)`` and the support's areas of the EGI ``a (K,)``:
    the 1σ ``(8,)`` (scaled by the reduced χ² — when above 1 if ``weighted``), the reduced χ², the
    support ``(K,)`` (bool) and ``L``'s covariance ``(2, 2)`` in its tangent plane (east, north;
    degrees²)."""
    sup = _support(a)
    J = _tumble_jacobian(final, state, x, a, sup, span)
    dof = max(len(final.t) - J.shape[1], 1)
    red = chi2 / dof
    cov = np.linalg.pinv(J.T @ J)[:8, :8] * (max(red, 1.0) if weighted else red)
    d = np.diag([math.cos(math.radians(state.lat_deg)), 1.0])  # (λ, β) → (east, north)
    return np.sqrt(np.clip(np.diag(cov), 0, None)), red, sup, d @ cov[5:7, 5:7] @ d


def _errors(final: _TFit, state: TumblingState, x: np.ndarray, a: np.ndarray, chi2: float, span: float, weighted: bool,
            final_fev: int, grids: int = 1, bootstrap: int = 0) -> tuple[dict[str, float], float, np.ndarray]:
    """The solution's 1σ (:class:`~cssat.inversion.tumble.TumblingSolution`'s ``errors``): the
    noise's part in quadrature with the shift of the fit on ``final``'s grid of normals turned at
    random — with the bootstrap, on that grid refined (:func:`~cssat.inversion.spin._refined`:
    joined with its turned copy; without it, the turned grid's shift also carries part of the
    valley the formal 1σ misses) — the root mean square of the shifts over ``grids`` such grids
    (seeds 0, 1, …; one shift alone is a single draw of the bias, Rayleigh-distributed in ``L``,
    often far below its spread); with the reduced χ² and the EGI's support ``(K,)``.

    The noise's part: Gauss–Newton's formal 1σ (:func:`_formal_errors`), or with ``bootstrap =
    B > 0`` a warm-started parametric bootstrap — ``B`` light curves drawn from the fitted model
    with the stated noise (× the reduced χ² where above 1; a fixed seed), each refitted from the
    solution (``final_fev``, the EGI re-solved by NNLS at every step) on the same grid, the root
    mean square of their shifts. The bootstrap measures the χ² valley as the refit sees it: where
    the NNLS support changes along it, the valley is far flatter than the curvature with the
    support held (the formal 1σ of ``L`` in class is ~10× too small).

    ``L``'s 1σ ellipse (``L_major_deg``, ``L_minor_deg``, ``L_pa_deg``; :mod:`cssat.inversion.ellipse`):
    the same refits' offsets in ``L``'s tangent plane — the replicates' second moments (or the
    formal covariance) plus the grids' — with ``L_dof`` the replicates it was estimated from (0:
    the formal one). ``L_major_deg² + L_minor_deg²`` is ``L_err_deg²`` to the tangent plane's
    accuracy; the ellipse keeps the valley's shape, which the radial 1σ's circle loses."""
    from cssat.inversion.ellipse import ellipse_of_cov, tangent_offset  # local: the ellipse's own module

    e, red, sup, cov_L = _formal_errors(final, state, x, a, chi2, span, weighted)
    formal_L = float(np.hypot(e[6], math.cos(math.radians(state.lat_deg)) * e[5]))
    centre = (state.lon_deg, state.lat_deg)

    def refit(fit: _TFit) -> tuple[np.ndarray, float, np.ndarray]:  # the shift, L's separation and its (east, north)
        _, xg, _ = _refine(fit, x, state.alpha, span, final_fev, state.t_ref_s, state.frame)
        to = (float(xg[5]), float(xg[6]))
        return xg - x, _separation_deg(centre, to), tangent_offset(centre, to)

    # the EGI grid's bias (it dominates at high SNR): the fit again on a turned grid, or with the bootstrap the grid refined
    grid = [refit(_TFit(final.t, final.y, final.w, final.S, final.O, (_refined if bootstrap else _turned)(final.N, g), final.brdf))
            for g in range(grids)]
    shift = np.sqrt(np.mean(np.square([d for d, _, _ in grid]), axis=0))
    grid_L = float(np.sqrt(np.mean(np.square([s_ for _, s_, _ in grid]))))
    noise, noise_L = e, formal_L
    out: dict[str, float] = {}
    if bootstrap:
        rng = np.random.default_rng(0)
        model = final.matrix(state) @ a
        sd = np.sqrt(max(red, 1.0) if weighted else red) / final.w
        boot = [refit(_TFit(final.t, model + sd * rng.standard_normal(len(model)), final.w, final.S, final.O, final.N,
                            final.brdf)) for _ in range(bootstrap)]
        noise = np.sqrt(np.mean(np.square([d for d, _, _ in boot]), axis=0))
        noise_L = float(np.sqrt(np.mean(np.square([s_ for _, s_, _ in boot]))))
        out["bootstrap_L_err_deg"] = noise_L
        cov_L = _moments(boot)
    major, minor, pa = ellipse_of_cov(cov_L + _moments(grid))
    errors = {"i1": np.hypot(noise[0], shift[0]), "i2": np.hypot(noise[1], shift[1]),
              "P_omega_s": np.hypot(noise[2], shift[2]) / x[2] ** 2, "P_phi_s": np.hypot(noise[3], shift[3]) / x[3] ** 2,
              "t0_s": np.hypot(noise[4], shift[4]), "L_lon_deg": np.hypot(noise[5], shift[5]),
              "L_lat_deg": np.hypot(noise[6], shift[6]), "phi0_deg": np.hypot(noise[7], shift[7]),
              "L_err_deg": float(np.hypot(noise_L, grid_L)), "formal_L_err_deg": formal_L, "grid_L_shift_deg": grid_L,
              "L_major_deg": major, "L_minor_deg": minor, "L_pa_deg": pa, "L_dof": float(bootstrap), **out}
    return {k: float(v) for k, v in errors.items()}, red, sup


def _moments(refits: list[tuple]) -> np.ndarray:
    """``L``'s second moments ``(2, 2)`` (degrees²) over the refits' ``(east, north)`` offsets."""
    return np.mean([np.outer(o, o) for _, _, o in refits], axis=0)


def _alternatives(others: list[tuple], x: np.ndarray, chi2: float, red: float, state: TumblingState) -> list[dict[str, Any]]:
    """The other refined minima ``others`` (``(chi2, x, alpha)``, best first) that are not the
    solution ``x (8,)`` or an earlier alternative reached from another start (``L`` within 1°,
    both frequencies within 1e-4): their ``L``, periods, moments, ``chi2``, ``delta_chi2`` in
    units of the reduced χ² ``red`` and ``separation_deg`` from the solution's ``L``."""
    alts: list[dict[str, Any]] = []
    for c2, x2, _ in others:
        if any(_separation_deg((float(x2[5]), float(x2[6])), (float(v[5]), float(v[6]))) < 1.0
               and abs(x2[2] / v[2] - 1) < 1e-4 and abs(x2[3] / v[3] - 1) < 1e-4
               for v in [x] + [np.array([0, 0, 1 / q["P_omega_s"], 1 / q["P_phi_s"], 0, q["L_lon_deg"], q["L_lat_deg"], 0])
                               for q in alts]):
            continue  # the same minimum reached from another start
        alts.append({"L_lon_deg": float(x2[5]), "L_lat_deg": float(x2[6]), "P_omega_s": float(1 / x2[2]),
                     "P_phi_s": float(1 / x2[3]), "i1": float(x2[0]), "i2": float(x2[1]), "chi2": float(c2),
                     "delta_chi2": float((c2 - chi2) / max(red, 1e-300)),
                     "separation_deg": _separation_deg((state.lon_deg, state.lat_deg), (float(x2[5]), float(x2[6])))})
    return alts
