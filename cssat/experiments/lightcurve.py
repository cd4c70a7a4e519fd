"""The light-curve experiment (paper Fig. 4 and Fig. 5).

Fig. 4: the atmosphere-free light curve of the satellite model over the scenario (1437 one-minute
steps from 2020-04-01 00:00 UTC by default) with five rendered images at marked times.
Fig. 5: the atmosphere-free curve against the facet-wise (Eq. 11) and the pixel-wise (Eq. 12)
attenuated noisy models, in magnitudes. The attenuated fluxes are zero-mean Gaussian sums and may
be negative: their magnitudes are those of ``|I(t)|``.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from cssat.experiments.common import require_int, save_figure, torch_device, write_npz

log = logging.getLogger("cssat")


def build_scenario(cfg: Any):
    from cssat.scene import ASTRA_1KR_SYNTHETIC_TLE, make_scenario

    sc = cfg.scenario
    tle = sc.get("tle")
    if tle is None:
        tle = ASTRA_1KR_SYNTHETIC_TLE
    elif len(tle) != 2:
        raise ValueError(f"scenario.tle: expected two lines, got {len(tle)}")
    obs = sc.observer
    return make_scenario(
        tle=(str(tle[0]), str(tle[1])),
        start_utc=str(sc.start_utc),
        n_steps=require_int(sc.n_steps, "scenario.n_steps", 1),
        step_s=float(sc.step_s),
        lat_deg=float(obs.lat_deg),
        lon_deg=float(obs.lon_deg),
        alt_m=float(obs.alt_m),
        name=str(sc.get("name", "")),
    )


def build_model(cfg_model: Any):
    from cssat.scene import get_model

    return get_model(
        name=str(cfg_model.name), path=cfg_model.get("path"), scale=float(cfg_model.get("scale", 1.0)),
        cd=float(cfg_model.cd), cs=float(cfg_model.cs),
    )


def run(cfg: Any, out_dir: Path) -> dict[str, Any]:
    import torch

    from cssat.optics import apparent_magnitude, attenuated_facetwise, attenuated_pixelwise, render, simulate_light_curve

    seed = require_int(cfg.get("seed", 0), "seed", 0)
    size = require_int(cfg.render.size, "render.size", 1, 4096)
    n_marks = require_int(cfg.render.get("n_images", 5), "render.n_images", 1, 20)
    fov = cfg.render.get("fov_m")
    timings: dict[str, float] = {}

    t = time.perf_counter()
    scenario = build_scenario(cfg)
    mesh = build_model(cfg.model)
    timings["seconds_scene"] = time.perf_counter() - t

    t = time.perf_counter()
    lc = simulate_light_curve(mesh, scenario, shadows=bool(cfg.get("shadows", True)))
    flux = lc.flux
    timings["seconds_light_curve"] = time.perf_counter() - t

    t = time.perf_counter()
    # rendering follows `device`; the photometry stays float64 (magnitudes span many decades)
    device = torch_device(cfg.get("device", "cpu"))
    images = render(mesh, lc.sun, lc.observer, size, fov_m=fov, brightness=lc.facets.to(device), dtype=torch.float64).cpu()
    timings["seconds_render"] = time.perf_counter() - t

    t = time.perf_counter()
    facetwise = attenuated_facetwise(lc.facets, seed=seed)
    pixelwise = attenuated_pixelwise(images, seed=seed + 1)
    timings["seconds_atmosphere"] = time.perf_counter() - t

    minutes = (scenario.times - scenario.times[0]) / np.timedelta64(1, "m")
    mag = apparent_magnitude(flux).numpy()
    mag_f = apparent_magnitude(facetwise.abs()).numpy()
    mag_p = apparent_magnitude(pixelwise.abs()).numpy()
    lit = flux.numpy() > 0
    marks = _mark_steps(flux.numpy(), n_marks)
    shadow = np.flatnonzero(scenario.sunlit < 1)
    pixel_sum_error = float((images.sum((1, 2)) - flux).abs().max() / flux.abs().max().clamp_min(1e-300))

    metrics: dict[str, Any] = {
        "model": mesh.name,
        "n_facets": len(mesh),
        "n_steps": len(scenario),
        "start_utc": str(scenario.times[0]),
        "image_size": size,
        "azimuth_deg_mean": float(scenario.azimuth_deg.mean()),
        "elevation_deg_mean": float(scenario.elevation_deg.mean()),
        "range_km_mean": float(scenario.range_km.mean()),
        "eclipse_start_utc": str(scenario.times[shadow[0]]) if shadow.size else None,
        "eclipse_end_utc": str(scenario.times[shadow[-1]]) if shadow.size else None,
        "magnitude_min": float(mag[lit].min()) if lit.any() else None,
        "magnitude_max": float(mag[lit].max()) if lit.any() else None,
        "magnitude_facetwise_median": float(np.median(mag_f[lit])) if lit.any() else None,
        "magnitude_pixelwise_median": float(np.median(mag_p[lit])) if lit.any() else None,
        "pixel_sum_relative_error": pixel_sum_error,
        "seed": seed,
        **timings,
    }
    write_npz(
        out_dir / "arrays.npz",
        times=scenario.times.astype("datetime64[s]").astype(str),
        minutes=minutes,
        flux=flux,
        flux_facetwise=facetwise,
        flux_pixelwise=pixelwise,
        magnitude=mag,
        sunlit=scenario.sunlit,
        elevation_deg=scenario.elevation_deg,
        azimuth_deg=scenario.azimuth_deg,
        range_km=scenario.range_km,
        mark_steps=marks,
        mark_images=images[marks],
    )
    _fig4(minutes, flux.numpy(), mag, images[marks].numpy(), marks, scenario, out_dir / "figures" / "fig4_lightcurve.png")
    _fig5(minutes, mag, mag_f, mag_p, out_dir / "figures" / "fig5_atmosphere.png")
    log.info(
        "lightcurve: %d steps, %s (%d facets), magnitude %.2f..%.2f, eclipse %s-%s, %.1f s",
        len(scenario), mesh.name, len(mesh), metrics["magnitude_min"] or math.nan, metrics["magnitude_max"] or math.nan,
        metrics["eclipse_start_utc"], metrics["eclipse_end_utc"], sum(timings.values()),
    )
    return metrics


def _mark_steps(flux: np.ndarray, n: int) -> np.ndarray:
    """``n`` steps spread over the lit part of the curve (as the paper's five marked points)."""
    lit = np.flatnonzero(flux > 0)
    if lit.size == 0:
        lit = np.arange(len(flux))
    pos = np.linspace(0, lit.size - 1, n + 2)[1:-1].round().astype(int)
    return lit[pos]


def _fig4(minutes, flux, mag, images, marks, scenario, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(marks)
    fig = plt.figure(figsize=(2.2 * n, 6.2))
    gs = fig.add_gridspec(2, n, height_ratios=[1, 1.25])
    for k, (step, img) in enumerate(zip(marks, images)):
        ax = fig.add_subplot(gs[0, k])
        ax.imshow(img, cmap="gray", interpolation="nearest", vmin=0, vmax=max(float(img.max()), 1e-300))
        ax.set_title(f"({k + 1}) {str(scenario.times[step])[11:16]} UTC", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    ax = fig.add_subplot(gs[1, :])
    ax.plot(minutes, mag, color="k", lw=1)
    ax.plot(minutes[marks], mag[marks], "o", color="tab:red")
    for k, step in enumerate(marks):
        ax.annotate(f"({k + 1})", (minutes[step], mag[step]), textcoords="offset points", xytext=(4, 6), fontsize=8, color="tab:red")
    ecl = scenario.sunlit < 1
    if ecl.any():
        ax.axvspan(minutes[ecl][0], minutes[ecl][-1], color="0.85", label="Earth shadow")
        ax.legend(loc="lower right", fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("minutes since " + str(scenario.times[0])[:16].replace("T", " ") + " UTC")
    ax.set_ylabel("apparent magnitude")
    ax.set_title("(b) simulated atmosphere-free light curve", fontsize=10)
    fig.suptitle("(a) synthetic images of the satellite at the marked times", fontsize=10, y=0.99)
    fig.tight_layout()
    save_figure(fig, path)


def _fig5(minutes, mag, mag_f, mag_p, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(minutes, mag_p, color="tab:orange", lw=0.6, label="simplified attenuated noisy LC (pixel-wise, Eq. 12)")
    ax.plot(minutes, mag_f, color="tab:blue", lw=0.6, label="attenuated noisy LC (facet-wise, Eq. 11)")
    ax.plot(minutes, mag, color="k", lw=1.2, label="atmosphere-free (Eq. 10)")
    ax.invert_yaxis()
    ax.set_xlabel("minutes")
    ax.set_ylabel("apparent magnitude (of |I|)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Atmosphere-free light curve and attenuated noisy light curves", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
