"""The occultation's inversion, scores and files (``cssat experiment=occultation``; the model and the
event: :mod:`cssat.experiments.forward.shadow`).

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
from typing import Any

import numpy as np

from cssat.experiments.context import Run
from cssat.experiments.files import write_npz
from cssat.occultation import (choose_prior, edge_width, event_geometry, feature_contrast, invert_event, iou, mask_centroid,
                               registered_iou, resample_mask)
from cssat.plots import save_figure
from cssat.plots.occultation import occultation_figures

__all__ = ["solve_event", "score_event", "write_event"]

log = logging.getLogger("cssat")


def solve_event(m: Any, run: Run) -> None:
    """The silhouette and the nuisances (:func:`~cssat.occultation.invert_event`), then the prior."""
    mas_m = m.mas_m
    known = {}
    if m.oracle:
        known = {"offset_m": m.s_true, "speed_error": m.eps_true, "gains": m.gains_true, "diameter_m": m.diam_mas * mas_m}
    limb = m.limb if m.oracle else m.limb_inv
    with run.stage("invert"):
        mask, info = invert_event(m.y.numpy(), m.sig.numpy(), (m.size_inv, m.size_inv), m.pixel, m.lams_inv, m.z, m.pos, m.v, m.times,
                                  weights=m.wts_inv, aperture_m=m.D, exposure_s=m.t_exp, limb_darkening=limb,
                                  diameters_m=np.linspace(0.0, m.dia_max, m.n_dia) * mas_m, known=known, solver=m.solver,
                                  tv=m.tv_weight, iters=m.iters, rounds=m.rounds, ground=m.ground, seed=run.seed)
    m.info, m.linear, m.used, m.shapes, m.candidates = info, info["linear"], "pixels", None, None
    if m.solver is not None:
        m.metrics["solver_linear"] = getattr(m.solver, "name", type(m.solver).__name__)
    m.geo, m.kernel_inv = event_geometry(m.y.numpy(), m.sig.numpy(), (m.size_inv, m.size_inv), m.pixel, m.lams_inv, m.z, m.pos,
                                         m.v, m.times, offset_m=info["grid_centre_m"], gains=info["gains"],
                                         speed_error=info["speed_error"], diameter_m=info["diameter_m"], aperture_m=m.D,
                                         exposure_s=m.t_exp, limb_darkening=limb)
    m.pixels_mask = mask
    if m.prior != "pixels":
        with run.stage("prior"):
            mask = _prior(m, mask, run)
    m.metrics["prior_used"] = m.used
    m.m = mask


def _prior(m: Any, mask: np.ndarray, run: Run) -> np.ndarray:
    """``shapes``: the union of superellipses (a multi-start over their number and starts, the one
    held-out telescopes predict best); ``auto``: that or the pixels, as held-out telescopes prefer
    (:func:`~cssat.occultation.choose_prior`)."""
    ms, choice = choose_prior(*m.geo, init_mask=mask, prior=m.prior, kernel=m.kernel_inv, weights=m.wts_inv, ground=m.ground,
                              tv=m.tv_weight, iters=m.iters, shape_iters=m.shape_iters, seed=run.seed)
    m.metrics.update(choice.metrics())
    m.used, m.shapes, m.candidates = choice.used, choice["params"], choice["candidate_masks"]
    return ms


def _offsets(m: Any) -> dict[str, Any]:
    """The silhouette centroid's time and path offsets, estimated against true, with their 1σ."""
    info, u = m.info, m.v / m.speed
    c_true, _ = mask_centroid(m.truth, m.pixel_t)
    true = m.s_true + c_true
    est, cov = info["offset_m"], info["offset_cov"]
    t_true = -float(true @ u) / (m.speed * (1 + m.eps_true))
    t_est = -float(est @ u) / (m.speed * (1 + info["speed_error"]))
    t_sig = math.sqrt(max(float(u @ cov @ u), 0.0)) / m.speed
    p_true, p_est = float(true @ m.across), float(est @ m.across)
    p_sig = math.sqrt(max(float(m.across @ cov @ m.across), 0.0))
    mas_m = m.mas_m
    d_est, d_sig = info["diameter_m"] / mas_m, info["diameter_sigma_m"] / mas_m
    g_err = info["gains"] - m.gains_true

    def sig(err, s):  # None where the quantity was handed over (σ = 0)
        return float(err / s) if s > 0 else None

    return {"time_offset_true_s": t_true, "time_offset_s": t_est, "time_offset_sigma_s": t_sig,
            "time_offset_error_sigmas": sig(t_est - t_true, t_sig),
            "path_offset_true_m": p_true, "path_offset_m": p_est, "path_offset_sigma_m": p_sig,
            "path_offset_error_sigmas": sig(p_est - p_true, p_sig),
            "centroid_sigma_m": [float(x) for x in info["centroid_sigma_m"]], "gap_sigma_m": info["gap_sigma_m"],
            "speed_error_true": m.eps_true, "speed_error": info["speed_error"], "speed_error_sigma": info["speed_error_sigma"],
            "star_diameter_true_mas": m.diam_mas, "star_diameter_mas": d_est, "star_diameter_sigma_mas": d_sig,
            "star_diameter": info.get("diameter_treatment"),
            "star_diameter_range2_mas": [x / mas_m for x in info["diameter_range2_m"]],
            "star_diameter_profile_best_mas": info["diameter_profile_best_m"] / mas_m,
            "star_diameter_error_sigmas": sig(d_est - m.diam_mas, d_sig),
            "gain_rms_error": float(np.sqrt(np.mean(g_err ** 2))), "gain_sigma_median": float(np.median(info["gains_sigma"])),
            "gain_true_rms": float(np.sqrt(np.mean((m.gains_true - 1) ** 2))),
            "gains_within_2sigma": float(np.mean(np.abs(g_err) <= 2 * info["gains_sigma"])) if info["gains_sigma"].any() else None}


