"""The light-curve experiment's stages (paper Fig. 4 and Fig. 5): a mesh in a scenario as the
target, the atmosphere over its facets and its rendered pixels as the forward model.

The target (``target._target_`` = :data:`SCENE_TARGET`) is the ``model`` group's mesh over the
``scenario`` (orbit, Sun, observer, time steps) rendered at ``render.size``; no unknown is
reconstructed, so the solver and denoiser stages are skipped.

Fig. 4: the atmosphere-free light curve of the ``model`` over the ``scenario`` (1437 one-minute
steps from 2020-04-01 00:00 UTC by default) with five rendered images at marked times.
Fig. 5: the atmosphere-free curve against the facet-wise (Eq. 11) and the pixel-wise (Eq. 12)
attenuated noisy curves: the ``atmosphere`` group's weights over the mesh's facets and over the
rendered images' pixels (both, whatever the model's ``emitters``), with the ``noise`` group.
The paper's zero-mean Gaussian weights make the fluxes sums that may be negative: the
magnitudes shown are those of ``|I(t)|``.

Outputs: ``arrays.npz`` (``times`` in seconds since ``epoch_utc``, the fluxes in W/m², the
magnitudes, ``sunlit`` — the fraction of the solar disk seen —, the masks ``lit`` and
``above_horizon`` as booleans, ``phase_angle_deg`` — the Sun–satellite–observer angle —, the
geometry and the marked renders) and ``lightcurve.csv`` (``time_utc, flux_W_m2, magnitude,
phase_angle_deg, sunlit, elevation_deg``; a dark step's magnitude is ``inf``), which pandas and
astropy read as they are.

Headline metrics: no image is reconstructed, so ``psnr`` and ``ssim`` are null; the
experiment's numbers are the magnitudes, the eclipse times and ``pixel_sum_relative_error``.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.experiments.context import Run

if TYPE_CHECKING:
    from cssat.scene import Scenario


log = logging.getLogger("cssat")

#: the ``_target_`` of the scene target (``conf/experiment/lightcurve.yaml``)
SCENE_TARGET = "cssat.experiments.scene.SceneTarget"


class SceneTarget:
    """A mesh in a scenario (the light-curve experiment's target): its settings are the ``model``,
    ``scenario``, ``render`` and ``shadows`` groups of the config, read by :func:`run`."""

    kind = "scene"


def read_observations(cfg: Any) -> Any:
    """The measured light curve of ``cfg.observations`` (a path; ``None`` when unset), read with
    the ``observed`` settings (column names, kind, time format)."""
    path = cfg.get("observations")
    if not path:
        return None
    from omegaconf import OmegaConf

    from cssat.data import read_light_curve

    opts = cfg.get("observed")
    opts = OmegaConf.to_container(opts, resolve=True) if OmegaConf.is_config(opts) else dict(opts or {})
    return read_light_curve(str(path), **opts)


def check_elements(cfg: Any, lc: Any, max_epoch_days: float = 14.0) -> None:
    """Refuse an element set that is not the observed object's: ``scenario.tle`` (null: the
    synthetic Astra 1KR set) must carry the file's NORAD number when the file names one, and its
    epoch must lie within ``max_epoch_days`` of the observations (SGP4's error grows by
    kilometres a day). A FieldError naming ``scenario.tle``."""
    from omegaconf import OmegaConf

    from cssat.scene.orbit import ASTRA_1KR_SYNTHETIC_TLE, _satellite, _skyfield

    tle = cfg.scenario.get("tle")
    given = tle is not None
    tle = ASTRA_1KR_SYNTHETIC_TLE if tle is None else OmegaConf.to_container(tle) if OmegaConf.is_config(tle) else tle
    ts, _ = _skyfield()
    sat, _ = _satellite(tle, ts)
    obj = str(lc.meta.get("object_id") or "").strip()
    satnum = int(sat.model.satnum)
    what = "scenario.tle" if given else "scenario.tle is null: the synthetic Astra 1KR set"
    if obj.isdigit() and int(obj) != satnum:
        raise FieldError("scenario.tle", f"the element set is of NORAD {satnum} ({what}), the observations of NORAD {obj}"
                                         f"{' ' + lc.meta['name'] if lc.meta.get('name') else ''}: give the object's own TLE")
    epoch = np.datetime64(sat.epoch.utc_datetime().replace(tzinfo=None), "us")
    days = float(np.abs((lc.times_utc[[0, -1]] - epoch) / np.timedelta64(1, "D")).max())
    if given and days > max_epoch_days:
        raise FieldError("scenario.tle", f"its epoch {epoch} is {days:.1f} days from the observations; SGP4 drifts by "
                                         f"kilometres a day: give an element set within {max_epoch_days:g} days")


def build_scenario(cfg: Any, times: Any = None, sites: Any = None) -> Scenario:
    """The :class:`cssat.scene.Scenario` of the ``scenario`` config (the synthetic Astra 1KR TLE
    when ``scenario.tle`` is null), on ``times`` (UTC) or ``scenario.times`` when given, else on
    its regular grid. ``sites (T, 3)`` (latitude °, longitude °, altitude m of each sample's
    observer, e.g. a SCORE file's): one observer per sample — each site's samples computed with
    its own observer, then put back in time order — instead of ``scenario.observer``."""
    from cssat.scene import ASTRA_1KR_SYNTHETIC_TLE, make_scenario

    if sites is not None and times is not None:
        import dataclasses

        sites = np.asarray(sites, dtype=np.float64)
        uniq, which = np.unique(sites, axis=0, return_inverse=True)
        which = which.reshape(-1)
        if len(uniq) > 1:
            stamps = np.asarray(times, dtype="datetime64[us]")
            parts = []
            for k, (lat, lon, alt) in enumerate(uniq):
                from omegaconf import OmegaConf, open_dict

                sub = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
                with open_dict(sub):
                    sub.scenario.observer = {"lat_deg": float(lat), "lon_deg": float(lon), "alt_m": float(alt)}
                parts.append((np.flatnonzero(which == k), build_scenario(sub, stamps[which == k])))
            arrays = {}
            for f in dataclasses.fields(parts[0][1]):
                if f.name == "name":
                    continue
                first = getattr(parts[0][1], f.name)
                out = np.empty((len(stamps),) + first.shape[1:], dtype=first.dtype)
                for idx, sc_k in parts:
                    out[idx] = getattr(sc_k, f.name)
                arrays[f.name] = out
            return dataclasses.replace(parts[0][1], **arrays)
        lat, lon, alt = uniq[0]
        from omegaconf import OmegaConf, open_dict

        cfg = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
        with open_dict(cfg):
            cfg.scenario.observer = {"lat_deg": float(lat), "lon_deg": float(lon), "alt_m": float(alt)}

    from omegaconf import OmegaConf

    sc = cfg.scenario
    tle = sc.get("tle")
    # two or three lines, a TLE text, or an OMM/GP record as a mapping of CCSDS keys
    tle = ASTRA_1KR_SYNTHETIC_TLE if tle is None else OmegaConf.to_container(tle) if OmegaConf.is_config(tle) else tle
    obs = sc.observer
    if times is None and sc.get("times") is not None:
        times = list(sc.times)
    return make_scenario(
        tle=tle, start_utc=str(sc.start_utc),
        n_steps=int_param(sc.n_steps, "scenario.n_steps", 1), step_s=float(sc.step_s),
        lat_deg=float(obs.lat_deg), lon_deg=float(obs.lon_deg), alt_m=float(obs.alt_m), name=sc.get("name"),
        times=times,
    )


def memory_parts(n_steps: int, size: int, n_facets: int = 0) -> dict[str, int]:
    """The large arrays (bytes): the float64 renders ``(T, size, size)``, the pixel-wise
    weights of Eq. 12 of the same size, and their product; the facet brightnesses ``(T, F)``
    with the facet-wise weights of Eq. 11 and their product, and the visibility masks."""
    b = n_steps * size * size * 8
    f = n_steps * n_facets * 8
    return {"renders": b, "Φ (pixel-wise)": b, "Φ ⊙ renders": b, "facet brightness (T, F)": f,
            "Φ (facet-wise)": f, "Φ ⊙ facets": f, "facet visibility": 2 * f}


def run(cfg: Any, run: Run) -> dict[str, Any]:
    """Run the light-curve experiment into ``run.out_dir``: ``arrays.npz``, ``lightcurve.csv``,
    ``figures/fig4_lightcurve`` and ``fig5_atmosphere``; return the metrics."""
    import torch

    from cssat.experiments.build import build, build_model
    from cssat.experiments.files import write_csv, write_npz
    from cssat.experiments.forward import Geometry
    from cssat.experiments.resources import check_memory
    from cssat.optics import apparent_magnitude, default_fov, render, simulate_light_curve
    from cssat.physics import Measurement
    from cssat.plots import atmosphere_figure, lightcurve_figure, save_figure

    with run.stage("setup"):
        seed, device = run.seed, run.device
        size = int_param(cfg.render.size, "render.size", 1, 4096)
        n_marks = int_param(cfg.render.get("n_images", 5), "render.n_images", 1, 20)
        geometry = build(cfg.geometry, "geometry") if cfg.get("geometry") is not None else Geometry()
        atm, noise = build(cfg.get("atmosphere"), "atmosphere", optional=geometry.kwargs()), build(cfg.get("noise"), "noise")
        fov = cfg.render.get("fov_m")
        if fov is not None:
            float_param(fov, "render.fov_m", 0.0, open_lo=True)
        mesh = build_model(cfg.model)
        attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        brdf = build(cfg.brdf, "brdf") if cfg.get("brdf") is not None and cfg.brdf.get("_target_") else None
        observed = read_observations(cfg)
        times = observed.times_utc if observed is not None else None
        n_steps = len(times) if times is not None else int_param(cfg.scenario.n_steps, "scenario.n_steps", 1)
        check_memory(memory_parts(n_steps, size, len(mesh.faces)),
                     run.memory_limit_gb, "lower render.size or scenario.n_steps")
    timings: dict[str, float] = {}

    t = time.perf_counter()
    scenario = build_scenario(cfg, times)
    timings["seconds_scene"] = time.perf_counter() - t
    t = time.perf_counter()
    lc = simulate_light_curve(mesh, scenario, shadows=bool(cfg.get("shadows", True)), attitude=attitude, brdf=brdf)
    flux = lc.flux
    timings["seconds_light_curve"] = time.perf_counter() - t
    t = time.perf_counter()
    # rendering follows `device`; the photometry stays float64 (magnitudes span many decades)
    fov_m = default_fov(mesh) if fov is None else float(fov)
    images = render(mesh, lc.sun, lc.observer, size, fov_m=fov_m, brightness=lc.facets.to(device),
                    dtype=torch.float64, progress=run.progress).cpu()
    timings["seconds_render"] = time.perf_counter() - t

    t = time.perf_counter()
    T = len(flux)
    if getattr(atm, "spatial", False):  # weights over the sky's pixels: no facet-wise form (Eq. 11)
        log.info("lightcurve: the %s atmosphere weights pixels by direction: no facet-wise curve", atm.name)
        facetwise = torch.full_like(flux, float("nan"))
    else:
        facetwise = Measurement(atm.operator(T, lc.facets.shape[1], seed=seed, dtype=torch.float64), noise,
                                seed=seed + 2).frames(lc.facets)
    pixelwise = Measurement(atm.operator(T, size * size, seed=seed + 1, dtype=torch.float64), noise, seed=seed + 3).frames(images)
    timings["seconds_atmosphere"] = time.perf_counter() - t

    minutes = (scenario.times - scenario.times[0]) / np.timedelta64(1, "m")
    mag, mag_f, mag_p = (apparent_magnitude(v).numpy() for v in (flux, facetwise.abs(), pixelwise.abs()))
    marks = _mark_steps(flux.numpy(), n_marks)
    metrics = {**_metrics(scenario, mesh, flux, images, mag, mag_f, mag_p), "image_size": size, **atm.describe(),
               **(attitude.describe() if attitude is not None else {"attitude": "nadir"}),
               **(brdf.describe() if brdf is not None else {"brdf": "mesh"}),
               **noise.describe(), "seed": seed, **timings}
    t = time.perf_counter()
    epoch = scenario.times[0]
    seconds = (scenario.times - epoch) / np.timedelta64(1, "s")
    phase = np.degrees(np.arccos(np.clip((scenario.sun_dir * scenario.obs_dir).sum(1), -1.0, 1.0)))
    write_npz(
        run.out_dir / "arrays.npz", times=seconds, epoch_utc=np.array(str(epoch)), minutes=minutes, flux=flux,
        flux_facetwise=facetwise, flux_pixelwise=pixelwise, magnitude=mag, sunlit=scenario.sunlit,
        lit=flux.numpy() > 0, above_horizon=scenario.elevation_deg > 0, phase_angle_deg=phase,
        elevation_deg=scenario.elevation_deg, azimuth_deg=scenario.azimuth_deg, range_km=scenario.range_km,
        mark_steps=marks, mark_images=images[marks],
    )
    write_csv(run.out_dir / "lightcurve.csv", [
        {"time_utc": f"{np.datetime_as_string(t, unit='s')}Z", "flux_W_m2": float(f), "magnitude": float(mm),
         "phase_angle_deg": float(a), "sunlit": float(s_), "elevation_deg": float(e)}
        for t, f, mm, a, s_, e in zip(scenario.times, flux.numpy(), mag, phase, scenario.sunlit, scenario.elevation_deg)])
    save_figure(lightcurve_figure(minutes, mag, images[marks].numpy(), marks, scenario.times, scenario.sunlit, fov_m),
                run.figure("fig4_lightcurve"))
    save_figure(atmosphere_figure(minutes, mag, mag_f, mag_p, getattr(atm, "name", ""), epoch=epoch),
                run.figure("fig5_atmosphere"))
    if observed is not None:
        metrics.update(_compare(observed, mag, epoch, run))
    metrics["seconds_write"] = time.perf_counter() - t
    metrics.update({f"seconds_{k}": v for k, v in run.seconds.items()})
    log.info("lightcurve: %d steps, %s (%d facets), magnitude %.2f..%.2f, eclipse %s-%s, %.1f s",
             len(scenario), mesh.name, len(mesh), metrics["magnitude_min"] or math.nan, metrics["magnitude_max"] or math.nan,
             metrics["eclipse_start_utc"], metrics["eclipse_end_utc"], sum(v for k, v in metrics.items() if k.startswith("seconds_")))
    return metrics


def _compare(observed: Any, mag: np.ndarray, epoch: Any, run: Run) -> dict[str, Any]:
    """The measured curve against the simulated one on its stamps: the figure
    ``observations`` and the residuals' metrics (``observations_*``; magnitudes)."""
    from cssat.plots import observations_figure, save_figure

    measured = observed.magnitudes()
    res = measured - mag
    ok = np.isfinite(res)  # a dark simulated step has an infinite magnitude
    hours = (observed.times_utc - observed.times_utc[0]) / np.timedelta64(1, "h")
    save_figure(observations_figure(hours, measured, observed.magnitude_errors(), mag, epoch=epoch,
                                    label=Path(observed.source).name), run.figure("observations"))
    out = {"observations_file": observed.source, "observations_n": len(observed), "observations_compared": int(ok.sum()),
           "observations_span_hours": float(hours[-1])}
    if ok.any():
        out.update(observations_offset_mag=float(np.median(res[ok])), observations_rms_mag=float(np.sqrt(np.mean(res[ok] ** 2))))
    return out


def _metrics(scenario, mesh, flux, images, mag, mag_f, mag_p) -> dict[str, Any]:
    """The scenario's geometry, the eclipse, the magnitudes and the render's flux check."""
    lit = flux.numpy() > 0
    shadow = np.flatnonzero(scenario.sunlit < 1)

    def stat(f, v):
        return float(f(v[lit])) if lit.any() else None

    return {
        "psnr": None, "ssim": None,
        "model": mesh.name, "n_facets": len(mesh), "n_steps": len(scenario), "start_utc": str(scenario.times[0]),
        "azimuth_deg_mean": float(scenario.azimuth_deg.mean()), "elevation_deg_mean": float(scenario.elevation_deg.mean()),
        "range_km_mean": float(scenario.range_km.mean()),
        "eclipse_start_utc": str(scenario.times[shadow[0]]) if shadow.size else None,
        "eclipse_end_utc": str(scenario.times[shadow[-1]]) if shadow.size else None,
        "magnitude_min": stat(np.min, mag), "magnitude_max": stat(np.max, mag),
        "magnitude_facetwise_median": stat(np.median, mag_f), "magnitude_pixelwise_median": stat(np.median, mag_p),
        "pixel_sum_relative_error": float((images.sum((1, 2)) - flux).abs().max() / flux.abs().max().clamp_min(1e-300)),
    }


def _mark_steps(flux: np.ndarray, n: int) -> np.ndarray:
    """``n`` steps spread over the lit part of the curve (as the paper's five marked points)."""
    lit = np.flatnonzero(flux > 0)
    if lit.size == 0:
        lit = np.arange(len(flux))
    pos = np.linspace(0, lit.size - 1, n + 2)[1:-1].round().astype(int)
    return lit[pos]
