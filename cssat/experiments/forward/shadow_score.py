"""The occultation's inversion, scores and files (``cssat experiment=occultation``; the model:
:mod:`cssat.experiments.forward.shadow`, the event: :mod:`cssat.experiments.forward.shadow_measure`). Each
function takes the stages' typed results: the plan (:class:`~cssat.experiments.forward.shadow.ShadowPlan`), what was
measured (:class:`~cssat.experiments.forward.shadow_measure.ShadowMeasured`) and what was solved (:class:`ShadowSolved`).

``solve``: :func:`~cssat.occultation.invert_event` on the recorded series with the inversion's own
band quadrature (``invert.n_wavelengths``), its assumed limb darkening and a grid of
``invert.n_diameters`` star diameters from 0 to ``invert.diameter_max_mas`` (the stated prior);
``event.oracle: true`` hands it the true offsets, speed, gains, diameter and limb darkening.
``invert.prior``: ``pixels`` (TV on the pixels), ``shapes`` (a union of superellipses, always) or
``auto`` — the telescopes split into two folds, each prior fitted on one and scored by the χ² of
the other (a held-out test, with power against a shape model that does not fit), the lower kept.

``score``: the reconstruction resampled onto the truth's finer grid where the fit placed it
(``iou_placed``) and after the best whole- and quarter-pixel shift (``iou``, the headline:
:func:`~cssat.occultation.registered_iou`); the linear route's (``iou_linear``) and the
geometric shadow's (``iou_geometric``); the silhouette centroid's time and path offsets against
the truth's in units of their reported 1σ; the star's diameter, the speed's error, the gains; the
edge width and feature contrast on the registered reconstruction; the photon budget.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from cssat.experiments.context import Run, one_thread
from cssat.experiments.files import write_npz
from cssat.experiments.forward.shadow_measure import ShadowMeasured
from cssat.occultation import (choose_prior, edge_width, event_geometry, feature_contrast, invert_event, iou, mask_centroid,
                               registered_iou, resample_mask)
from cssat.plots import save_figure
from cssat.plots.occultation import occultation_figures

if TYPE_CHECKING:
    from cssat.experiments.forward.shadow import ShadowPlan

__all__ = ["ShadowSolved", "solve_event", "score_event", "write_event", "reconstruction_images"]

log = logging.getLogger("cssat")


@dataclass
class ShadowSolved:
    """What the shadow model's ``solve`` stage hands on; ``P`` = the inversion's grid
    (:attr:`~cssat.models.shadow.config.ShadowSettings.size_inv` pixels a side)."""

    info: dict[str, Any]  #: :func:`~cssat.occultation.invert_event`'s report (the nuisances, their 1σ, the χ²)
    linear: Optional[np.ndarray]  #: ``(P, P)`` the linear route's reconstruction (None: ``invert.init: empty``)
    pixels_mask: np.ndarray  #: ``(P, P)`` the pixel prior's reconstruction
    mask: np.ndarray  #: ``(P, P)`` the reconstruction kept (the prior used)
    used: str  #: the prior used: pixels | shapes
    shapes: Any  #: the shape prior's parameters (None: not fitted)
    candidates: Any  #: the shape candidates' masks (None: not fitted)
    geometry: tuple  #: :func:`~cssat.occultation.event_geometry`'s tuple at the fitted nuisances
    kernel: Any  #: its smoothing kernel
    metrics: dict[str, Any]  #: the solve's metrics (the linear solver, the prior's choice, ``prior_used``)


def solve_event(p: ShadowPlan, meas: ShadowMeasured, run: Run) -> ShadowSolved:
    """The silhouette and the nuisances (:func:`~cssat.occultation.invert_event`), then the prior."""
    s, g, r = p.settings, meas.geometry, meas.record
    ev, inv, size_inv, pixel, D, t_exp = r.event, s.invert, s.size_inv, s.silhouette.pixel_m, s.array.aperture_m, s.array.exposure_s
    mas_m = g.mas_m
    known = {}
    if s.event.oracle:
        known = {"offset_m": ev.s_true, "speed_error": ev.eps_true, "gains": r.gains_true,
                 "diameter_m": s.star.diameter_mas * mas_m}
    limb = s.star.limb_darkening if s.event.oracle else inv.limb_darkening
    # the silhouette's fits on one thread whatever ``threads``: the same answer at every thread count
    with run.stage("invert"), one_thread():
        mask, info = invert_event(r.y.numpy(), r.sig.numpy(), (size_inv, size_inv), pixel, g.lams_inv, g.z, r.pos, g.v, r.times,
                                  weights=g.wts_inv, aperture_m=D, exposure_s=t_exp, limb_darkening=limb,
                                  diameters_m=np.linspace(0.0, inv.diameter_max_mas, inv.n_diameters) * mas_m, known=known,
                                  solver=p.solver, tv=inv.tv, iters=inv.iters, rounds=inv.rounds, ground=s.silhouette.ground,
                                  seed=run.seed)
    metrics: dict[str, Any] = {}
    if p.solver is not None:
        metrics["solver_linear"] = getattr(p.solver, "name", type(p.solver).__name__)
    geo, kernel = event_geometry(r.y.numpy(), r.sig.numpy(), (size_inv, size_inv), pixel, g.lams_inv, g.z, r.pos, g.v, r.times,
                                 offset_m=info["grid_centre_m"], gains=info["gains"], speed_error=info["speed_error"],
                                 diameter_m=info["diameter_m"], aperture_m=D, exposure_s=t_exp, limb_darkening=limb)
    pixels_mask, used, shapes, candidates = mask, "pixels", None, None
    if inv.prior != "pixels":
        with run.stage("prior"), one_thread():
            ms, choice = choose_prior(*geo, init_mask=mask, prior=inv.prior, kernel=kernel, weights=g.wts_inv,
                                      ground=s.silhouette.ground, tv=inv.tv, iters=inv.iters, shape_iters=inv.shape_iters,
                                      seed=run.seed)
            metrics.update(choice.metrics())
            mask, used, shapes, candidates = ms, choice.used, choice["params"], choice["candidate_masks"]
    metrics["prior_used"] = used
    return ShadowSolved(info, info["linear"], pixels_mask, mask, used, shapes, candidates, geo, kernel, metrics)


def _offsets(p: ShadowPlan, meas: ShadowMeasured, solved: ShadowSolved) -> dict[str, Any]:
    """The silhouette centroid's time and path offsets, estimated against true, with their 1σ."""
    g, ev, info = meas.geometry, meas.record.event, solved.info
    u, speed, across, gains_true, diam = g.v / g.speed, g.speed, ev.across, meas.record.gains_true, p.settings.star.diameter_mas
    c_true, _ = mask_centroid(meas.truth.truth, meas.truth.pixel_t)
    true = ev.s_true + c_true
    est, cov = info["offset_m"], info["offset_cov"]
    t_true = -float(true @ u) / (speed * (1 + ev.eps_true))
    t_est = -float(est @ u) / (speed * (1 + info["speed_error"]))
    t_sig = math.sqrt(max(float(u @ cov @ u), 0.0)) / speed
    p_true, p_est = float(true @ across), float(est @ across)
    p_sig = math.sqrt(max(float(across @ cov @ across), 0.0))
    mas_m = g.mas_m
    d_est, d_sig = info["diameter_m"] / mas_m, info["diameter_sigma_m"] / mas_m
    g_err = info["gains"] - gains_true

    def sig(err, s):  # None where the quantity was handed over (σ = 0)
        return float(err / s) if s > 0 else None

    return {"time_offset_true_s": t_true, "time_offset_s": t_est, "time_offset_sigma_s": t_sig,
            "time_offset_error_sigmas": sig(t_est - t_true, t_sig),
            "path_offset_true_m": p_true, "path_offset_m": p_est, "path_offset_sigma_m": p_sig,
            "path_offset_error_sigmas": sig(p_est - p_true, p_sig),
            "centroid_sigma_m": [float(x) for x in info["centroid_sigma_m"]], "gap_sigma_m": info["gap_sigma_m"],
            "speed_error_true": ev.eps_true, "speed_error": info["speed_error"], "speed_error_sigma": info["speed_error_sigma"],
            "star_diameter_true_mas": diam, "star_diameter_mas": d_est, "star_diameter_sigma_mas": d_sig,
            "star_diameter": info.get("diameter_treatment"),
            "star_diameter_range2_mas": [x / mas_m for x in info["diameter_range2_m"]],
            "star_diameter_profile_best_mas": info["diameter_profile_best_m"] / mas_m,
            "star_diameter_error_sigmas": sig(d_est - diam, d_sig),
            "gain_rms_error": float(np.sqrt(np.mean(g_err ** 2))), "gain_sigma_median": float(np.median(info["gains_sigma"])),
            "gain_true_rms": float(np.sqrt(np.mean((gains_true - 1) ** 2))),
            "gains_within_2sigma": float(np.mean(np.abs(g_err) <= 2 * info["gains_sigma"])) if info["gains_sigma"].any() else None}


