"""The occultation's ``measure`` stage (``cssat experiment=occultation``; the model:
:mod:`cssat.experiments.forward.shadow`): the event's geometry, the truth's shadow and the recorded
series, each handed on as a typed result (:class:`ShadowMeasured`).

``geometry`` (:func:`event_geometry_of`) — the ``scenario`` at ``scenario.start_utc``, the star,
the fundamental plane, the shadow's predicted velocity and distance, the star's altitude, the line
of telescopes and its projection into the plane, the band's quadrature; the exposure and the
memory checked against them. ``shadow`` (:func:`truth_shadow`) — the truth on the fine grid, its
polychromatic ground shadow and that shadow seen through an aperture, an exposure and the true
star's disk. ``record`` (:func:`record_series`) — the telescopes drawn, the event's true offsets
and speed error (:func:`draw_event`), the gains of the atmosphere and the noisy series.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from cssat._checks import FieldError
from cssat.experiments.build import validate_solver
from cssat.experiments.context import Run
from cssat.experiments.resources import check_memory
from cssat.experiments.scene import build_scenario
from cssat.occultation import (bar_target, band_wavelengths, noisy, pattern_kernel, photons, plane_basis, record,
                               scintillation_gains, shadow, shadow_track, silhouette, smooth, star_direction)
from cssat.scene.attitude import nadir_pointing_frame

if TYPE_CHECKING:
    from cssat.experiments.forward.shadow import ShadowPlan

__all__ = ["ShadowGeometry", "ShadowTruth", "ShadowEvent", "ShadowRecord", "ShadowMeasured", "measure_event",
           "event_geometry_of", "truth_shadow", "draw_event", "record_series", "MAX_EXPOSURES", "MAS"]

#: the most exposures a telescope's series may hold
MAX_EXPOSURES = 1_000_000
MAS = 1e-3 / 206264.806  # a milliarcsecond, rad (this literal, not 1e-3 * ARCSEC: the 1e-9 difference changes the headline, note 37)


@dataclass
class ShadowGeometry:
    """The event's geometry at the predicted passage (stage ``geometry``); the plane's axes are
    (east, north), ``L`` the truth's wavelengths, ``L'`` the inversion's."""

    z: float  #: the satellite's distance (m)
    mas_m: float  #: one milliarcsecond at that distance (m)
    v: np.ndarray  #: ``(2,)`` the shadow's predicted velocity in the plane (m/s)
    speed: float  #: its norm (m/s)
    view: np.ndarray  #: ``(3,)`` the line of sight in the body frame
    lams: np.ndarray  #: ``(L,)`` the truth's wavelengths (m)
    wts: np.ndarray  #: ``(L,)`` their weights
    lams_inv: np.ndarray  #: ``(L',)`` the inversion's wavelengths (m)
    wts_inv: np.ndarray  #: ``(L',)`` their weights
    lam: float  #: the effective wavelength (m): the photon-weighted mean over the band (``optics.wavelength_m`` without one)
    airmass: float  #: ``1 / sin`` of the star's altitude
    line_plane: np.ndarray  #: ``(2,)`` one ground metre along the line of telescopes, in the plane
    projection: float  #: its length (plane metres per ground metre)
    spacing_ground: float  #: the slots' spacing on the ground (m)
    spacing: float  #: that spacing in the plane (m)
    n_slots: int  #: the slots along the line (``array.n_slots``, or as many as span the silhouette)


@dataclass
class ShadowTruth:
    """The truth and its shadow (stage ``shadow``); ``N`` = ``silhouette.size × truth_oversample``
    pixels a side, ``M`` the ground grid's (``silhouette.ground`` × larger)."""

    pixel_t: float  #: the truth's pixel (m)
    truth: np.ndarray  #: ``(N, N)`` the silhouette, 1 = opaque
    kernel: Any  #: the true smoothing kernel: aperture, exposure's smear, the star's limb-darkened disk
    pattern: torch.Tensor  #: ``(M, M)`` the polychromatic shadow's intensity (float64; 1 = unocculted)
    smoothed: torch.Tensor  #: ``(M, M)`` that pattern through the kernel


@dataclass
class ShadowEvent:
    """The event's truth (what the inversion estimates) and the array's reach across the track."""

    across: np.ndarray  #: ``(2,)`` the unit vector across the track, in the plane
    width_across: float  #: the silhouette's width across the track (m)
    span: float  #: the line's reach across the track, apertures included (m)
    cover_m: float  #: the path offset that still spans the silhouette (m)
    dt_true: float  #: the true time offset (s)
    c_true: float  #: the true cross-track offset (m)
    eps_true: float  #: the true relative speed error
    s_true: np.ndarray  #: ``(2,)`` the origin's shadow at t = 0 in the plane (m)


