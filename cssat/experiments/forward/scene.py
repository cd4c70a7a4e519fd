"""The scene forward model (``forward: scene``; ``cssat experiment=lightcurve``, paper Fig. 4 and
Fig. 5): a mesh in a scenario, measured as its light curve and through an atmosphere over its
facets (Eq. 11) and over its rendered pixels (Eq. 12). No unknown is reconstructed: the model's
``solve`` is empty and its numbers are the magnitudes, the eclipse and the render's flux check.

Stages: ``plan`` — ``render.*``, ``geometry``, ``atmosphere``, ``noise``, ``model``, ``attitude``,
``brdf`` and a measured file checked, the memory of the renders and the facet arrays estimated;
``measure`` — the ``scenario`` (orbit, Sun, observer, time steps; ``observations=<file>``: the
file's time stamps), the atmosphere-free light curve of the ``model`` (stage ``light_curve``),
its images rendered at ``render.size`` (stage ``render``), the facet-wise and pixel-wise
attenuated noisy curves with the ``atmosphere`` group's weights and the ``noise`` group (stage
``atmosphere``; a model whose weights depend on the pixels' directions has no facet-wise form);
``score`` — the geometry, the eclipse, the magnitudes, ``pixel_sum_relative_error``; ``write`` —
``arrays.npz`` (``times`` in seconds since ``epoch_utc``, the fluxes in W/m², the magnitudes,
``sunlit`` — the fraction of the solar disk seen —, the masks ``lit`` and ``above_horizon``,
``phase_angle_deg``, the geometry and the marked renders), ``lightcurve.csv`` (``time_utc,
flux_W_m2, magnitude, phase_angle_deg, sunlit, elevation_deg``; a dark step's magnitude is
``inf``), the figures ``fig4_lightcurve``, ``fig5_atmosphere`` and, for a measured file,
``observations`` (the measured curve against the simulated one, ``observations_*`` metrics).

The paper's zero-mean Gaussian weights make the fluxes sums that may be negative: the magnitudes
shown are those of ``|I(t)|``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cssat._checks import int_param
from cssat.experiments.build import build, build_model
from cssat.experiments.context import Run
from cssat.experiments.files import write_csv, write_npz
from cssat.experiments.forward.sensing import Geometry
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.resources import check_memory
from cssat.experiments.scene import build_scenario, read_observations
from cssat.models.scene.config import SceneSettings
from cssat.plots import atmosphere_figure, lightcurve_figure, observations_figure, save_figure

if TYPE_CHECKING:
    import torch

__all__ = ["SceneLightCurve", "ScenePlan", "SceneMeasured", "memory_parts"]

log = logging.getLogger("cssat")


def memory_parts(n_steps: int, size: int, n_facets: int = 0) -> dict[str, int]:
    """The large arrays (bytes): the float64 renders ``(T, size, size)``, the pixel-wise
    weights of Eq. 12 of the same size, and their product; the facet brightnesses ``(T, F)``
    with the facet-wise weights of Eq. 11 and their product, and the visibility masks."""
    b = n_steps * size * size * 8
    f = n_steps * n_facets * 8
    return {"renders": b, "Φ (pixel-wise)": b, "Φ ⊙ renders": b, "facet brightness (T, F)": f,
            "Φ (facet-wise)": f, "Φ ⊙ facets": f, "facet visibility": 2 * f}


@dataclass
class SceneMeasured:
    """What the scene's ``measure`` stage hands on (``T`` time steps, ``S = render.size``)."""

    scenario: Any  #: the scenario (:class:`cssat.scene.Scenario`, ``T`` steps)
    flux: torch.Tensor  #: ``(T,)`` the atmosphere-free light curve, W/m²
    images: torch.Tensor  #: ``(T, S, S)`` the renders, float64, W/m² per pixel
    fov_m: float  #: the renders' field of view (m)
    facetwise: torch.Tensor  #: ``(T,)`` the facet-wise attenuated noisy curve (Eq. 11; NaN: none)
    pixelwise: torch.Tensor  #: ``(T,)`` the pixel-wise attenuated noisy curve (Eq. 12)
    magnitude: np.ndarray  #: ``(T,)`` the magnitudes of ``flux`` in the ``magnitudes`` band
    magnitude_facetwise: np.ndarray  #: ``(T,)`` those of ``|facetwise|``
    magnitude_pixelwise: np.ndarray  #: ``(T,)`` those of ``|pixelwise|``
    marks: np.ndarray  #: the marked steps (``render.n_images``, spread over the lit part)
    earthshine: bool  #: whether earthshine was simulated (``auto`` decided)