def _place(meas: ShadowMeasured, solved: ShadowSolved) -> tuple[float, float]:
    """The fitted grid's centre on the truth's grid (north, east; m)."""
    rel = solved.info["grid_centre_m"] - meas.record.event.s_true  # (east, north)
    return float(rel[1]), float(rel[0])


def reconstruction_images(p: ShadowPlan, meas: ShadowMeasured, solved: ShadowSolved, north_m: float,
                          east_m: float) -> tuple[np.ndarray, np.ndarray]:
    """``(registered, geometric)``, each ``(N, N)`` on the truth's grid: the reconstruction kept,
    resampled where the fit placed it and shifted by the registration (``north_m``, ``east_m``;
    the score's ``registration_*_m``), and the geometric shadow (1 − the smoothed pattern, clipped)."""
    truth, pt, Is = meas.truth.truth, meas.truth.pixel_t, meas.truth.smoothed
    place = _place(meas, solved)
    registered = resample_mask(solved.mask, p.settings.silhouette.pixel_m, truth.shape, pt, (place[0] + north_m, place[1] + east_m))
    gy, gx = (Is.shape[-2] - truth.shape[0]) // 2, (Is.shape[-1] - truth.shape[1]) // 2
    geometric = np.clip(1 - Is.numpy()[gy:gy + truth.shape[0], gx:gx + truth.shape[1]], 0, 1)
    return registered, geometric


