"""The spin state of a tumbling object — a torque-free rigid body in non-principal-axis rotation
— and its EGI from a light curve (Kaasalainen 2001, Pravec et al. 2005):
:func:`estimate_tumbling` and its :class:`~cssat.inversion.results.TumblingSolution` (a read-only
mapping of its keys with attributes).

The state, its motion and its light curve's EGI fit are :mod:`cssat.inversion.tumble_state`'s
(:class:`TumblingState`, :func:`tumbling_rates`, :func:`torque_free_invariants`, re-exported
here); the search's frequency pairs, coarse grid and starts :mod:`cssat.inversion.tumble_search`'s;
the refinement, continuation and 1σ :mod:`cssat.inversion.tumble_fit`'s.
"""

from __future__ import annotations

import inspect
import logging
import time
from typing import Any

import numpy as np

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param
from cssat.inversion.period_verdict import MODEL_FITS_CHI2
from cssat.inversion.results import TumblingSolution
from cssat.inversion.spin_errors import rivals
from cssat.inversion.tumble_fit import (_alternatives, _best_motion, _check_tumble, _continuation, _distinct_minima, _errors,
                                        _refine, _rephase, _support)
from cssat.inversion.tumble_search import INERTIA_GRID, _CoarseGrid, _distinct_starts, _given_pairs, _lattice_pairs
from cssat.inversion.tumble_state import TumblingState, _TFit, torque_free_invariants, tumbling_rates

__all__ = ["TumblingState", "TumblingSolution", "tumbling_rates", "estimate_tumbling", "check_tumbling_options",
           "torque_free_invariants"]

log = logging.getLogger("cssat")