@dataclass
class ScenePlan:
    """What the scene's ``plan`` stage hands on: the typed settings and the objects built from
    the groups, checked before any work."""

    settings: SceneSettings  #: the model's own settings (``render.*``, ``shadows``, ``earthshine``, …)
    scenario_cfg: Any  #: the config ``build_scenario`` reads (its ``scenario`` node)
    mesh: Any  #: the ``model`` group's mesh
    attitude: Any  #: the ``attitude`` group's object (``None``: nadir)
    brdf: Any  #: the ``brdf`` group's object (``None``: the mesh's own, Eq. 8–9)
    atmosphere: Any  #: the ``atmosphere`` group's object (its weights)
    noise: Any  #: the ``noise`` group's object
    band: Any  #: the magnitudes' band (``None``: V with the Sun at -26.74)
    observed: Any  #: the measured light curve of ``observations`` (``None``: none)

    @property
    def times(self) -> Any:
        """The measured file's UTC stamps (``None``: the scenario's grid)."""
        return self.observed.times_utc if self.observed is not None else None


class SceneLightCurve(ForwardModel):
    """A mesh in a scenario, its light curve rendered and attenuated (the module's docstring has
    the stages): ``plan`` returns a :class:`ScenePlan`, ``measure`` a :class:`SceneMeasured`;
    ``score`` and ``write`` read them with ``run.result(stage)``."""

    name = "scene"
    timed_inside = ("measure", "estimate", "solve")
    #: nothing is estimated or solved: the magnitudes (score) come from the curves of measure
    needs = {"measure": ("plan",), "score": ("plan", "measure"), "write": ("plan", "measure", "score")}

    def plan(self, cfg: Any, run: Run) -> ScenePlan:
        s = SceneSettings.from_config(cfg)
        geometry = build(cfg.geometry, "geometry") if cfg.get("geometry") is not None else Geometry()
        atm = build(cfg.get("atmosphere"), "atmosphere", optional=geometry.kwargs())
        noise = build(cfg.get("noise"), "noise")
        mesh = build_model(cfg.model)
        attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        from cssat.optics.passbands import resolve_band  # heavy: cssat.optics imports torch

        band = resolve_band(s.magnitudes.band, s.magnitudes.system, field="magnitudes.band")
        brdf = build(cfg.brdf, "brdf") if cfg.get("brdf") is not None and cfg.brdf.get("_target_") else None
        observed = read_observations({"observations": s.observations, "observed": asdict(s.observed)})
        n_steps = len(observed.times_utc) if observed is not None else int_param(cfg.scenario.n_steps,
                                                                                 "scenario.n_steps", 1)
        check_memory(memory_parts(n_steps, s.render.size, len(mesh.faces)), run.memory_limit_gb,
                     "lower render.size or scenario.n_steps")
        return ScenePlan(s, cfg, mesh, attitude, brdf, atm, noise, band, observed)

    def measure(self, run: Run) -> SceneMeasured:
        import torch  # heavy: torch (~1 s); the module imports without it

        from cssat.optics import default_fov, render, simulate_light_curve  # heavy: cssat.optics imports torch

        p: ScenePlan = run.result("plan")
        s = p.settings
        with run.stage("scene"):
            scenario = build_scenario(p.scenario_cfg, p.times)
        with run.stage("light_curve"):
            earthshine = s.earthshine
            if earthshine == "auto":  # decided once, here: the metrics report what was simulated
                from cssat.optics.lightcurve import earthshine_matters  # heavy: cssat.optics imports torch

                earthshine = earthshine_matters(scenario)
            lc = simulate_light_curve(p.mesh, scenario, shadows=s.shadows, attitude=p.attitude,
                                      brdf=p.brdf, earthshine=earthshine, earth_albedo=s.earth_albedo)
        with run.stage("render"):  # rendering follows `device`; the photometry stays float64 (magnitudes span many decades)
            fov_m = default_fov(p.mesh) if s.render.fov_m is None else float(s.render.fov_m)
            images = render(p.mesh, lc.sun, lc.observer, s.render.size, fov_m=fov_m,
                            brightness=lc.facets.to(run.device), dtype=torch.float64, progress=run.progress).cpu()
        with run.stage("atmosphere"):
            facetwise, pixelwise = _attenuate(run, p, lc, images)
        from cssat.optics import apparent_magnitude, magnitude  # heavy: cssat.optics imports torch

        to_mag = apparent_magnitude if p.band is None else (lambda v: magnitude(v, *p.band))
        mag, mag_f, mag_p = (to_mag(v).numpy() for v in (lc.flux, facetwise.abs(), pixelwise.abs()))
        return SceneMeasured(scenario, lc.flux, images, fov_m, facetwise, pixelwise, mag, mag_f, mag_p,
                             _mark_steps(lc.flux.numpy(), s.render.n_images), bool(earthshine))

    def solve(self, run: Run) -> None:
        """Nothing is reconstructed: the light curves are the result."""

    def score(self, run: Run) -> dict[str, Any]:
        p: ScenePlan = run.result("plan")
        m: SceneMeasured = run.result("measure")
        atm, attitude, brdf = p.atmosphere, p.attitude, p.brdf
        return {**_metrics(m.scenario, p.mesh, m.flux, m.images, m.magnitude, m.magnitude_facetwise,
                           m.magnitude_pixelwise),
                "image_size": p.settings.render.size, **atm.describe(),
                **(attitude.describe() if attitude is not None else {"attitude": "nadir"}),
                **(brdf.describe() if brdf is not None else {"brdf": "mesh"}), **p.noise.describe(), "seed": run.seed,
                **({"magnitude_band": f"{p.band[0].name} ({p.band[1]})"} if p.band is not None else {}),
                **({"earthshine_albedo": p.settings.earth_albedo} if m.earthshine else {})}

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        p: ScenePlan = run.result("plan")
        m: SceneMeasured = run.result("measure")
        sc, flux, mag, marks, images = m.scenario, m.flux, m.magnitude, m.marks, m.images
        minutes = (sc.times - sc.times[0]) / np.timedelta64(1, "m")
        epoch = sc.times[0]
        seconds = (sc.times - epoch) / np.timedelta64(1, "s")
        phase = np.degrees(np.arccos(np.clip((sc.sun_dir * sc.obs_dir).sum(1), -1.0, 1.0)))
        write_npz(run.out_dir / "arrays.npz", times=seconds, epoch_utc=np.array(str(epoch)), minutes=minutes, flux=flux,
                  flux_facetwise=m.facetwise, flux_pixelwise=m.pixelwise, magnitude=mag, sunlit=sc.sunlit,
                  lit=flux.numpy() > 0, above_horizon=sc.elevation_deg > 0, phase_angle_deg=phase,
                  elevation_deg=sc.elevation_deg, azimuth_deg=sc.azimuth_deg, range_km=sc.range_km,
                  mark_steps=marks, mark_images=images[marks])
        write_csv(run.out_dir / "lightcurve.csv", [
            {"time_utc": f"{np.datetime_as_string(t, unit='s')}Z", "flux_W_m2": float(f), "magnitude": float(mm),
             "phase_angle_deg": float(a), "sunlit": float(s_), "elevation_deg": float(e)}
            for t, f, mm, a, s_, e in zip(sc.times, flux.numpy(), mag, phase, sc.sunlit, sc.elevation_deg)])
        save_figure(lightcurve_figure(minutes, mag, images[marks].numpy(), marks, sc.times, sc.sunlit, m.fov_m),
                    run.figure("fig4_lightcurve"))
        save_figure(atmosphere_figure(minutes, mag, m.magnitude_facetwise, m.magnitude_pixelwise,
                                      getattr(p.atmosphere, "name", ""), epoch=epoch), run.figure("fig5_atmosphere"))
        if p.observed is not None:
            metrics.update(_compare(p.observed, mag, epoch, run))

    def headline(self, metrics: dict[str, Any], run: Run) -> str:
        return "lightcurve: %d steps, %s (%d facets), magnitude %.2f..%.2f, eclipse %s-%s, %.1f s" % (
            metrics["n_steps"], metrics["model"], metrics["n_facets"], metrics["magnitude_min"] or math.nan,
            metrics["magnitude_max"] or math.nan, metrics["eclipse_start_utc"], metrics["eclipse_end_utc"],
            sum(v for k, v in metrics.items() if k.startswith("seconds_")))