def score_event(m: Any) -> dict[str, Any]:
    """The metrics (the module's docstring)."""
    truth, pt = m.truth, m.pixel_t
    rel = m.info["grid_centre_m"] - m.s_true  # the fitted grid's centre on the truth's grid (east, north)
    place = (float(rel[1]), float(rel[0]))

    def registered(mask):  # a reconstruction where the fit placed it, on the truth's grid, then registered
        return registered_iou(resample_mask(mask, m.pixel, truth.shape, pt, place), truth, pixel_m=pt, truth_pixel_m=pt)

    reg = registered(m.m)
    m.registered = resample_mask(m.m, m.pixel, truth.shape, pt, (place[0] + reg["shift_north_m"], place[1] + reg["shift_east_m"]))
    gy, gx = (m.Is.shape[-2] - truth.shape[0]) // 2, (m.Is.shape[-1] - truth.shape[1]) // 2
    m.geometric = np.clip(1 - m.Is.numpy()[gy:gy + truth.shape[0], gx:gx + truth.shape[1]], 0, 1)
    fc = feature_contrast(m.registered, truth, pt, m.feat)
    m.metrics.update(iou=reg["iou"], iou_placed=reg["iou_unregistered"], registration_north_m=reg["shift_north_m"],
                     registration_east_m=reg["shift_east_m"], iou_geometric=iou(m.geometric, truth),
                     chi2_per_sample=m.info["chi2_per_sample"], silhouette_area_m2=float(truth.sum() * pt ** 2),
                     edge_width_m=edge_width(m.registered, truth, pt), feature_m=m.feat, thin_contrast=fc["thin_contrast"],
                     gap_contrast=fc["gap_contrast"], thin_pixels=fc["thin_pixels"], gap_pixels=fc["gap_pixels"],
                     truth_pixel_m=pt, inversion_pixel_m=m.pixel, n_wavelengths=len(m.lams),
                     n_wavelengths_inversion=len(m.lams_inv), **_offsets(m))
    m.metrics["iou_pixels"] = registered(m.pixels_mask)["iou"]
    m.metrics["silhouette_recovered"] = bool((np.asarray(m.m) >= 0.5).any())  # else the offsets' 1σ is not to be trusted
    if m.linear is not None:
        m.metrics["iou_linear"] = registered(m.linear)["iou"]
    if m.candidates is not None:  # each shape candidate's IoU, for diagnosis (not known at fit time)
        for c, mk in zip(m.metrics.get("shape_candidates", []), m.candidates):
            c["iou"] = registered(mk)["iou"]
    return m.metrics


def write_event(m: Any, run: Run, metrics: dict[str, Any]) -> None:
    """``arrays.npz`` and the figures ``occultation_shadow``, ``occultation_series``, ``occultation_silhouette``."""
    extra = {} if m.linear is None else {"reconstruction_linear": m.linear}
    if m.shapes is not None:
        extra["shapes"] = m.shapes
    write_npz(run.out_dir / "arrays.npz", truth=m.truth, pattern=m.I.numpy(), smoothed=m.Is.numpy(), series=m.y.numpy(),
              sigma=m.sig.numpy(), clean=m.clean.numpy(), positions_m=m.pos, ground_offsets_m=m.ground_offsets, times_s=m.times,
              velocity_m_s=m.v, offset_true_m=m.s_true, gains_true=m.gains_true, gains=m.info["gains"],
              gains_sigma=m.info["gains_sigma"],
              grid_centre_m=m.info["grid_centre_m"], offset_cov=m.info["offset_cov"], reconstruction=m.m,
              reconstruction_registered=m.registered, diameter_profile=m.info["diameter_profile"], **extra)
    figs = occultation_figures(m.truth, m.I.numpy(), m.y.numpy(), m.registered, m.geometric, m.pixel_t, m.times, metrics)
    for stem, fig in figs.items():
        save_figure(fig, run.figure(stem))