def estimate_tumbling(times_s: Any, flux: Any, sun: Any, obs: Any, *, sigma: Any = None, brdf: Any = None,
                      frame: str = "ecliptic", periods_s: Any = None, min_period_s: float = 60.0,
                      max_period_s: float = 3000.0, arc_s: float = 3600.0, inertia_grid: Any = INERTIA_GRID,
                      max_ratio: float = 8.0, n_poles: int = 40, n_t0: int = 6, n_phi: int = 8, n_prerank: int = 16,
                      n_pairs: int = 3, screen_moments: int = 6, screen_poles: int = 20, n_screen: int = 24, n_starts: int = 8,
                      n_refine: int = 4, coarse_normals: int = 64, coarse_samples: int = 160, mid_normals: int = 150,
                      mid_samples: int = 400, n_normals: int = 600, max_samples: int = 1200, growth: float = 3.0,
                      max_fev: int = 200, screen_fev: int = 30, final_fev: int = 60, error_grids: int = 1, bootstrap: int = 20,
                      rephase: bool = True, heldout: Any = None) -> TumblingSolution:
    """The torque-free tumbling state (:class:`TumblingState`) and EGI of an object from its light
    curve ``flux (T,)`` at ``times_s (T,)``, the Sun and observer directions ``sun``, ``obs (T, 3)``
    (inertial unit vectors from the object), ``sigma`` its 1σ, ``brdf`` (default Lambert): the
    tumbling inversion of Kaasalainen (2001) with the EGI model of
    :func:`~cssat.inversion.egi_operator` (no shadowing), scored by the NNLS EGI fit's χ².

    1. The light curve's frequency lattice: ``periods_s = (P_ω, P_φ)`` given, or the two
       fundamental frequencies of :func:`~cssat.inversion.estimate_tumbling_periods` on the first
       ``arc_s`` seconds (over one short arc the geometry barely changes, so the 2-D Fourier
       series holds; its ``f_φ`` is the synodic one). Which lattice vectors are ``f_ω`` and
       ``f_φ`` is not known: the pairs of :func:`~cssat.inversion.tumble_search._candidates`
       (``f_ω`` a primitive vector with coefficients ≤ 1, ``f_φ = `` a complement shifted by whole
       ``f_ω``, the ratio within what the inertia grid's motions reach and ``max_ratio``, both
       periods above ``min_period_s``)
       are ranked by the χ² of the 2-D Fourier series of order 3 in their basis (in the physical
       basis the light curve's power sits at low orders: 2f_φ, 2f_φ ± f_ω, …) and the
       ``n_prerank`` best kept.
    2. Coarse search on that arc (``coarse_samples`` samples, ``coarse_normals`` normals): when
       there are more than ``n_pairs`` pairs, each is first scored on ``screen_moments`` moments
       of the grid spread over it and ``screen_poles`` directions, and the ``n_pairs`` best kept;
       then for each moment of ``inertia_grid`` (default :data:`INERTIA_GRID`, 27 points) and
       each pair, every ``α``
       with that frequency ratio, and a grid of ``n_poles`` directions of ``L`` × ``n_t0``
       polhode phases × ``n_phi`` precession phases, each scored by NNLS.
    3. The best start of each moment and direction (two distinct directions per moment, at most
       ``n_screen``) refined by a few (``screen_fev``) steps of Levenberg–Marquardt (trust-region
       reflective, the EGI re-solved by NNLS at each step: variable projection) in all eight
       numbers ``(i₁, i₂, f_ω, f_φ, t₀, λ, β, φ₀)`` on ``mid_samples`` samples and
       ``mid_normals`` normals; the ``n_starts`` best refined fully (``max_fev``); the
       ``n_refine`` best, and the best of each other basin until ``n_refine`` basins are carried
       (:func:`~cssat.inversion.tumble_fit._distinct_minima`), carried to arcs
       ``growth`` times longer (a continuation in time: the phases stay coherent while the span
       grows) up to every sample; with ``rephase`` (default) each one's two phases searched again
       at that span from ``n_t0 × n_phi`` starts, the best added beside it where lower
       (:func:`~cssat.inversion.tumble_fit._rephase`: the continuation keeps the first arc's
       phases while the frequencies move); then each fitted on ``max_samples`` samples and
       ``n_normals`` normals (``final_fev``). Every motion has a twin — the body
       turned 180° about its circulation axis, half a period of ``ω`` on
       (:meth:`TumblingState.twin`) — that is the same motion in space but puts the EGI on the
       grid turned; the twin is refined too and kept when it fits better.
    4. 1σ by Gauss–Newton and the EGI grid's bias (:class:`TumblingSolution`): the root mean
       square of the solution's shifts when refined again (``final_fev``) on ``error_grids``
       grids of normals, in quadrature with — when the verdict (step 5) is reliable and
       ``bootstrap = B > 0`` (default 20) — the RMS shift of ``B`` refits of light curves drawn
       from the fitted model at the stated noise (a warm-started parametric bootstrap, a fixed
       seed; ``B`` more refinements; the grids then the fine one refined, joined with a copy
       turned at random), else the formal 1σ (it holds the NNLS support fixed and misses the
       flat valley along ``L``: ~4–30× too small in class, BENCHMARKS.md "Coverage of the pole
       and L"; the grids then turned at random, whose shift carries part of that valley).
    5. The verdict (``verdict``, ``verdict_why``, as :func:`~cssat.inversion.estimate_spin`'s
       step 6): ``heldout = (times_s, flux, sun, obs, sigma)`` predicted and its χ² tested against
       what a right model reaches at the noise (the ``1 − 10⁻³`` quantile of
       :func:`~cssat.inversion.spin_errors.heldout_threshold`); without it the fitted samples'
       χ²; without ``sigma`` unreliable. When unreliable every 1σ in ``errors`` is NaN — of ``L``
       (``L_err_deg``, ``L_lon_deg``, ``L_lat_deg``, ``formal_L_err_deg``, ``grid_L_shift_deg``,
       ``bootstrap_L_err_deg``) and of the moments, periods and phases too: on 22 unreliable
       in-class tumblers (seeds 700–729) the periods' 1σ of 0.004–4 s missed wrong periods by up
       to 5e5σ (181 s for 2090 s).

    Assumptions: torque-free rigid rotation (no damping, no torques) over the span, a convex body
    (no self-shadowing), one BRDF shape, samples dense enough to resolve the light curve's
    harmonics (seconds, not minutes: a 30 s cadence aliases a 200 s tumbler's glints).
    """
    from cssat.inversion.egi import fibonacci_sphere  # heavy: cssat.inversion.egi imports torch
    from cssat.inversion.spin import _check_light_curve  # heavy: cssat.inversion.spin imports torch

    clock = time.perf_counter()
    frame = choice_param(frame, "frame", ("ecliptic", "equatorial"))
    options = _option_names()  # the signature read once, not once a local
    check_tumbling_options(**{k: v for k, v in locals().items() if k in options})  # the options: before any work
    t, y, S, O, w, sig = _check_light_curve(times_s, flux, sun, obs, sigma, brdf)
    if heldout is not None:  # checked before any work (step 5 reads it)
        from cssat.inversion.spin import _check_heldout  # heavy: cssat.inversion.spin imports the EGI operator (torch)

        _check_heldout(heldout)
    samples = (t, y, w, S, O)
    t_ref = float(t[0])
    span = float(t[-1] - t[0])
    arc_s = float_param(arc_s, "arc_s", 0.0, open_lo=True)
    grid_I = _check_inertia_grid(inertia_grid)
    error_grids = int_param(error_grids, "error_grids", 1, 64)  # step 4's, refused before any work
    bootstrap = int_param(bootstrap, "bootstrap", 0, 1000)
    rephase = bool_param(rephase, "rephase")
    n_poles, n_t0, n_phi, n_starts, n_refine = (int_param(v, k, 1) for v, k in (
        (n_poles, "n_poles"), (n_t0, "n_t0"), (n_phi, "n_phi"), (n_starts, "n_starts"), (n_refine, "n_refine")))
    arc = t <= t_ref + arc_s
    if arc.sum() < 16:
        raise FieldError("arc_s", f"the first arc ({arc_s:g} s) holds {int(arc.sum())} samples: at least 16 are needed")
    # 1. the lattice
    if periods_s is not None:
        lattice, pairs = _given_pairs(periods_s)
    else:
        lattice, pairs = _lattice_pairs(t[arc], y[arc], w[arc], None if sig is None else sig[arc], t_ref, grid_I, min_period_s,
                                        max_period_s, max_ratio, n_prerank)
    # 2. the coarse search on the first arc
    coarse = _TFit.spread(samples, arc, int_param(coarse_samples, "coarse_samples", 16),
                          fibonacci_sphere(int_param(coarse_normals, "coarse_normals", 8)).numpy(), brdf)
    grid = _CoarseGrid(coarse, n_t0, n_phi, t_ref, frame)
    if len(pairs) > n_pairs:  # the lattice's pairs screened on four moments and half the directions
        pairs = grid.screen(grid_I, pairs, n_pairs, screen_moments, screen_poles, clock)
    table = grid.scan(grid_I, pairs, n_poles)
    if not table:
        raise FieldError("periods_s", "no torque-free motion of the inertia grid has these frequencies: give periods_s "
                                      "or widen inertia_grid / max_ratio")
    table.sort(key=lambda r: r[0])
    log.info("estimate_tumbling: %d frequency pairs, coarse search %.1f s", len(pairs), time.perf_counter() - clock)
    # 3. the distinct starts refined on the first arc, then continued to longer arcs and every sample
    starts = _distinct_starts(table, n_poles, n_screen)
    mid_N = fibonacci_sphere(int_param(mid_normals, "mid_normals", 16)).numpy()
    fine_N = fibonacci_sphere(int_param(n_normals, "n_normals", 16)).numpy()
    n_mid = int_param(mid_samples, "mid_samples", 16)
    arc_fit = _TFit.spread(samples, arc, n_mid, mid_N, brdf)
    screened = sorted((_refine(arc_fit, q[1], q[2], arc_s, screen_fev, t_ref, frame) for q in starts), key=lambda r: r[0])
    cur = _distinct_minima(sorted((_refine(arc_fit, r[1], r[2], arc_s, max_fev, t_ref, frame) for r in screened[:n_starts]),
                                  key=lambda r: r[0]), n_refine, arc_s)
    log.info("estimate_tumbling: %d starts refined on the first arc, %.1f s (best reduced chi2 %.3g)", len(starts),
             time.perf_counter() - clock, cur[0][0] / len(arc_fit.t))
    cur = _continuation(samples, cur, arc_s, growth, n_mid, mid_N, brdf, max_fev, t_ref, frame, clock)
    if rephase:  # the phases searched again at the full span (the continuation kept the first arc's)
        cur = _rephase(_TFit.spread(samples, np.ones(len(t), bool), n_mid, mid_N, brdf), cur, n_t0, n_phi, max_fev, t_ref, frame)
        log.info("estimate_tumbling: phases rescanned, %.1f s (best reduced chi2 %.3g)", time.perf_counter() - clock,
                 cur[0][0] / min(n_mid, len(t)))
    final = _TFit.spread(samples, np.ones(len(t), bool), max_samples, fine_N, brdf)
    cur = sorted((_refine(final, r[1], r[2], span, final_fev, t_ref, frame) for r in cur), key=lambda r: r[0])
    log.info("estimate_tumbling: final fit, %.1f s", time.perf_counter() - clock)
    cur, state = _best_motion(final, cur, span, final_fev, t_ref, frame)
    chi2, x, alpha = cur[0]
    state.lon_deg = float((state.lon_deg + 180.0) % 360.0 - 180.0)
    state.phi0_deg = float(state.phi0_deg % 360.0)
    a, chi2 = final.solve(state)
    # 5. the verdict: the model tested on held-out data against the noise; no 1σ of L when unreliable
    check = _check_tumble(final, state, x, a, _support(a), chi2, span, sig, heldout)
    # 4. 1σ: the bootstrap (when reliable) or Gauss–Newton, and the EGI grid's bias
    errors, red, sup = _errors(final, state, x, a, chi2, span, sig is not None, final_fev, error_grids,
                               bootstrap if check["verdict"] == "reliable" else 0)
    if check["verdict"] == "unreliable":  # every 1σ withheld: an unreliable tumbler's periods were 1e5σ off
        errors = {k: float("nan") for k in errors}
    alts = _alternatives(cur[1:], x, chi2, red, state)
    full = _TFit(t, y, w, S, O, fine_N, brdf)
    resid = y - full.matrix(state) @ a
    from cssat.inversion.egi import split_lobes  # heavy: cssat.inversion.egi imports torch

    normals, areas, lobe_areas, _ = split_lobes(a, fine_N, brdf)
    return TumblingSolution(state=state, normals=normals, areas=areas, lobe_areas=lobe_areas, chi2=float(chi2),
                            reduced_chi2=float(red), model_fits=bool(red <= MODEL_FITS_CHI2) if sig is not None else None,
                            residual=resid, errors=errors, lattice_hz=np.asarray(lattice),
                            frequency_pairs=[(1 / fw, 1 / fp) for fw, fp in pairs], alternatives=alts,
                            ambiguous=bool(rivals(alts)), brdf=brdf,
                            **check,
                            coarse=[{"chi2": float(r[0]), "P_omega_s": float(1 / r[1][2]), "P_phi_s": float(1 / r[1][3]),
                                     "i1": float(r[1][0]), "i2": float(r[1][1])} for r in table[:20]])