def score_event(p: ShadowPlan, meas: ShadowMeasured, solved: ShadowSolved) -> dict[str, Any]:
    """The metrics (the module's docstring): the plan's, the measure's and the solve's, then the scores."""
    s, g, info = p.settings, meas.geometry, solved.info
    truth, pt, pixel = meas.truth.truth, meas.truth.pixel_t, s.silhouette.pixel_m
    place = _place(meas, solved)

    def registered(mask):  # a reconstruction where the fit placed it, on the truth's grid, then registered
        return registered_iou(resample_mask(mask, pixel, truth.shape, pt, place), truth, pixel_m=pt, truth_pixel_m=pt)

    metrics = dict(p.metrics)
    metrics.update(meas.metrics)
    metrics.update(solved.metrics)
    reg = registered(solved.mask)
    reg_mask, geometric = reconstruction_images(p, meas, solved, reg["shift_north_m"], reg["shift_east_m"])
    feat = s.feature_m
    fc = feature_contrast(reg_mask, truth, pt, feat)
    metrics.update(iou=reg["iou"], iou_placed=reg["iou_unregistered"], registration_north_m=reg["shift_north_m"],
                   registration_east_m=reg["shift_east_m"], iou_geometric=iou(geometric, truth),
                   chi2_per_sample=info["chi2_per_sample"], silhouette_area_m2=float(truth.sum() * pt ** 2),
                   edge_width_m=edge_width(reg_mask, truth, pt), feature_m=feat, thin_contrast=fc["thin_contrast"],
                   gap_contrast=fc["gap_contrast"], thin_pixels=fc["thin_pixels"], gap_pixels=fc["gap_pixels"],
                   truth_pixel_m=pt, inversion_pixel_m=pixel, n_wavelengths=len(g.lams),
                   n_wavelengths_inversion=len(g.lams_inv), **_offsets(p, meas, solved))
    metrics["iou_pixels"] = registered(solved.pixels_mask)["iou"]
    metrics["silhouette_recovered"] = bool((np.asarray(solved.mask) >= 0.5).any())  # else the offsets' 1σ is not to be trusted
    if solved.linear is not None:
        metrics["iou_linear"] = registered(solved.linear)["iou"]
    if solved.candidates is not None and "shape_candidates" in metrics:  # each candidate's IoU, for diagnosis (not known at fit time)
        cands = list(metrics["shape_candidates"])
        for i, (c, mk) in enumerate(zip(cands, solved.candidates)):
            cands[i] = {**c, "iou": registered(mk)["iou"]}
        metrics["shape_candidates"] = cands
    return metrics


def write_event(p: ShadowPlan, meas: ShadowMeasured, solved: ShadowSolved, run: Run, metrics: dict[str, Any]) -> None:
    """``arrays.npz`` and the figures ``occultation_shadow``, ``occultation_series``, ``occultation_silhouette``."""
    t, r, info = meas.truth, meas.record, solved.info
    registered, geometric = reconstruction_images(p, meas, solved, metrics["registration_north_m"],
                                                  metrics["registration_east_m"])
    extra = {} if solved.linear is None else {"reconstruction_linear": solved.linear}
    if solved.shapes is not None:
        extra["shapes"] = solved.shapes
    write_npz(run.out_dir / "arrays.npz", truth=t.truth, pattern=t.pattern.numpy(), smoothed=t.smoothed.numpy(),
              series=r.y.numpy(), sigma=r.sig.numpy(), clean=r.clean.numpy(), positions_m=r.pos,
              ground_offsets_m=r.ground_offsets, times_s=r.times, velocity_m_s=meas.geometry.v, offset_true_m=r.event.s_true,
              gains_true=r.gains_true, gains=info["gains"], gains_sigma=info["gains_sigma"],
              grid_centre_m=info["grid_centre_m"], offset_cov=info["offset_cov"], reconstruction=solved.mask,
              reconstruction_registered=registered, diameter_profile=info["diameter_profile"], **extra)
    figs = occultation_figures(t.truth, t.pattern.numpy(), r.y.numpy(), registered, geometric, t.pixel_t, r.times, metrics)
    for stem, fig in figs.items():
        save_figure(fig, run.figure(stem))