@dataclass
class ShadowRecord:
    """The recorded series (stage ``record``); ``J`` telescopes, ``K`` exposures."""

    n_on: int  #: the telescopes (``J``)
    ground_offsets: np.ndarray  #: ``(J,)`` their positions along the line on the ground (m)
    pos: np.ndarray  #: ``(J, 2)`` their positions in the plane (m)
    event: ShadowEvent  #: the event's truth
    times: np.ndarray  #: ``(K,)`` the exposures' mid-times from the predicted passage (s)
    clean: torch.Tensor  #: ``(J, K)`` the noiseless series (1 = unocculted)
    gains_true: np.ndarray  #: ``(J,)`` the true frozen scintillation gains (1: none)
    y: torch.Tensor  #: ``(J, K)`` the recorded series
    sig: torch.Tensor  #: ``(J, K)`` its noise's 1σ


@dataclass
class ShadowMeasured:
    """What the shadow model's ``measure`` stage hands on."""

    geometry: ShadowGeometry
    truth: ShadowTruth
    record: ShadowRecord
    metrics: dict[str, Any]  #: the metrics of the geometry, the target and the record


def measure_event(p: ShadowPlan, run: Run) -> ShadowMeasured:
    """The stages ``geometry``, ``shadow`` and ``record``, each timed."""
    with run.stage("geometry"):
        geo, metrics = event_geometry_of(p, run)
    with run.stage("shadow"):
        truth = truth_shadow(p, geo)
        metrics["target"] = p.settings.silhouette.target
    with run.stage("record"):
        rec, more = record_series(p, geo, truth, run)
    metrics.update(more)
    return ShadowMeasured(geo, truth, rec, metrics)


