"""The shadow forward model (``forward: shadow``; ``cssat experiment=occultation``, issue 25): a GEO
satellite's silhouette measured as the Fresnel shadow it casts on a star, recorded by a line of
telescopes across its track (:mod:`cssat.occultation`).

Stages: ``plan`` — every setting of ``star``, ``optics``, ``array``, ``silhouette``, ``invert``
and the ``solver`` checked in the range its physics implies (throughput ≤ 1, read noise ≥ 0, the
aperture and the exposure against the grid), the model and attitude built; ``measure`` — the
``scenario`` at ``scenario.start_utc``, the star (``star.ra_deg``/``dec_deg``; null: exactly behind
the satellite then), the fundamental plane, the shadow's velocity and the satellite's distance
along the line of sight (:func:`~cssat.occultation.shadow_track`), the sampling and memory checked
before the shadow is computed (stage ``geometry``); the ``model``'s silhouette in its
``attitude`` seen along that line (``silhouette.target: bars``: a resolution target of
``silhouette.bar_m`` bars and gaps, :func:`~cssat.occultation.bar_target`), ``silhouette.size``
pixels of ``silhouette.pixel_m``, its ground shadow on ``silhouette.ground`` × the silhouette's
grid over ``optics.n_wavelengths`` (:func:`~cssat.occultation.shadow`) averaged over each
telescope's aperture, its exposure and the star's limb-darkened disk (stage ``shadow``);
``array.n_slots`` positions across the track, one every ``array.spacing_m``, a random
``array.fill`` of them present (seeded), their series with photon, read and scintillation noise
(stage ``record``); ``solve`` — the silhouette, first by the ``solver`` group's solver on the
linearised model (:func:`~cssat.occultation.invert_linear`; default TV by PDHG,
``solver.lam`` 3e-2, 500 iterations; ``invert.init: empty`` skips it), then by the non-linear fit
started from it (:func:`~cssat.occultation.invert_silhouette`, ``invert.tv``, ``invert.iters``),
and a union of superellipses (``invert.prior``); ``score`` — ``iou`` (``iou_linear``: the linear
route alone), ``iou_geometric`` (the shadow's dark region thresholded at 0.5: what a
geometric-chord analysis sees), ``edge_width_m``, ``thin_contrast`` / ``gap_contrast`` (features
narrower than ``invert.feature_m``) and the photon budget; ``write`` — ``arrays.npz`` and the
figures ``occultation_shadow``, ``occultation_series``, ``occultation_silhouette``.

Assumptions: Fresnel diffraction of a thin opaque screen (Babinet) at the satellite's distance,
a point-like line of sight per telescope averaged over its aperture and exposure, the shadow's
velocity constant over the event; photon, read and scintillation noise as in
:func:`~cssat.occultation.noisy`.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param
from cssat.experiments.build import build, build_model, build_solver, validate_solver
from cssat.experiments.context import Run
from cssat.experiments.files import write_npz
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.resources import check_memory
from cssat.experiments.scene import build_scenario
from cssat.occultation import (bar_target, edge_width, feature_contrast, fit_shapes, invert_linear, invert_silhouette,
                               iou, noisy, pattern_kernel, photons, record, shadow, shadow_track, silhouette, smooth,
                               star_direction)
from cssat.plots import save_figure
from cssat.plots.occultation import occultation_figures
from cssat.scene.attitude import nadir_pointing_frame

__all__ = ["Shadow", "MAX_EXPOSURES"]

log = logging.getLogger("cssat")

#: the settings of each group of the shadow model (conf/experiment/occultation.yaml)
_KEYS = {"star": ("ra_deg", "dec_deg", "magnitude", "diameter_mas", "limb_darkening"),
         "optics": ("wavelength_m", "bandwidth_m", "n_wavelengths"),
         "array": ("aperture_m", "spacing_m", "n_slots", "fill", "exposure_s", "throughput", "read_noise_e", "scintillation"),
         "silhouette": ("target", "bar_m", "size", "pixel_m", "ground"),
         "invert": ("init", "tv", "iters", "n_starts", "prior", "shape_iters", "feature_m")}
#: the most exposures a telescope's series may hold
MAX_EXPOSURES = 1_000_000
#: the widest silhouette grid (m): silhouette.size × silhouette.pixel_m
MAX_SILHOUETTE_M = 1000.0


def _known_keys(*nodes: Any) -> None:
    """Refuse a setting the model does not read (a typo would otherwise be ignored)."""
    for group, node in zip(_KEYS, nodes):
        for key in node:
            if key not in _KEYS[group]:
                hint = "; the linear route's solver is the solver group (solver.lam, solver.max_iter)" \
                    if key in ("linear_tv", "linear_iters") else ""
                raise FieldError(f"{group}.{key}", f"not a setting of the occultation; {group} has: {', '.join(_KEYS[group])}{hint}")


class Shadow(ForwardModel):
    """A silhouette through Fresnel diffraction onto an array of telescopes (the module's docstring has the stages)."""

    name = "shadow"
    timed_inside = ("measure", "solve")

    def plan(self, cfg: Any, run: Run) -> None:
        self.cfg = cfg
        star, optics, array, sil, inv = (cfg.get(k) or {} for k in ("star", "optics", "array", "silhouette", "invert"))
        self.size = size = int_param(sil.get("size", 128), "silhouette.size", 8, 4096)
        self.pixel = pixel = float_param(sil.get("pixel_m", 0.2), "silhouette.pixel_m", 0.0, open_lo=True)
        # the Fresnel shadow of a star in a filter: from the near UV to the thermal infrared
        self.lam = float_param(optics.get("wavelength_m", 550e-9), "optics.wavelength_m", 1e-7, 3e-5)
        self.band = float_param(optics.get("bandwidth_m", 0.0), "optics.bandwidth_m", 0.0, self.lam)
        self.n_lam = int_param(optics.get("n_wavelengths", 1), "optics.n_wavelengths", 1, 64)
        self.mag = float_param(star.get("magnitude", 8.0), "star.magnitude", -30.0, 30.0)
        if (star.get("ra_deg") is None) != (star.get("dec_deg") is None):
            missing = "dec_deg" if star.get("dec_deg") is None else "ra_deg"
            raise FieldError(f"star.{missing}", "give both star.ra_deg and star.dec_deg, or neither (a star exactly behind "
                                                "the satellite)")
        if star.get("ra_deg") is not None:
            float_param(star.get("ra_deg"), "star.ra_deg", 0.0, 360.0)
            float_param(star.get("dec_deg"), "star.dec_deg", -90.0, 90.0)
        self.diam_mas = float_param(star.get("diameter_mas", 0.2), "star.diameter_mas", 0.0)
        self.limb = float_param(star.get("limb_darkening", 0.6), "star.limb_darkening", 0.0, 1.0)
        self.D = D = float_param(array.get("aperture_m", 0.5), "array.aperture_m", 0.0, open_lo=True)
        self.spacing = spacing = float_param(array.get("spacing_m", D), "array.spacing_m", 0.0, open_lo=True)
        self.fill = float_param(array.get("fill", 0.25), "array.fill", 0.0, 1.0, open_lo=True)
        self.t_exp = float_param(array.get("exposure_s", 1e-4), "array.exposure_s", 0.0, open_lo=True)
        # every choice checked before any work, with its full key and the range its physics implies
        _known_keys(star, optics, array, sil, inv)
        self.target = choice_param(sil.get("target", "model"), "silhouette.target", ("model", "bars"))
        self.init = choice_param(inv.get("init", "linear"), "invert.init", ("linear", "empty"))
        self.prior = choice_param(inv.get("prior", "auto"), "invert.prior", ("auto", "pixels", "shapes"))
        self.throughput = float_param(array.get("throughput", 0.5), "array.throughput", 0.0, 1.0, open_lo=True)
        self.read_noise = float_param(array.get("read_noise_e", 1.0), "array.read_noise_e", 0.0, 1e6)
        self.scint = bool_param(array.get("scintillation", True), "array.scintillation")
        self.ground = ground = float_param(sil.get("ground", 1.0), "silhouette.ground", 1.0, 8.0)
        self.bar_m = float_param(sil.get("bar_m", 0.5), "silhouette.bar_m", 0.0, open_lo=True)
        self.tv_weight = float_param(inv.get("tv", 0.3), "invert.tv", 0.0)
        self.iters = int_param(inv.get("iters", 300), "invert.iters", 1, 10**6)
        self.n_starts = int_param(inv.get("n_starts", 1), "invert.n_starts", 1, 1000)
        self.shape_iters = int_param(inv.get("shape_iters", 200), "invert.shape_iters", 1, 10**6)
        feat = inv.get("feature_m")  # null: the bar width for a bar target, else 0.5 m
        self.feat = float_param(feat if feat is not None else (self.bar_m if self.target == "bars" else 0.5),
                                "invert.feature_m", 0.0, open_lo=True)
        grid_m = size * pixel * ground  # the ground grid's side
        if size * pixel > MAX_SILHOUETTE_M:
            raise FieldError("silhouette.pixel_m", f"{pixel:g} m × {size} pixels is a {size * pixel:.3g} m silhouette, more than "
                                                   f"{MAX_SILHOUETTE_M:g} m: a satellite is metres to tens of metres across")
        if D > grid_m:
            raise FieldError("array.aperture_m", f"{D:g} m is wider than the ground grid ({grid_m:g} m: silhouette.size × "
                                                 "pixel_m × ground): the aperture would average the whole shadow away")
        self.n_slots = int_param(int(size * pixel // spacing) if array.get("n_slots") is None else array.get("n_slots"),
                                 "array.n_slots", 1, 100000)  # null: as many as span the grid
        # the linear route's solver (the solver group; its size-dependent settings once the series' length is known)
        self.solver = build_solver(cfg.solver, None, size * size) if self.init == "linear" else None
        self.mesh = build_model(cfg.model)
        self.attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        self.metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": self.mesh.name, "seed": run.seed}

    def measure(self, run: Run) -> None:
        with run.stage("geometry"):
            self._geometry()
        with run.stage("shadow"):
            self._shadow()
        with run.stage("record"):
            self._record(run)

    def _geometry(self) -> None:
        """The scenario around the event, the star, the shadow's track and the line of sight in the
        body frame; the exposure against the grid and the memory, before the shadow is computed."""
        from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

        cfg, star = self.cfg, self.cfg.get("star") or {}
        cfg2 = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
        with open_dict(cfg2):
            cfg2.scenario.n_steps, cfg2.scenario.step_s, cfg2.scenario.times = 3, 1.0, None
        sc = build_scenario(cfg2)
        if star.get("ra_deg") is None or star.get("dec_deg") is None:
            rel = sc.r_sat[1] - sc.r_obs[1]
            d = rel / np.linalg.norm(rel)  # a star exactly behind the satellite at the middle time
        else:
            d = star_direction(star.ra_deg, star.dec_deg)
        tr = shadow_track(sc, d)
        self.z = z = float(tr["distance_km"][1]) * 1e3
        self.v = v = tr["velocity_km_s"][1] * 1e3  # m/s in the plane (east, north)
        frames = self.attitude.frames(sc) if self.attitude is not None else nadir_pointing_frame(sc.r_sat, sc.v_sat)
        self.view = frames[1] @ d  # the line of sight in the body frame
        self.metrics.update(distance_km=z / 1e3, shadow_speed_km_s=float(np.linalg.norm(v)) / 1e3,
                            miss_km=float(tr["miss_km"][1]), fresnel_scale_m=math.sqrt(self.lam * z))
        self._check_sampling(float(np.linalg.norm(v)))
        if float(tr["miss_km"][1]) * 1e3 > self.size * self.pixel:
            log.info("occultation: the shadow's centre passes %.3g km from the station; the array is placed on the track",
                     tr["miss_km"][1])

    def _check_sampling(self, speed: float) -> None:
        """An exposure that smears over the whole grid, or so short that a series would hold more
        than :data:`MAX_EXPOSURES`; and the memory of the shadow and the series."""
        size, pixel, ground, t_exp = self.size, self.pixel, self.ground, self.t_exp
        grid_m = size * pixel * ground
        if speed * t_exp > grid_m:
            raise FieldError("array.exposure_s", f"{t_exp:g} s smears the shadow over {speed * t_exp:.3g} m, more than the "
                                                 f"ground grid ({grid_m:g} m): shorten it")
        n_exp = int(grid_m / max(speed * t_exp, 1e-300)) + 1
        if n_exp > MAX_EXPOSURES:
            raise FieldError("array.exposure_s", f"{t_exp:g} s cuts the shadow's {grid_m / speed:.3g} s passage into "
                                                 f"{n_exp:.3g} exposures, more than {MAX_EXPOSURES:.0e}: lengthen it")
        side = int(size * ground)
        n_tel = max(1, int(round(self.fill * self.n_slots)))
        kernel_px = int((self.D + speed * t_exp) / pixel) + 1
        parts = {"shadow fields (complex, per wavelength)": 16 * side * side * self.n_lam * 4,
                 "smoothing kernel": 8 * kernel_px * kernel_px * 4, "series": 8 * n_tel * n_exp * 6}
        if self.solver is not None:
            validate_solver(self.solver, n_tel * n_exp, size * size)
        limit = self.cfg.get("memory_limit_gb")
        check_memory(parts, None if limit is None else float(limit), "lower silhouette.size or ground, or lengthen array.exposure_s")

    def _shadow(self) -> None:
        """The silhouette (the truth), its ground shadow and that shadow seen through an aperture, an
        exposure and the star's disk."""
        size, pixel, v, z = self.size, self.pixel, self.v, self.z
        if self.target == "bars":
            self.truth = bar_target(size, pixel, self.bar_m)
        else:
            self.truth = silhouette(self.mesh, self.view, pixel, size)
        self.metrics["target"] = self.target
        n_lam, lam = self.n_lam, self.lam
        self.lams = lam + self.band * (np.arange(n_lam) + 0.5 - n_lam / 2) / n_lam if n_lam > 1 else np.array([lam])
        theta = self.diam_mas * 1e-3 / 206265.0
        self.speed = speed = float(np.linalg.norm(v))
        if speed <= 0:
            raise FieldError("star", "the shadow does not move (the satellite moves with the star)")
        self.k = pattern_kernel(pixel, aperture_m=self.D, star_diameter_m=theta * z, limb_darkening=self.limb,
                                smear_m=speed * self.t_exp, smear_dir=v / speed)
        self.I = shadow(torch.as_tensor(self.truth, dtype=torch.float64), pixel, self.lams, z, ground=self.ground)
        self.Is = smooth(self.I, self.k)

    def _record(self, run: Run) -> None:
        """The telescopes placed across the track (a seeded ``fill`` of the slots) and their noisy series."""
        v, speed, n_slots, D, t_exp = self.v, self.speed, self.n_slots, self.D, self.t_exp
        u = v / speed
        across = np.array([-u[1], u[0]])
        offsets = (np.arange(n_slots) - (n_slots - 1) / 2) * self.spacing
        rng = np.random.default_rng(run.seed)
        n_on = self.n_on = max(1, int(round(self.fill * n_slots)))
        on = np.sort(rng.choice(n_slots, n_on, replace=False))
        self.pos = offsets[on, None] * across[None, :]
        t_half = self.I.shape[-1] * self.pixel / 2 / speed  # the whole ground grid passes each telescope
        self.times = np.arange(-t_half, t_half, t_exp)
        self.clean = record(self.Is, self.pixel, self.pos, v, self.times)
        gen = torch.Generator().manual_seed(run.seed + 1)
        self.y, self.sig = noisy(self.clean, self.mag, D, t_exp, throughput=self.throughput, read_noise_e=self.read_noise,
                                 scintillation=self.scint, generator=gen)
        self.metrics.update(n_telescopes=int(n_on), n_slots=n_slots, fill=n_on / n_slots, n_samples=int(self.y.numel()),
                            photons_per_exposure=photons(self.mag, D, t_exp), star_magnitude=self.mag, aperture_m=D)

    def solve(self, run: Run) -> None:
        self.geo = (self.y, self.sig, (self.size, self.size), self.pixel, self.lams, self.z, self.pos, self.v, self.times)
        with run.stage("invert_linear"):
            self.linear = None
            if self.solver is not None:
                self.linear, linfo = invert_linear(*self.geo, kernel=self.k, solver=self.solver, ground=self.ground)
                self.metrics.update(iou_linear=iou(self.linear, self.truth), chi2_per_sample_linear=linfo["chi2_per_sample"],
                                    solver_linear=getattr(self.solver, "name", type(self.solver).__name__))
        with run.stage("invert"):
            self._fit(run)

    def _fit(self, run: Run) -> None:
        """The non-linear fit from the linear estimate, then the union of shapes where it fits to the noise."""
        m, info = invert_silhouette(*self.geo, kernel=self.k, tv=self.tv_weight, iters=self.iters, n_starts=self.n_starts,
                                    seed=run.seed, init=self.linear, ground=self.ground)
        self.metrics.update(iou_pixels=iou(m, self.truth), chi2_per_sample_pixels=info["chi2_per_sample"])
        used, self.shapes = "pixels", None
        if self.prior != "pixels":
            try:
                ms, params, sinfo = fit_shapes(*self.geo, init_mask=m, kernel=self.k, ground=self.ground, iters=self.shape_iters)
                n_y = int(self.y.numel())
                # the sparse model is kept when it explains the data to the noise (χ² per sample within
                # 3σ of 1: 1 + 3√(2/n)), or always with prior: shapes
                fits = sinfo["chi2_per_sample"] <= 1 + 3 * math.sqrt(2 / n_y)
                self.metrics.update(iou_shapes=iou(ms, self.truth), chi2_per_sample_shapes=sinfo["chi2_per_sample"],
                                    n_shapes=sinfo["n_shapes"])
                if self.prior == "shapes" or fits:
                    m, info, used, self.shapes = ms, {**info, "chi2_per_sample": sinfo["chi2_per_sample"]}, "shapes", params
            except FieldError as e:
                if self.prior == "shapes":
                    raise
                log.info("occultation: no shapes fitted (%s)", e)
        self.metrics["prior_used"] = used
        self.m, self.info = m, info

    def score(self, run: Run) -> dict[str, Any]:
        size, m, truth, pixel = self.size, self.m, self.truth, self.pixel
        gy, gx = (self.I.shape[-2] - size) // 2, (self.I.shape[-1] - size) // 2
        self.geometric = np.clip(1 - self.Is.numpy()[gy:gy + size, gx:gx + size], 0, 1)  # on the silhouette's grid
        fc = feature_contrast(m, truth, pixel, self.feat)
        self.metrics.update(iou=iou(m, truth), iou_geometric=iou(self.geometric, truth),
                            chi2_per_sample=self.info["chi2_per_sample"], silhouette_area_m2=float(truth.sum() * pixel ** 2),
                            edge_width_m=edge_width(m, truth, pixel), feature_m=self.feat, thin_contrast=fc["thin_contrast"],
                            gap_contrast=fc["gap_contrast"], thin_pixels=fc["thin_pixels"], gap_pixels=fc["gap_pixels"])
        return self.metrics

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        extra = {} if self.linear is None else {"reconstruction_linear": self.linear}
        if self.shapes is not None:
            extra["shapes"] = self.shapes
        write_npz(run.out_dir / "arrays.npz", truth=self.truth, pattern=self.I.numpy(), smoothed=self.Is.numpy(),
                  series=self.y.numpy(), sigma=self.sig.numpy(), clean=self.clean.numpy(), positions_m=self.pos,
                  times_s=self.times, velocity_m_s=self.v, reconstruction=self.m, **extra)
        figs = occultation_figures(self.truth, self.I.numpy(), self.y.numpy(), self.m, self.geometric, self.pixel, self.times,
                                   metrics)
        for stem, fig in figs.items():
            save_figure(fig, run.figure(stem))

    def headline(self, metrics: dict[str, Any]) -> str:
        return (f"occultation: {self.mesh.name} at {self.z / 1e3:.0f} km, shadow {self.speed / 1e3:.2f} km/s, Fresnel scale "
                f"{math.sqrt(self.lam * self.z):.2f} m; {self.n_on} of {self.n_slots} telescopes; IoU {metrics['iou']:.3f} "
                f"(the shadow's dark region: {metrics['iou_geometric']:.3f})")