def check_tumbling_options(**options: Any) -> None:
    """Refuse, before any work, a keyword option of :func:`estimate_tumbling` out of its range
    or unknown (a :class:`~cssat._checks.FieldError` naming it): counts ``>= 1`` (grids and
    samples ``>= 16``, coarse normals ``>= 8``), periods and the arc ``> 0``, ``max_period_s >
    min_period_s``, ``max_ratio >= 1``, ``growth > 1``, ``inertia_grid`` in the rigid-body triangle."""
    allowed = _option_names()
    for k in options:
        if k not in allowed:
            raise FieldError(k, f"unknown option; allowed: {', '.join(allowed)}")
    o = {k: p.default for k, p in inspect.signature(estimate_tumbling).parameters.items() if k in allowed}
    o.update(options)
    for k in ("n_poles", "n_t0", "n_phi", "n_prerank", "n_pairs", "screen_moments", "screen_poles", "n_screen", "n_starts",
              "n_refine", "max_fev", "screen_fev", "final_fev"):
        int_param(o[k], k, 1, 10**7)
    int_param(o["error_grids"], "error_grids", 1, 64)
    int_param(o["bootstrap"], "bootstrap", 0, 1000)
    bool_param(o["rephase"], "rephase")
    int_param(o["coarse_normals"], "coarse_normals", 8, 10**6)
    for k in ("coarse_samples", "mid_normals", "mid_samples", "n_normals", "max_samples"):
        int_param(o[k], k, 16, 10**7)
    float_param(o["arc_s"], "arc_s", 0.0, open_lo=True)
    lo = float_param(o["min_period_s"], "min_period_s", 0.0, open_lo=True)
    float_param(o["max_period_s"], "max_period_s", lo, open_lo=True)
    float_param(o["max_ratio"], "max_ratio", 1.0)
    float_param(o["growth"], "growth", 1.0, open_lo=True)
    if o["periods_s"] is not None:
        try:
            _given_pairs(o["periods_s"])
        except (TypeError, ValueError) as err:
            raise FieldError("periods_s", f"expected (P_omega, P_phi) in seconds, got {o['periods_s']!r}") from err
    _check_inertia_grid(o["inertia_grid"])