def _attenuate(run: Run, p: ScenePlan, lc: Any, images: Any) -> tuple[Any, Any]:
    """The facet-wise (Eq. 11) and pixel-wise (Eq. 12) attenuated noisy curves ``(T,)`` of the
    light curve ``lc`` and its renders ``images (T, S, S)``."""
    import torch  # heavy: torch (~1 s); the module imports without it

    from cssat.physics import Measurement  # heavy: cssat.physics imports torch

    atm, noise, seed, flux, size = p.atmosphere, p.noise, run.seed, lc.flux, p.settings.render.size
    T = len(flux)
    if getattr(atm, "spatial", False):  # weights over the sky's pixels: no facet-wise form (Eq. 11)
        log.info("lightcurve: the %s atmosphere weights pixels by direction: no facet-wise curve", atm.name)
        facetwise = torch.full_like(flux, float("nan"))
    else:
        facetwise = Measurement(atm.operator(T, lc.facets.shape[1], seed=seed, dtype=torch.float64), noise,
                                seed=seed + 2).frames(lc.facets)
    pixelwise = Measurement(atm.operator(T, size * size, seed=seed + 1, dtype=torch.float64), noise,
                            seed=seed + 3).frames(images)
    return facetwise, pixelwise


def _compare(observed: Any, mag: np.ndarray, epoch: Any, run: Run) -> dict[str, Any]:
    """The measured curve against the simulated one on its stamps: the figure
    ``observations`` and the residuals' metrics (``observations_*``; magnitudes)."""
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
