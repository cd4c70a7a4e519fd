"""The occultation experiment (``cssat experiment=occultation``, issue 25): a GEO satellite's
Fresnel shadow on a star, recorded by a line of telescopes across its track, and the
silhouette inverted from the recorded series (:mod:`cssat.occultation`).

Stages: the ``scenario`` at ``scenario.start_utc`` → the star (``star.ra_deg``/``dec_deg``;
null: exactly behind the satellite then) → the fundamental plane, the shadow's velocity and the
satellite's distance along the line of sight (:func:`~cssat.occultation.shadow_track`) → the
``model``'s silhouette in its ``attitude`` seen along that line (``silhouette.target: bars``:
a resolution target of ``silhouette.bar_m`` bars and gaps instead, :func:`~cssat.occultation.bar_target`) (``silhouette.size`` pixels of
``silhouette.pixel_m``) → the ground shadow (on ``silhouette.ground`` × the silhouette's grid) (:func:`~cssat.occultation.shadow`, ``optics.n_wavelengths``
over the filter) → the averages over each telescope's aperture, its exposure and the star's
limb-darkened disk → ``array.n_slots`` positions across the track, one telescope every
``array.spacing_m``, of which a random ``array.fill`` are present (seeded) → their series with
photon, read and scintillation noise → the silhouette: first by TV on the linearised model
(:func:`~cssat.occultation.invert_linear`, ``invert.linear_tv``; ``invert.init: empty`` skips
it), then by the non-linear fit started from it (:func:`~cssat.occultation.invert_silhouette`,
``invert.tv``, ``invert.iters``).
Outputs: ``arrays.npz`` (truth, pattern, series, reconstructions), the figures
``occultation_shadow``, ``occultation_series``, ``occultation_silhouette``; metrics ``iou``
(``iou_linear``: the linear route alone), ``iou_geometric`` (the shadow's own dark region
thresholded at 0.5: what a geometric-chord analysis sees), ``edge_width_m`` (10–90 %,
:func:`~cssat.occultation.edge_width`), ``thin_contrast`` / ``gap_contrast`` (features narrower
than ``invert.feature_m``, :func:`~cssat.occultation.feature_contrast`) and the photon budget.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param

log = logging.getLogger("cssat")


def run(cfg: Any, out_dir: Any) -> dict[str, Any]:
    """Run the occultation experiment ``cfg`` into ``out_dir`` and return its metrics."""
    import torch

    from cssat.experiments.build import build, build_model
    from cssat.experiments.context import Run
    from cssat.experiments.files import write_npz
    from cssat.experiments.scene import build_scenario
    from cssat.occultation import (edge_width, feature_contrast, invert_linear, invert_silhouette, iou, noisy, pattern_kernel,
                                   photons, record, shadow, shadow_track, silhouette, smooth, star_direction)
    from cssat.scene.attitude import nadir_pointing_frame

    run_ = Run.from_config(cfg, out_dir)
    with run_.stage("setup"):
        star, optics, array, sil, inv = (cfg.get(k) or {} for k in ("star", "optics", "array", "silhouette", "invert"))
        size = int_param(sil.get("size", 128), "silhouette.size", 8, 4096)
        pixel = float_param(sil.get("pixel_m", 0.2), "silhouette.pixel_m", 0.0, open_lo=True)
        lam = float_param(optics.get("wavelength_m", 550e-9), "optics.wavelength_m", 0.0, open_lo=True)
        band = float_param(optics.get("bandwidth_m", 0.0), "optics.bandwidth_m", 0.0)
        n_lam = int_param(optics.get("n_wavelengths", 1), "optics.n_wavelengths", 1, 64)
        mag = float_param(star.get("magnitude", 8.0), "star.magnitude", -30.0, 30.0)
        diam_mas = float_param(star.get("diameter_mas", 0.2), "star.diameter_mas", 0.0)
        limb = float_param(star.get("limb_darkening", 0.6), "star.limb_darkening", 0.0, 1.0)
        D = float_param(array.get("aperture_m", 0.5), "array.aperture_m", 0.0, open_lo=True)
        spacing = float_param(array.get("spacing_m", D), "array.spacing_m", 0.0, open_lo=True)
        fill = float_param(array.get("fill", 0.25), "array.fill", 0.0, 1.0, open_lo=True)
        t_exp = float_param(array.get("exposure_s", 1e-4), "array.exposure_s", 0.0, open_lo=True)
        # every choice checked before any work, with its full key and the range its physics implies
        _known_keys(star, optics, array, sil, inv)
        target = choice_param(sil.get("target", "model"), "silhouette.target", ("model", "bars"))
        init = choice_param(inv.get("init", "linear"), "invert.init", ("linear", "empty"))
        prior = choice_param(inv.get("prior", "auto"), "invert.prior", ("auto", "pixels", "shapes"))
        throughput = float_param(array.get("throughput", 0.5), "array.throughput", 0.0, 1.0, open_lo=True)
        read_noise = float_param(array.get("read_noise_e", 1.0), "array.read_noise_e", 0.0, 1e6)
        scint = bool_param(array.get("scintillation", True), "array.scintillation")
        ground = float_param(sil.get("ground", 1.0), "silhouette.ground", 1.0, 8.0)
        bar_m = float_param(sil.get("bar_m", 0.5), "silhouette.bar_m", 0.0, open_lo=True)
        linear_tv = float_param(inv.get("linear_tv", 1e-2), "invert.linear_tv", 0.0)
        linear_iters = int_param(inv.get("linear_iters", 500), "invert.linear_iters", 1, 10**6)
        tv_weight = float_param(inv.get("tv", 0.3), "invert.tv", 0.0)
        iters = int_param(inv.get("iters", 300), "invert.iters", 1, 10**6)
        n_starts = int_param(inv.get("n_starts", 1), "invert.n_starts", 1, 1000)
        shape_iters = int_param(inv.get("shape_iters", 200), "invert.shape_iters", 1, 10**6)
        feat = inv.get("feature_m")  # null: the bar width for a bar target, else 0.5 m
        feat = float_param(feat if feat is not None else (bar_m if target == "bars" else 0.5), "invert.feature_m", 0.0,
                           open_lo=True)
        grid_m = size * pixel * ground  # the ground grid's side
        if D > grid_m:
            raise FieldError("array.aperture_m", f"{D:g} m is wider than the ground grid ({grid_m:g} m: silhouette.size × "
                                                 "pixel_m × ground): the aperture would average the whole shadow away")
        n_slots = int_param(int(size * pixel // spacing) if array.get("n_slots") is None else array.get("n_slots"),
                            "array.n_slots", 1, 100000)  # null: as many as span the grid
        mesh = build_model(cfg.model)
        attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
    metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": mesh.name, "seed": run_.seed}

    with run_.stage("geometry"):
        from omegaconf import OmegaConf, open_dict

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
        z = float(tr["distance_km"][1]) * 1e3
        v = tr["velocity_km_s"][1] * 1e3  # m/s in the plane (east, north)
        frames = attitude.frames(sc) if attitude is not None else nadir_pointing_frame(sc.r_sat, sc.v_sat)
        view = frames[1] @ d  # the line of sight in the body frame
        metrics.update(distance_km=z / 1e3, shadow_speed_km_s=float(np.linalg.norm(v)) / 1e3,
                       miss_km=float(tr["miss_km"][1]), fresnel_scale_m=math.sqrt(lam * z))
        _check_sampling(float(np.linalg.norm(v)), t_exp, pixel, size, ground, D, n_lam, fill, n_slots,
                        cfg.get("memory_limit_gb"))
        if float(tr["miss_km"][1]) * 1e3 > size * pixel:
            log.info("occultation: the shadow's centre passes %.3g km from the station; the array is placed on the track",
                     tr["miss_km"][1])

    with run_.stage("shadow"):
        if target == "bars":
            from cssat.occultation import bar_target

            truth = bar_target(size, pixel, bar_m)
        else:
            truth = silhouette(mesh, view, pixel, size)
        metrics["target"] = target
        lams = lam + band * (np.arange(n_lam) + 0.5 - n_lam / 2) / n_lam if n_lam > 1 else np.array([lam])
        theta = diam_mas * 1e-3 / 206265.0
        speed = float(np.linalg.norm(v))
        if speed <= 0:
            raise FieldError("star", "the shadow does not move (the satellite moves with the star)")
        k = pattern_kernel(pixel, aperture_m=D, star_diameter_m=theta * z, limb_darkening=limb, smear_m=speed * t_exp,
                           smear_dir=v / speed)
        dtype = torch.float64
        I = shadow(torch.as_tensor(truth, dtype=dtype), pixel, lams, z, ground=ground)
        Is = smooth(I, k)

    with run_.stage("record"):
        u = v / speed
        across = np.array([-u[1], u[0]])
        offsets = (np.arange(n_slots) - (n_slots - 1) / 2) * spacing
        rng = np.random.default_rng(run_.seed)
        n_on = max(1, int(round(fill * n_slots)))
        on = np.sort(rng.choice(n_slots, n_on, replace=False))
        pos = offsets[on, None] * across[None, :]
        t_half = I.shape[-1] * pixel / 2 / speed  # the whole ground grid passes each telescope
        times = np.arange(-t_half, t_half, t_exp)
        clean = record(Is, pixel, pos, v, times)
        gen = torch.Generator().manual_seed(run_.seed + 1)
        y, sig = noisy(clean, mag, D, t_exp, throughput=throughput, read_noise_e=read_noise, scintillation=scint,
                       generator=gen)
        metrics.update(n_telescopes=int(n_on), n_slots=n_slots, fill=n_on / n_slots, n_samples=int(y.numel()),
                       photons_per_exposure=photons(mag, D, t_exp), star_magnitude=mag, aperture_m=D)

    with run_.stage("invert_linear"):
        geo = (y, sig, (size, size), pixel, lams, z, pos, v, times)
        linear = None
        if init == "linear":
            from cssat.recon import TV

            solver = TV(lam=linear_tv, method="pdhg", max_iter=linear_iters)
            linear, linfo = invert_linear(*geo, kernel=k, solver=solver, ground=ground)
            metrics.update(iou_linear=iou(linear, truth), chi2_per_sample_linear=linfo["chi2_per_sample"])

    with run_.stage("invert"):
        m, info = invert_silhouette(*geo, kernel=k, tv=tv_weight, iters=iters, n_starts=n_starts, seed=run_.seed, init=linear,
                                    ground=ground)
        gy, gx = (I.shape[-2] - size) // 2, (I.shape[-1] - size) // 2
        metrics.update(iou_pixels=iou(m, truth), chi2_per_sample_pixels=info["chi2_per_sample"])
        used, shapes = "pixels", None
        if prior != "pixels":
            from cssat.occultation import fit_shapes

            try:
                ms, params, sinfo = fit_shapes(*geo, init_mask=m, kernel=k, ground=ground, iters=shape_iters)
                n_y = int(y.numel())
                # the sparse model is kept when it explains the data to the noise (χ² per sample within
                # 3σ of 1: 1 + 3√(2/n)), or always with prior: shapes
                fits = sinfo["chi2_per_sample"] <= 1 + 3 * math.sqrt(2 / n_y)
                metrics.update(iou_shapes=iou(ms, truth), chi2_per_sample_shapes=sinfo["chi2_per_sample"], n_shapes=sinfo["n_shapes"])
                if prior == "shapes" or fits:
                    m, info, used, shapes = ms, {**info, "chi2_per_sample": sinfo["chi2_per_sample"]}, "shapes", params
            except FieldError as e:
                if prior == "shapes":
                    raise
                log.info("occultation: no shapes fitted (%s)", e)
        metrics["prior_used"] = used
        geometric = np.clip(1 - Is.numpy()[gy:gy + size, gx:gx + size], 0, 1)  # on the silhouette's grid
        fc = feature_contrast(m, truth, pixel, feat)
        metrics.update(iou=iou(m, truth), iou_geometric=iou(geometric, truth), chi2_per_sample=info["chi2_per_sample"],
                       silhouette_area_m2=float(truth.sum() * pixel ** 2), edge_width_m=edge_width(m, truth, pixel),
                       feature_m=feat, thin_contrast=fc["thin_contrast"], gap_contrast=fc["gap_contrast"],
                       thin_pixels=fc["thin_pixels"], gap_pixels=fc["gap_pixels"])

    with run_.stage("write"):
        out = Path(out_dir)
        write_npz(out / "arrays.npz", truth=truth, pattern=I.numpy(), smoothed=Is.numpy(), series=y.numpy(), sigma=sig.numpy(),
                  clean=clean.numpy(), positions_m=pos, times_s=times, velocity_m_s=v, reconstruction=m,
                  **({} if linear is None else {"reconstruction_linear": linear}),
                  **({} if shapes is None else {"shapes": shapes}))
        _figures(run_, truth, I.numpy(), y.numpy(), m, geometric, pixel, times, metrics)
    metrics.update(run_.timings())
    log.info("occultation: %s at %.0f km, shadow %.2f km/s, Fresnel scale %.2f m; %d of %d telescopes; IoU %.3f "
             "(the shadow's dark region: %.3f)", mesh.name, z / 1e3, speed / 1e3, math.sqrt(lam * z), n_on, n_slots,
             metrics["iou"], metrics["iou_geometric"])
    return metrics


#: the settings of each group of the occultation experiment (conf/experiment/occultation.yaml)
_KEYS = {"star": ("ra_deg", "dec_deg", "magnitude", "diameter_mas", "limb_darkening"),
         "optics": ("wavelength_m", "bandwidth_m", "n_wavelengths"),
         "array": ("aperture_m", "spacing_m", "n_slots", "fill", "exposure_s", "throughput", "read_noise_e", "scintillation"),
         "silhouette": ("target", "bar_m", "size", "pixel_m", "ground"),
         "invert": ("init", "linear_tv", "linear_iters", "tv", "iters", "n_starts", "prior", "shape_iters", "feature_m")}
#: the most exposures a telescope's series may hold
MAX_EXPOSURES = 1_000_000


def _known_keys(*nodes: Any) -> None:
    """Refuse a setting the experiment does not read (a typo would otherwise be ignored)."""
    for group, node in zip(_KEYS, nodes):
        for key in node:
            if key not in _KEYS[group]:
                raise FieldError(f"{group}.{key}", f"not a setting of the occultation; {group} has: {', '.join(_KEYS[group])}")


def _check_sampling(speed: float, t_exp: float, pixel: float, size: int, ground: float, D: float, n_lam: int,
                    fill: float, n_slots: int, limit_gb: Any) -> None:
    """Before the shadow is computed: an exposure that smears over the whole grid, or so short that
    a series would hold more than ``MAX_EXPOSURES``; and the memory of the shadow and the series."""
    from cssat.experiments.resources import check_memory

    grid_m = size * pixel * ground
    if speed * t_exp > grid_m:
        raise FieldError("array.exposure_s", f"{t_exp:g} s smears the shadow over {speed * t_exp:.3g} m, more than the "
                                             f"ground grid ({grid_m:g} m): shorten it")
    n_exp = int(grid_m / max(speed * t_exp, 1e-300)) + 1
    if n_exp > MAX_EXPOSURES:
        raise FieldError("array.exposure_s", f"{t_exp:g} s cuts the shadow's {grid_m / speed:.3g} s passage into {n_exp:.3g} "
                                             f"exposures, more than {MAX_EXPOSURES:.0e}: lengthen it")
    side = int(size * ground)
    n_tel = max(1, int(round(fill * n_slots)))
    kernel_px = int((D + speed * t_exp) / pixel) + 1
    parts = {"shadow fields (complex, per wavelength)": 16 * side * side * n_lam * 4,
             "smoothing kernel": 8 * kernel_px * kernel_px * 4, "series": 8 * n_tel * n_exp * 6}
    check_memory(parts, None if limit_gb is None else float(limit_gb),
                 "lower silhouette.size or ground, or lengthen array.exposure_s")


def _figures(run_, truth, pattern, series, recon, geometric, pixel, times, metrics) -> None:
    from matplotlib.figure import Figure

    from cssat.plots import save_figure

    ext = [-truth.shape[1] * pixel / 2, truth.shape[1] * pixel / 2, -truth.shape[0] * pixel / 2, truth.shape[0] * pixel / 2]

    def panel(img, size, label, xlabel, ylabel, title, stem, **show):
        fig = Figure(figsize=size)
        ax = fig.add_subplot()
        fig.colorbar(ax.imshow(img, cmap="gray", **show), ax=ax, label=label)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=10)
        fig.tight_layout()
        save_figure(fig, run_.figure(stem))

    gext = [-pattern.shape[1] * pixel / 2, pattern.shape[1] * pixel / 2, -pattern.shape[0] * pixel / 2, pattern.shape[0] * pixel / 2]
    panel(pattern, (6, 5), "intensity / unocculted star", "east (m)", "north (m)",
          f"Ground shadow (Fresnel scale {metrics['fresnel_scale_m']:.1f} m)", "occultation_shadow", origin="lower", extent=gext)
    panel(series, (7, 4), "recorded / unocculted", "time (ms)", "telescope",
          f"Recorded series: {metrics['n_telescopes']} telescopes, V = {metrics['star_magnitude']:g}", "occultation_series",
          aspect="auto", extent=[times[0] * 1e3, times[-1] * 1e3, len(series) - 0.5, -0.5])
    fig = Figure(figsize=(12, 4))
    for i, (img, title) in enumerate(((truth, "true silhouette"), (geometric, f"shadow's dark region (IoU {metrics['iou_geometric']:.2f})"),
                                      (recon, f"reconstructed (IoU {metrics['iou']:.2f})"))):
        ax = fig.add_subplot(1, 3, i + 1)
        ax.imshow(img, origin="lower", extent=ext, cmap="gray_r", vmin=0, vmax=1)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("east (m)")
    fig.tight_layout()
    save_figure(fig, run_.figure("occultation_silhouette"))