def _option_names() -> list[str]:
    """:func:`estimate_tumbling`'s keyword options: its keyword-only arguments but the data
    (``sigma``, ``heldout``) and the model's frame and BRDF, which are checked where they are read."""
    return [k for k, p in inspect.signature(estimate_tumbling).parameters.items()
            if p.kind is p.KEYWORD_ONLY and k not in ("sigma", "brdf", "frame", "heldout")]


def _check_inertia_grid(inertia_grid: Any) -> np.ndarray:
    """The moments ``(M, 2)`` of ``inertia_grid``, each in the rigid-body triangle."""
    try:
        grid_I = np.asarray(inertia_grid, dtype=np.float64).reshape(-1, 2)
    except (TypeError, ValueError) as err:
        raise FieldError("inertia_grid", f"expected pairs (I1/I3, I2/I3), got {inertia_grid!r}") from err
    if not len(grid_I):
        raise FieldError("inertia_grid", "expected at least one pair (I1/I3, I2/I3), got none")
    if not np.all((grid_I[:, 0] > 0) & (grid_I[:, 0] <= grid_I[:, 1]) & (grid_I[:, 1] <= 1) & (grid_I.sum(1) >= 1)):
        raise FieldError("inertia_grid", "each (I1/I3, I2/I3) needs 0 < I1/I3 <= I2/I3 <= 1 <= I1/I3 + I2/I3")
    return grid_I
