"""The shadow forward model (``forward: shadow``; ``cssat experiment=occultation``, issues 25 and
37): a GEO satellite's silhouette measured as the Fresnel shadow it casts on a star, recorded by
a line of telescopes on the ground, inverted with nothing handed over but what an observer knows.

Stages: ``plan`` — every setting of ``star``, ``optics``, ``event``, ``array``, ``silhouette``,
``invert`` and the ``solver`` checked in the range its physics implies, the model and attitude
built; ``measure`` — the ``scenario`` at ``scenario.start_utc``, the star (``star.ra_deg``/
``dec_deg``; null: exactly behind the satellite then), the fundamental plane, the shadow's
predicted velocity and the distance (:func:`~cssat.occultation.shadow_track`), the star's
altitude (airmass ``1/sin alt``), the telescopes on level ground along the horizontal line whose
projection is across the track, one every ``array.spacing_m`` *ground* metres (null: one
aperture in the plane), a seeded ``array.fill`` of the slots, projected into the plane along the
starlight (stage ``geometry``); the truth — the ``model``'s silhouette in its ``attitude`` (or
``silhouette.target: bars``) on a grid ``silhouette.truth_oversample`` × finer than the
inversion's, its polychromatic shadow (``optics.band`` × a blackbody of the star's ``star.bv``
colour, ``optics.n_wavelengths`` nodes, :func:`~cssat.occultation.band_wavelengths`; ``band:
null`` — monochromatic at ``optics.wavelength_m``) averaged over the aperture, the exposure's
smear and the true star's limb-darkened disk (stage ``shadow``); the event as it happens — the
shadow late by a time offset drawn within ±``event.time_error_s``, off its predicted path by a
cross-track offset (``event.path_offset_m``; null: drawn where the array still spans the
silhouette), its speed off by ``event.speed_error`` (relative 1σ), each telescope's frozen
scintillation gain and the white rest (``array.scintillation: frozen``; ``white``: independent
per exposure, the old model; ``none``), photon and read noise; the recording window the
predicted passage ± the time error (stage ``record``); ``solve`` — :func:`~cssat.occultation.invert_event`
(the offsets, speed, gains and the star's diameter estimated with the silhouette; ``event.oracle:
true`` hands them over: the labelled oracle row), the prior (``invert.prior``; pixels, or shapes
kept when held-out telescopes prefer them); ``score`` and ``write``
(:mod:`cssat.experiments.forward.shadow_score`).

Assumptions: Fresnel diffraction of a thin opaque screen (Babinet) at the satellite's distance;
a point-like line of sight per telescope averaged over its aperture and exposure; the shadow's
velocity constant over the event; level ground, the local vertical the geocentric one (≤ 0.2°
from the geodetic); scintillation as in :mod:`cssat.occultation.nuisance`; the photon count
from cssat's V zero point for the star's magnitude in the band.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.experiments.build import build, build_model, build_solver, validate_solver
from cssat.experiments.context import Run
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.shadow_score import score_event, solve_event, write_event
from cssat.experiments.resources import check_memory
from cssat.experiments.scene import build_scenario
from cssat.occultation import (bar_target, band_wavelengths, noisy, pattern_kernel, photons, plane_basis, record,
                               scintillation_gains, shadow, shadow_track, silhouette, smooth, star_direction, teff_from_bv)
from cssat.scene.attitude import nadir_pointing_frame

__all__ = ["Shadow", "MAX_EXPOSURES"]

log = logging.getLogger("cssat")

#: the settings of each group of the shadow model (conf/experiment/occultation.yaml)
_KEYS = {"star": ("ra_deg", "dec_deg", "magnitude", "bv", "diameter_mas", "limb_darkening"),
         "optics": ("band", "wavelength_m", "n_wavelengths"),
         "event": ("time_error_s", "time_offset_s", "path_offset_m", "path_error_m", "speed_error", "oracle"),
         "array": ("aperture_m", "spacing_m", "n_slots", "fill", "exposure_s", "throughput", "read_noise_e", "scintillation"),
         "silhouette": ("target", "bar_m", "size", "pixel_m", "ground", "truth_oversample"),
         "invert": ("init", "tv", "iters", "prior", "shape_iters", "feature_m", "rounds", "n_wavelengths", "limb_darkening",
                    "diameter_max_mas", "n_diameters", "margin_m")}
#: the most exposures a telescope's series may hold
MAX_EXPOSURES = 1_000_000
#: the widest silhouette grid (m): silhouette.size × silhouette.pixel_m
MAX_SILHOUETTE_M = 1000.0
MAS = 1e-3 / 206264.806  # a milliarcsecond, rad (this literal, not 1e-3 * ARCSEC: the 1e-9 difference changes the headline, note 37)


def _known_keys(cfg: Any) -> dict[str, Any]:
    """The groups, refusing a setting the model does not read (a typo would otherwise be ignored)."""
    nodes = {g: cfg.get(g) or {} for g in _KEYS}
    for group, node in nodes.items():
        for key in node:
            if key not in _KEYS[group]:
                raise FieldError(f"{group}.{key}", f"not a setting of the occultation; {group} has: {', '.join(_KEYS[group])}")
    return nodes


class Shadow(ForwardModel):
    """A silhouette through Fresnel diffraction onto an array of telescopes (the module's docstring has the stages)."""

    name = "shadow"
    timed_inside = ("measure", "solve")
    #: the nuisances are estimated with the silhouette (solve) from the recorded series (measure)
    needs = {"measure": ("plan",), "solve": ("plan", "measure"), "score": ("measure", "solve"),
             "write": ("measure", "solve", "score")}

    def plan(self, cfg: Any, run: Run) -> None:
        self.cfg = cfg
        n = _known_keys(cfg)
        star, optics, event, array, sil, inv = (n[g] for g in ("star", "optics", "event", "array", "silhouette", "invert"))
        self.size = size = int_param(sil.get("size", 128), "silhouette.size", 8, 4096)
        self.pixel = pixel = float_param(sil.get("pixel_m", 0.2), "silhouette.pixel_m", 0.0, open_lo=True)
        self.os = int_param(sil.get("truth_oversample", 4), "silhouette.truth_oversample", 1, 16)
        self.band = choice_param(optics.get("band", "V"), "optics.band", (None, "V", "R", "g", "r", "i", "clear"))
        self.lam = float_param(optics.get("wavelength_m", 550e-9), "optics.wavelength_m", 1e-7, 3e-5)
        self.n_lam = int_param(optics.get("n_wavelengths", 8), "optics.n_wavelengths", 1, 64)
        self.n_lam_inv = int_param(inv.get("n_wavelengths", 4), "invert.n_wavelengths", 1, 64)
        self.mag = float_param(star.get("magnitude", 8.0), "star.magnitude", -30.0, 30.0)
        self.teff = teff_from_bv(star.get("bv", 1.1))
        if (star.get("ra_deg") is None) != (star.get("dec_deg") is None):
            missing = "dec_deg" if star.get("dec_deg") is None else "ra_deg"
            raise FieldError(f"star.{missing}", "give both star.ra_deg and star.dec_deg, or neither (a star exactly behind "
                                                "the satellite)")
        if star.get("ra_deg") is not None:
            float_param(star.get("ra_deg"), "star.ra_deg", 0.0, 360.0)
            float_param(star.get("dec_deg"), "star.dec_deg", -90.0, 90.0)
        self.diam_mas = float_param(star.get("diameter_mas", 0.5), "star.diameter_mas", 0.0, 100.0)
        self.limb = float_param(star.get("limb_darkening", 0.7), "star.limb_darkening", 0.0, 1.0)
        self.limb_inv = float_param(inv.get("limb_darkening", 0.6), "invert.limb_darkening", 0.0, 1.0)
        self.dia_max = float_param(inv.get("diameter_max_mas", 3.0), "invert.diameter_max_mas", 0.0, 100.0)
        self.n_dia = int_param(inv.get("n_diameters", 7), "invert.n_diameters", 1, 200)
        self.t_err = float_param(event.get("time_error_s", 0.01), "event.time_error_s", 0.0, 1.0)
        self.t_off = None if event.get("time_offset_s") is None else float_param(event.time_offset_s, "event.time_offset_s", -1.0, 1.0)
        self.path_off = None if event.get("path_offset_m") is None else float_param(event.path_offset_m, "event.path_offset_m", -1e4, 1e4)
        self.path_err = float_param(event.get("path_error_m", 1000.0), "event.path_error_m", 0.0, 1e7, open_lo=True)
        self.speed_err = float_param(event.get("speed_error", 1e-3), "event.speed_error", 0.0, 0.1)
        self.oracle = choice_param(event.get("oracle", False), "event.oracle", (False, True))
        self.D = D = float_param(array.get("aperture_m", 0.5), "array.aperture_m", 0.0, open_lo=True)
        self.spacing_g = None if array.get("spacing_m") is None else float_param(array.spacing_m, "array.spacing_m", 0.0, open_lo=True)
        if self.spacing_g is not None and self.spacing_g < D:
            raise FieldError("array.spacing_m", f"{self.spacing_g:g} m on the ground is less than one aperture ({D:g} m): "
                                                "the telescopes would stand inside each other")
        self.fill = float_param(array.get("fill", 0.25), "array.fill", 0.0, 1.0, open_lo=True)
        self.t_exp = float_param(array.get("exposure_s", 2e-4), "array.exposure_s", 0.0, open_lo=True)
        self.init = choice_param(inv.get("init", "linear"), "invert.init", ("linear", "empty"))
        self.prior = choice_param(inv.get("prior", "auto"), "invert.prior", ("auto", "pixels", "shapes"))
        self.throughput = float_param(array.get("throughput", 0.5), "array.throughput", 0.0, 1.0, open_lo=True)
        self.read_noise = float_param(array.get("read_noise_e", 1.0), "array.read_noise_e", 0.0, 1e6)
        scint = array.get("scintillation", "frozen")
        scint = {True: "frozen", False: "none"}.get(scint, scint) if isinstance(scint, bool) else scint
        self.scint = choice_param(scint, "array.scintillation", ("frozen", "white", "none"))
        self.ground = float_param(sil.get("ground", 1.25), "silhouette.ground", 1.0, 8.0)
        self.bar_m = float_param(sil.get("bar_m", 0.5), "silhouette.bar_m", 0.0, open_lo=True)
        self.target = choice_param(sil.get("target", "model"), "silhouette.target", ("model", "bars"))
        self.tv_weight = float_param(inv.get("tv", 0.3), "invert.tv", 0.0)
        self.iters = int_param(inv.get("iters", 300), "invert.iters", 1, 10**6)
        self.rounds = int_param(inv.get("rounds", 2), "invert.rounds", 1, 20)
        margin = float_param(inv.get("margin_m", 1.6), "invert.margin_m", 0.0, 100.0)
        self.size_inv = size + 2 * int(round(margin / pixel))  # the inversion's grid: the silhouette's and a margin
        self.shape_iters = int_param(inv.get("shape_iters", 200), "invert.shape_iters", 1, 10**6)
        feat = inv.get("feature_m")  # null: the bar width for a bar target, else 0.5 m
        self.feat = float_param(feat if feat is not None else (self.bar_m if self.target == "bars" else 0.5),
                                "invert.feature_m", 0.0, open_lo=True)
        if size * pixel > MAX_SILHOUETTE_M:
            raise FieldError("silhouette.pixel_m", f"{pixel:g} m × {size} pixels is a {size * pixel:.3g} m silhouette, more than "
                                                   f"{MAX_SILHOUETTE_M:g} m: a satellite is metres to tens of metres across")
        if D > size * pixel * self.ground:
            raise FieldError("array.aperture_m", f"{D:g} m is wider than the ground grid ({size * pixel * self.ground:g} m: "
                                                 "silhouette.size × pixel_m × ground): the aperture would average the whole shadow away")
        ns = array.get("n_slots")
        self.n_slots = None if ns is None else int_param(ns, "array.n_slots", 1, 100000)
        self.solver = build_solver(cfg.solver, None, self.size_inv ** 2) if self.init == "linear" else None
        self.mesh = build_model(cfg.model)
        self.attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        idealised = [k for k, on in (("oracle", self.oracle), ("monochromatic", self.band is None),
                                     ("white scintillation", self.scint == "white"), ("no scintillation", self.scint == "none"))
                     if on]
        self.metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": self.mesh.name, "seed": run.seed,
                                        "row": " + ".join(idealised) or "realistic"}

    def measure(self, run: Run) -> None:
        with run.stage("geometry"):
            self._geometry(run)
        with run.stage("shadow"):
            self._shadow()
        with run.stage("record"):
            self._record(run)

    def _geometry(self, run: Run) -> None:
        """The scenario around the event, the star, the shadow's track, the star's altitude, the
        line of sight in the body frame and the telescopes on the ground projected into the plane."""
        from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

        cfg, star = self.cfg, self.cfg.get("star") or {}
        cfg2 = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
        with open_dict(cfg2):
            cfg2.scenario.n_steps, cfg2.scenario.step_s, cfg2.scenario.times = 3, 1.0, None
        sc = build_scenario(cfg2)
        rel = sc.r_sat[1] - sc.r_obs[1]
        d = rel / np.linalg.norm(rel) if star.get("ra_deg") is None else star_direction(star.ra_deg, star.dec_deg)
        tr = shadow_track(sc, d)
        self.z = z = float(tr["distance_km"][1]) * 1e3
        self.mas_m = MAS * z  # one milliarcsecond at the satellite's distance, m
        self.v = v = tr["velocity_km_s"][1] * 1e3  # predicted, m/s in the plane (east, north)
        self.speed = speed = float(np.linalg.norm(v))
        if not speed > 0:
            raise FieldError("star", "the shadow does not move (the satellite moves with the star)")
        frames = self.attitude.frames(sc) if self.attitude is not None else nadir_pointing_frame(sc.r_sat, sc.v_sat)
        self.view = frames[1] @ d  # the line of sight in the body frame
        if self.band is None:
            self.lams, self.wts = np.array([self.lam]), np.ones(1)
            self.lams_inv, self.wts_inv = self.lams, self.wts
        else:
            self.lams, self.wts = band_wavelengths(self.band, self.teff, self.n_lam)
            self.lams_inv, self.wts_inv = band_wavelengths(self.band, self.teff, self.n_lam_inv)
            self.lam = float(band_wavelengths(self.band, self.teff, 1)[0][0])  # the photon-weighted mean wavelength
        up = sc.r_obs[1] / np.linalg.norm(sc.r_obs[1])
        alt = math.degrees(math.asin(float(np.clip(d @ up, -1, 1))))
        if alt <= 5.0:
            raise FieldError("star", f"the star is {alt:.1f}° above the horizon at the event (> 5° needed)")
        e, nn = plane_basis(d)
        v3 = (v[0] * e + v[1] * nn) / speed
        g = np.cross(up, v3)
        g /= np.linalg.norm(g)  # horizontal, perpendicular to the track's direction: projects across the track
        self.line_plane = np.array([g @ e, g @ nn])  # one ground metre along the line, in the plane
        self.projection = float(np.linalg.norm(self.line_plane))
        self.spacing_ground = self.spacing_g if self.spacing_g is not None else max(self.D / self.projection, self.D)
        self.spacing = self.spacing_ground * self.projection  # in the plane
        if self.n_slots is None:
            self.n_slots = max(1, int(self.size * self.pixel // self.spacing))
        self.metrics.update(distance_km=z / 1e3, shadow_speed_km_s=speed / 1e3, miss_km=float(tr["miss_km"][1]),
                            fresnel_scale_m=math.sqrt(self.lam * z), star_altitude_deg=alt, airmass=1 / math.sin(math.radians(alt)),
                            array_ground_spacing_m=self.spacing_ground, array_plane_spacing_m=self.spacing,
                            array_ground_length_m=(self.n_slots - 1) * self.spacing_ground,
                            array_plane_length_m=(self.n_slots - 1) * self.spacing, ground_projection=self.projection,
                            band=self.band, effective_wavelength_m=self.lam, star_teff_k=self.teff)
        self._check_sampling()

    def _check_sampling(self) -> None:
        """An exposure that smears over the whole grid, or so short that a series would hold more
        than :data:`MAX_EXPOSURES`; and the memory of the truth's shadow and the series."""
        size, pixel, ground, t_exp, speed = self.size, self.pixel, self.ground, self.t_exp, self.speed
        grid_m = size * pixel * ground
        if speed * t_exp > grid_m:
            raise FieldError("array.exposure_s", f"{t_exp:g} s smears the shadow over {speed * t_exp:.3g} m, more than the "
                                                 f"ground grid ({grid_m:g} m): shorten it")
        n_exp = int((grid_m + 2 * speed * self.t_err) / max(speed * t_exp, 1e-300)) + 1
        if n_exp > MAX_EXPOSURES:
            raise FieldError("array.exposure_s", f"{t_exp:g} s cuts the recorded window into {n_exp:.3g} exposures, more "
                                                 f"than {MAX_EXPOSURES:.0e}: lengthen it")
        side = int(size * self.os * ground)
        n_tel = max(1, int(round(self.fill * self.n_slots)))
        kernel_px = int((self.D + speed * t_exp) / pixel * self.os) + 1
        parts = {"truth's shadow fields (complex, per wavelength)": 16 * (2 * side) ** 2 * 2,
                 "smoothing kernel": 8 * kernel_px * kernel_px * 4, "series": 8 * n_tel * n_exp * 6}
        if self.solver is not None:
            validate_solver(self.solver, n_tel * n_exp, self.size_inv ** 2)
        limit = self.cfg.get("memory_limit_gb")
        check_memory(parts, None if limit is None else float(limit), "lower silhouette.size, ground or truth_oversample")

    def _shadow(self) -> None:
        """The truth on the fine grid, its ground shadow and that shadow seen through an aperture,
        an exposure and the true star's disk."""
        size, pt, z = self.size * self.os, self.pixel / self.os, self.z
        self.pixel_t = pt
        self.truth = bar_target(size, pt, self.bar_m) if self.target == "bars" else silhouette(self.mesh, self.view, pt, size)
        if not self.truth.sum() > 0:
            raise FieldError("silhouette", "the silhouette is empty on its grid (a model seen edge-on, or a grid too small)")
        self.metrics["target"] = self.target
        self.k_true = pattern_kernel(pt, aperture_m=self.D, star_diameter_m=self.diam_mas * self.mas_m, limb_darkening=self.limb,
                                     smear_m=self.speed * self.t_exp, smear_dir=self.v / self.speed)
        self.I = shadow(torch.as_tensor(self.truth, dtype=torch.float64), pt, self.lams, z, weights=self.wts, ground=self.ground)
        self.Is = smooth(self.I, self.k_true)

    def _draw_event(self, rng: np.random.Generator) -> None:
        """The event's truth: time and path offsets, the speed's error."""
        u = self.v / self.speed
        self.across = np.array([-u[1], u[0]])
        yy, xx = np.nonzero(self.truth >= 0.5)
        pt = self.pixel_t
        cross = ((xx + 0.5 - self.truth.shape[1] / 2) * self.across[0] + (yy + 0.5 - self.truth.shape[0] / 2) * self.across[1]) * pt
        self.width_across = float(cross.max() - cross.min() + pt)
        self.span = (self.n_slots - 1) * self.spacing + self.D  # the line's reach across the track, apertures included
        self.cover_m = max((self.span - self.width_across) / 2, 0.0)  # the path error that still spans the silhouette
        self.dt_true = float(rng.uniform(-self.t_err, self.t_err)) if self.t_off is None else self.t_off
        self.c_true = float(rng.uniform(-self.cover_m, self.cover_m)) if self.path_off is None else self.path_off
        self.eps_true = float(rng.normal(0.0, self.speed_err))
        self.s_true = -self.v * (1 + self.eps_true) * self.dt_true + self.c_true * self.across  # the origin's shadow at t = 0

    def _record(self, run: Run) -> None:
        """The telescopes on the ground (a seeded ``fill`` of the slots), the event drawn, the gains
        of the atmosphere and the noisy series over the recorded window."""
        n_slots, D, t_exp = self.n_slots, self.D, self.t_exp
        rng = np.random.default_rng(run.seed)
        n_on = self.n_on = max(1, int(round(self.fill * n_slots)))
        on = np.sort(rng.choice(n_slots, n_on, replace=False))
        self.ground_offsets = (np.arange(n_slots) - (n_slots - 1) / 2)[on] * self.spacing_ground  # m along the line
        self.pos = self.ground_offsets[:, None] * self.line_plane[None, :]  # (J, 2) in the plane
        self._draw_event(rng)
        t_half = self.size * self.pixel * self.ground / 2 / self.speed + self.t_err
        self.times = np.arange(-t_half, t_half, t_exp) + t_exp / 2
        self.clean = record(self.Is, self.pixel_t, self.pos - self.s_true, self.v * (1 + self.eps_true), self.times)
        airmass = self.metrics["airmass"]
        self.gains_true, white = np.ones(n_on), None
        if self.scint == "frozen":
            sg = scintillation_gains(self.pos, D, t_exp, len(self.times) * t_exp, airmass=airmass, wavelength_m=self.lam, rng=rng)
            self.gains_true, white = sg["gains"], sg["white_sigma"]
            self.metrics.update(scintillation_frozen_sigma=sg["frozen_sigma"], scintillation_white_sigma=white,
                                scintillation_neighbour_correlation=float(sg["correlation"][0, 1]) if n_on > 1 else None)
        gen = torch.Generator().manual_seed(run.seed + 1)
        self.y, self.sig = noisy(self.clean, self.mag, D, t_exp, throughput=self.throughput, read_noise_e=self.read_noise,
                                 scintillation=self.scint != "none", airmass=airmass, gains=self.gains_true,
                                 scintillation_sigma=white, generator=gen)
        # any overlap of the silhouette with the line's reach: |path offset| ≤ (span + width)/2, the offset N(0, path_err)
        p_cap = math.erf(((self.span + self.width_across) / 2) / (self.path_err * math.sqrt(2)))
        self.metrics.update(n_telescopes=int(n_on), n_slots=n_slots, fill=n_on / n_slots, n_samples=int(self.y.numel()),
                            photons_per_exposure=photons(self.mag, D, t_exp, self.throughput), star_magnitude=self.mag,
                            aperture_m=D, scintillation=self.scint, silhouette_width_across_m=self.width_across,
                            path_needed_m=self.cover_m, path_error_m=self.path_err, path_capture_probability=p_cap,
                            recorded_window_s=len(self.times) * t_exp)

    def solve(self, run: Run) -> None:
        solve_event(self, run)

    def score(self, run: Run) -> dict[str, Any]:
        return score_event(self)

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        write_event(self, run, metrics)

    def headline(self, metrics: dict[str, Any]) -> str:
        return (f"occultation ({metrics['row']}): {self.mesh.name} at {self.z / 1e3:.0f} km, shadow {self.speed / 1e3:.2f} km/s; "
                f"{self.n_on} of {self.n_slots} telescopes; IoU {metrics['iou']:.3f} registered "
                f"({metrics['iou_placed']:.3f} where the fit placed it); time offset {metrics['time_offset_s'] * 1e3:+.3f} ms "
                f"(true {metrics['time_offset_true_s'] * 1e3:+.3f}), path {metrics['path_offset_m']:+.2f} m "
                f"(true {metrics['path_offset_true_m']:+.2f})")