def event_geometry_of(p: ShadowPlan, run: Run) -> tuple[ShadowGeometry, dict[str, Any]]:
    """The scenario around the event, the star, the shadow's track, the star's altitude, the
    line of sight in the body frame and the telescopes on the ground projected into the plane;
    with the geometry's metrics. The exposure and the memory checked (:func:`_check_sampling`)."""
    s = p.settings
    star, optics = s.star, s.optics
    sc = build_scenario(p.scenario_cfg)
    rel = sc.r_sat[1] - sc.r_obs[1]
    d = rel / np.linalg.norm(rel) if star.ra_deg is None else star_direction(star.ra_deg, star.dec_deg)
    tr = shadow_track(sc, d)
    z = float(tr["distance_km"][1]) * 1e3
    v = tr["velocity_km_s"][1] * 1e3  # predicted, m/s in the plane (east, north)
    speed = float(np.linalg.norm(v))
    if not speed > 0:
        raise FieldError("star", "the shadow does not move (the satellite moves with the star)")
    frames = p.attitude.frames(sc) if p.attitude is not None else nadir_pointing_frame(sc.r_sat, sc.v_sat)
    view = frames[1] @ d  # the line of sight in the body frame
    lam = optics.wavelength_m
    if optics.band is None:
        lams, wts = np.array([lam]), np.ones(1)
        lams_inv, wts_inv = lams, wts
    else:
        lams, wts = band_wavelengths(optics.band, p.teff, optics.n_wavelengths)
        lams_inv, wts_inv = band_wavelengths(optics.band, p.teff, s.invert.n_wavelengths)
        lam = float(band_wavelengths(optics.band, p.teff, 1)[0][0])  # the photon-weighted mean wavelength
    up = sc.r_obs[1] / np.linalg.norm(sc.r_obs[1])
    alt = math.degrees(math.asin(float(np.clip(d @ up, -1, 1))))
    if alt <= 5.0:
        raise FieldError("star", f"the star is {alt:.1f}° above the horizon at the event (> 5° needed)")
    e, nn = plane_basis(d)
    v3 = (v[0] * e + v[1] * nn) / speed
    g = np.cross(up, v3)
    g /= np.linalg.norm(g)  # horizontal, perpendicular to the track's direction: projects across the track
    line_plane = np.array([g @ e, g @ nn])  # one ground metre along the line, in the plane
    projection = float(np.linalg.norm(line_plane))
    D = s.array.aperture_m
    spacing_ground = s.array.spacing_m if s.array.spacing_m is not None else max(D / projection, D)
    spacing = spacing_ground * projection  # in the plane
    n_slots = s.array.n_slots if s.array.n_slots is not None else max(1, int(s.silhouette.width_m // spacing))
    airmass = 1 / math.sin(math.radians(alt))
    geo = ShadowGeometry(z, MAS * z, v, speed, view, lams, wts, lams_inv, wts_inv, lam, airmass, line_plane, projection,
                         spacing_ground, spacing, n_slots)
    metrics = dict(distance_km=z / 1e3, shadow_speed_km_s=speed / 1e3, miss_km=float(tr["miss_km"][1]),
                   fresnel_scale_m=math.sqrt(lam * z), star_altitude_deg=alt, airmass=airmass,
                   array_ground_spacing_m=spacing_ground, array_plane_spacing_m=spacing,
                   array_ground_length_m=(n_slots - 1) * spacing_ground,
                   array_plane_length_m=(n_slots - 1) * spacing, ground_projection=projection,
                   band=optics.band, effective_wavelength_m=lam, star_teff_k=p.teff)
    _check_sampling(p, geo, run)
    return geo, metrics


def _check_sampling(p: ShadowPlan, geo: ShadowGeometry, run: Run) -> None:
    """An exposure that smears over the whole grid, or so short that a series would hold more
    than :data:`MAX_EXPOSURES`; and the memory of the truth's shadow and the series."""
    s = p.settings
    size, pixel, ground, t_exp, speed = s.silhouette.size, s.silhouette.pixel_m, s.silhouette.ground, s.array.exposure_s, geo.speed
    grid_m = size * pixel * ground
    if speed * t_exp > grid_m:
        raise FieldError("array.exposure_s", f"{t_exp:g} s smears the shadow over {speed * t_exp:.3g} m, more than the "
                                             f"ground grid ({grid_m:g} m): shorten it")
    n_exp = int((grid_m + 2 * speed * s.event.time_error_s) / max(speed * t_exp, 1e-300)) + 1
    if n_exp > MAX_EXPOSURES:
        raise FieldError("array.exposure_s", f"{t_exp:g} s cuts the recorded window into {n_exp:.3g} exposures, more "
                                             f"than {MAX_EXPOSURES:.0e}: lengthen it")
    side = int(size * s.silhouette.truth_oversample * ground)
    n_tel = max(1, int(round(s.array.fill * geo.n_slots)))
    if n_tel < 2:  # the silhouette's held-out test leaves one telescope out: before the truth is rendered
        raise FieldError("array.n_slots" if geo.n_slots < 2 else "array.fill",
                         f"array.fill {s.array.fill:g} of {geo.n_slots} slots places {n_tel} telescope: the held-out test "
                         "needs at least two (raise array.fill or array.n_slots)")
    kernel_px = int((s.array.aperture_m + speed * t_exp) / pixel * s.silhouette.truth_oversample) + 1
    parts = {"truth's shadow fields (complex, per wavelength)": 16 * (2 * side) ** 2 * 2,
             "smoothing kernel": 8 * kernel_px * kernel_px * 4, "series": 8 * n_tel * n_exp * 6}
    if p.solver is not None:
        validate_solver(p.solver, n_tel * n_exp, s.size_inv ** 2)
    check_memory(parts, run.memory_limit_gb, "lower silhouette.size, ground or truth_oversample")


def truth_shadow(p: ShadowPlan, geo: ShadowGeometry) -> ShadowTruth:
    """The truth on the fine grid, its ground shadow and that shadow seen through an aperture,
    an exposure and the true star's disk."""
    s = p.settings
    sil = s.silhouette
    size, pt, z = sil.size * sil.truth_oversample, sil.pixel_m / sil.truth_oversample, geo.z
    truth = bar_target(size, pt, sil.bar_m) if sil.target == "bars" else silhouette(p.mesh, geo.view, pt, size)
    if not truth.sum() > 0:
        raise FieldError("silhouette", "the silhouette is empty on its grid (a model seen edge-on, or a grid too small)")
    kernel = pattern_kernel(pt, aperture_m=s.array.aperture_m, star_diameter_m=s.star.diameter_mas * geo.mas_m,
                            limb_darkening=s.star.limb_darkening, smear_m=geo.speed * s.array.exposure_s,
                            smear_dir=geo.v / geo.speed)
    pattern = shadow(torch.as_tensor(truth, dtype=torch.float64), pt, geo.lams, z, weights=geo.wts, ground=sil.ground)
    return ShadowTruth(pt, truth, kernel, pattern, smooth(pattern, kernel))


def draw_event(p: ShadowPlan, geo: ShadowGeometry, truth: ShadowTruth, n_slots: int, rng: np.random.Generator) -> ShadowEvent:
    """The event's truth: time and path offsets (``event.time_offset_s``, ``path_offset_m``; null:
    drawn from ``rng``), the speed's error (drawn)."""
    ev = p.settings.event
    u = geo.v / geo.speed
    across = np.array([-u[1], u[0]])
    t, pt = truth.truth, truth.pixel_t
    yy, xx = np.nonzero(t >= 0.5)
    cross = ((xx + 0.5 - t.shape[1] / 2) * across[0] + (yy + 0.5 - t.shape[0] / 2) * across[1]) * pt
    width_across = float(cross.max() - cross.min() + pt)
    span = (n_slots - 1) * geo.spacing + p.settings.array.aperture_m  # the line's reach across the track, apertures included
    cover_m = max((span - width_across) / 2, 0.0)  # the path error that still spans the silhouette
    dt_true = float(rng.uniform(-ev.time_error_s, ev.time_error_s)) if ev.time_offset_s is None else ev.time_offset_s
    c_true = float(rng.uniform(-cover_m, cover_m)) if ev.path_offset_m is None else ev.path_offset_m
    eps_true = float(rng.normal(0.0, ev.speed_error))
    s_true = -geo.v * (1 + eps_true) * dt_true + c_true * across  # the origin's shadow at t = 0
    return ShadowEvent(across, width_across, span, cover_m, dt_true, c_true, eps_true, s_true)


def record_series(p: ShadowPlan, geo: ShadowGeometry, truth: ShadowTruth, run: Run) -> tuple[ShadowRecord, dict[str, Any]]:
    """The telescopes on the ground (a seeded ``fill`` of the slots), the event drawn, the gains
    of the atmosphere and the noisy series over the recorded window; with the record's metrics."""
    s = p.settings
    arr = s.array
    n_slots, D, t_exp, mag = geo.n_slots, arr.aperture_m, arr.exposure_s, s.star.magnitude
    rng = np.random.default_rng(run.seed)
    n_on = max(1, int(round(arr.fill * n_slots)))
    on = np.sort(rng.choice(n_slots, n_on, replace=False))
    ground_offsets = (np.arange(n_slots) - (n_slots - 1) / 2)[on] * geo.spacing_ground  # m along the line
    pos = ground_offsets[:, None] * geo.line_plane[None, :]  # (J, 2) in the plane
    ev = draw_event(p, geo, truth, n_slots, rng)
    t_half = s.silhouette.width_m * s.silhouette.ground / 2 / geo.speed + s.event.time_error_s
    times = np.arange(-t_half, t_half, t_exp) + t_exp / 2
    clean = record(truth.smoothed, truth.pixel_t, pos - ev.s_true, geo.v * (1 + ev.eps_true), times)
    metrics: dict[str, Any] = {}
    gains_true, white = np.ones(n_on), None
    if arr.scintillation == "frozen":
        sg = scintillation_gains(pos, D, t_exp, len(times) * t_exp, airmass=geo.airmass, wavelength_m=geo.lam, rng=rng)
        gains_true, white = sg["gains"], sg["white_sigma"]
        metrics.update(scintillation_frozen_sigma=sg["frozen_sigma"], scintillation_white_sigma=white,
                       scintillation_neighbour_correlation=float(sg["correlation"][0, 1]) if n_on > 1 else None)
    gen = torch.Generator().manual_seed(run.seed + 1)
    y, sig = noisy(clean, mag, D, t_exp, throughput=arr.throughput, read_noise_e=arr.read_noise_e,
                   scintillation=arr.scintillation != "none", airmass=geo.airmass, gains=gains_true,
                   scintillation_sigma=white, generator=gen)
    # any overlap of the silhouette with the line's reach: |path offset| ≤ (span + width)/2, the offset N(0, path_err)
    p_cap = math.erf(((ev.span + ev.width_across) / 2) / (s.event.path_error_m * math.sqrt(2)))
    metrics.update(n_telescopes=int(n_on), n_slots=n_slots, fill=n_on / n_slots, n_samples=int(y.numel()),
                   photons_per_exposure=photons(mag, D, t_exp, arr.throughput), star_magnitude=mag,
                   aperture_m=D, scintillation=arr.scintillation, silhouette_width_across_m=ev.width_across,
                   path_needed_m=ev.cover_m, path_error_m=s.event.path_error_m, path_capture_probability=p_cap,
                   recorded_window_s=len(times) * t_exp)
    return ShadowRecord(n_on, ground_offsets, pos, ev, times, clean, gains_true, y, sig), metrics
