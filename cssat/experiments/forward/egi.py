"""The EGI forward model (``forward: egi``; ``cssat experiment=inversion``): a satellite's
extended Gaussian image measured as its light curve through a scene and an attitude — compressed
sensing whose sensing matrix is known and real (:mod:`cssat.inversion`).

Stages: ``plan`` — every setting of ``nights``, ``inversion`` (its ``tumbling`` options too),
``model``, ``attitude``, ``brdf``, ``noise`` and the measured file checked, the scenario's size
and memory estimated; ``measure`` — the ``model`` in the ``attitude`` over ``nights.n`` nights of
the ground station (``scenario``: the samples where the Sun is below ``nights.sun_alt_max_deg``,
the object above ``nights.min_elevation_deg`` and fully sunlit), its light curve with the
``brdf`` group's surface and ``shadows``, photometric noise (``noise``); or the measured light
curve ``observations=<file>`` (read with the ``observed`` settings; its time stamps give the
scenario; the ``scenario.tle`` must be the object's), its nights split by gaps over 6 h; the
first ``nights.fit`` nights fitted (null: all but the last), the others held out; ``estimate``
— the attitude, whose frames make the EGI operator (``inversion.spin``: ``search`` — the pole and
sidereal period by :func:`~cssat.inversion.estimate_spin` —, ``tumbling`` — the torque-free state
by :func:`~cssat.inversion.estimate_tumbling` —, ``known`` — the true attitude, an **oracle** —,
or ``auto``: search for a ``spin`` attitude or a measured file, tumbling for a ``tumbling``
attitude, known otherwise); ``solve`` — the EGI on ``inversion.n_normals`` normals and its
convex shape (:func:`~cssat.inversion.invert_convex`) — or with ``inversion.shape=parametric`` a
shadowed box-wing fitted from it (:mod:`~cssat.experiments.forward.egi_parametric`) —, the held-out nights predicted, the
observability of the fitted geometry; ``score`` — against the truth (none for a file);
``write`` — ``arrays.npz``, ``shape.obj`` (metres), ``egi.csv``, ``lightcurve.csv`` and the
figures ``inversion_lightcurve``, ``inversion_egi``, ``inversion_shapes``,
``inversion_observability``.

Assumptions: those of :func:`~cssat.inversion.egi_operator` (no shadowing in the model, single
scattering, one BRDF shape) and of the attitude searched (a principal-axis spin, or torque-free
rotation); the simulated truth has shadows when ``shadows`` is true.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, float_param
from cssat.experiments.build import build, build_model, build_solver, validate_solver
from cssat.experiments.context import Run, as_field
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.egi_parametric import score_parametric, solve_parametric, write_parametric
from cssat.experiments.forward.egi_score import (EGI_MATCH_DEG, EGI_WEIGHT_SHARE, EGISolution, egi_recovered_share,
                                                 score_truth, solve_egi, true_egi, write_egi)
from cssat.experiments.forward.nights import check_constrained, check_search, check_size, night_index, night_mask, span_seconds
from cssat.experiments.scene import build_scenario, check_elements, read_observations
from cssat.inversion import estimate_spin, estimate_tumbling, estimate_tumbling_periods
from cssat.inversion.tumble import check_tumbling_options
from cssat.models.egi.config import EGISettings
from cssat.optics.lightcurve import simulate_light_curve
from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
from cssat.scene.attitude import nadir_pointing_frame, to_body
from cssat.scene.attitudes import Spin, Tumbling

__all__ = ["EGILightCurve", "EGIPlan", "EGIMeasured", "EGIAttitude", "EGISolution", "egi_recovered_share",
           "EGI_WEIGHT_SHARE", "EGI_MATCH_DEG"]

log = logging.getLogger("cssat")


@dataclass
class EGIPlan:
    """What the EGI model's ``plan`` stage hands on: the typed settings and the objects built
    from the groups, checked before any work."""

    settings: EGISettings  #: the model's own settings (``nights.*``, ``inversion.*``, ``shadows``, ``observations``, …)
    cfg: Any  #: the composed config (its ``scenario`` node, read by ``build_scenario``)
    spin_mode: str  #: ``inversion.spin`` resolved: search | tumbling | known
    auto: bool  #: whether ``inversion.spin`` was ``auto``
    solver: Any  #: the ``solver`` group's EGI solver
    mesh: Any  #: the ``model`` group's mesh (the truth)
    attitude: Any  #: the ``attitude`` group's object (``None``: nadir)
    brdf: Any  #: the truth's surface (the ``brdf`` group's object; ``None``: the mesh's own)
    model_brdf: Any  #: the surface the inversion assumes (``None``: Lambert)
    noise: Any  #: the ``noise`` group's object
    observed: Any  #: the measured light curve (``None``: a simulation)
    metrics: dict[str, Any] = field(default_factory=dict)  #: what the plan records (the truth's and the model's surfaces)


@dataclass
class EGIMeasured:
    """What the EGI model's ``measure`` stage hands on (``T`` observable samples)."""

    scenario: Any  #: the whole scenario (:class:`cssat.scene.Scenario`)
    keep: np.ndarray  #: ``(T_all,)`` bool: the scenario's observable samples
    t: np.ndarray  #: ``(T,)`` seconds since the scenario's first step
    night: np.ndarray  #: ``(T,)`` each sample's night
    unit: np.ndarray  #: ``(T,)`` W/m² → per unit irradiance and range (m² / (W/m²))
    sun_in: np.ndarray  #: ``(T, 3)`` the Sun's direction, inertial
    obs_in: np.ndarray  #: ``(T, 3)`` the observer's direction, inertial
    true_frames: Any  #: ``(T, 3, 3)`` the true attitude's frames (``None``: a file without an attitude)
    flux_w: np.ndarray  #: ``(T,)`` the measured flux, W/m²
    sigma_w: Any  #: ``(T,)`` its 1σ, W/m² (``None``: unknown)
    clean_w: Any  #: ``(T,)`` the noiseless flux, W/m² (``None``: a file)
    y: np.ndarray  #: ``(T,)`` the flux per unit irradiance and range (m²)
    sigma: Any  #: ``(T,)`` its 1σ (``None``: unknown)
    fit: np.ndarray  #: ``(T,)`` bool: the fitted nights' samples
    held: np.ndarray  #: ``(T,)`` bool: the held-out nights' samples
    metrics: dict[str, Any] = field(default_factory=dict)


@dataclass
class EGIAttitude:
    """What the EGI model's ``estimate`` stage hands on: the attitude the EGI operator uses."""

    sol: Any  #: the searched spin or tumbling solution (``None``: the attitude known)
    frames: np.ndarray  #: ``(T, 3, 3)`` the attitude's body frames
    sun_b: np.ndarray  #: ``(T, 3)`` the Sun in the body frame
    obs_b: np.ndarray  #: ``(T, 3)`` the observer in the body frame
    metrics: dict[str, Any] = field(default_factory=dict)


class EGILightCurve(ForwardModel):
    """The EGI through a scene and an attitude (the module's docstring has the stages): ``plan``
    returns an :class:`EGIPlan`, ``measure`` an :class:`EGIMeasured`, ``estimate`` an
    :class:`EGIAttitude`, ``solve`` an :class:`EGISolution`; later stages read them with
    ``run.result(stage)``."""

    name = "egi"
    timed_inside = ("measure", "estimate", "solve")
    #: the samples and nights (measure) → the periods and the attitude's frames on the fitted nights
    #: (estimate) → the EGI from those frames with plan's solver (solve) → the truth's errors
    #: (score: the true frames of measure) → arrays and figures
    needs = {"measure": ("plan",), "estimate": ("plan", "measure"), "solve": ("plan", "measure", "estimate"),
             "score": ("plan", "measure", "estimate", "solve"), "write": ("plan", "measure", "estimate", "solve", "score")}

    def plan(self, cfg: Any, run: Run) -> EGIPlan:
        s = EGISettings.from_config(cfg)
        inv = s.inversion
        with as_field("inversion.tumbling"):  # every option of the tumbling search, before any work
            check_tumbling_options(**inv.tumbling_options())
        solver = build_solver(cfg.solver, None, inv.n_normals)  # its size-dependent settings once the samples are known
        if getattr(solver, "unknown", "any") == "image":
            raise FieldError("solver", f"{getattr(solver, 'name', 'this solver')} works on images; the EGI is areas on "
                                       "the sphere's normals: solver=nnls|nnomp|nnl1|nntv (nntv: TV on the sphere)")
        search = inv.search()
        mesh = build_model(cfg.model)
        attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        observed = read_observations({"observations": s.observations, "observed": asdict(s.observed)})
        # the spin search's settings, before any work, with their full keys; the longest period against a
        # simulation's span here, against a measured file's once its usable nights are known (measure)
        check_search(search, span_seconds(None, s.nights.n) if observed is None else None)
        spin_mode = _resolve(inv.spin, attitude, observed)
        if not observed:
            check_size(cfg.scenario.step_s, s.nights.n, len(mesh.faces) if hasattr(mesh, "faces") else 0,
                       inv if spin_mode != "known" else None, inv.n_normals, cfg.get("memory_limit_gb"))
        brdf = build(cfg.brdf, "brdf") if cfg.get("brdf") is not None and cfg.brdf.get("_target_") else None
        # the surface the inversion assumes, whatever the truth's (a real satellite's materials are unknown):
        # Lambert, an EGI per scattering lobe (diffuse + Blinn–Phong lobes: glints, mixed materials), or the
        # simulated one — the in-class oracle
        if inv.brdf == "lobes":
            from cssat.inversion.egi import Lobes  # heavy: cssat.inversion.egi imports torch

            lobes = inv.lobes
            try:
                model_brdf = Lobes(list(lobes) if not isinstance(lobes, (int, float, str)) else lobes)
            except (FieldError, TypeError, ValueError) as e:
                raise FieldError("inversion.lobes", f"expected a list of Blinn–Phong exponents in [1, 1e5] (e.g. [100]), "
                                                    f"got {lobes!r}") from e
        else:
            model_brdf = brdf if inv.brdf == "simulated" else None
        noise = build(cfg.get("noise"), "noise")
        if observed is not None:
            check_elements(cfg, observed)
        metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": mesh.name, "seed": run.seed}
        if observed is None:  # what the truth had and what the inversion assumed: in class only when both agree
            metrics.update(truth_brdf=brdf.name if brdf is not None else "mesh", truth_shadows=s.shadows,
                           truth_shadow_resolution_m=s.shadow_resolution_m,
                           inversion_brdf=model_brdf.name if model_brdf is not None else "lambert")
        return EGIPlan(s, cfg, spin_mode, inv.spin == "auto", solver, mesh, attitude, brdf, model_brdf, noise, observed,
                       metrics)

    def measure(self, run: Run) -> EGIMeasured:
        p: EGIPlan = run.result("plan")
        with run.stage("scene"):
            scene = _scene(p)
        with run.stage("light_curve"):
            return _light_curve(p, run.seed, *scene)

    def estimate(self, run: Run) -> EGIAttitude:
        p: EGIPlan = run.result("plan")
        m: EGIMeasured = run.result("measure")
        with run.stage("spin"):
            metrics = _two_periods(p, m)
            return _attitude(p, m, metrics)

    def solve(self, run: Run) -> EGISolution:
        p, m, a = run.result("plan"), run.result("measure"), run.result("estimate")
        with run.stage("invert"):
            sol = solve_egi(p, m, a)
            if p.settings.inversion.shape == "parametric":
                solve_parametric(p.settings.inversion.parametric, m, a, sol)
        return sol

    def score(self, run: Run) -> dict[str, Any]:
        p, m, a, sol = run.result("plan"), run.result("measure"), run.result("estimate"), run.result("solve")
        metrics = {**p.metrics, **m.metrics, **a.metrics, **sol.metrics}
        if p.observed is None and m.true_frames is not None:
            metrics.update(score_truth(p, m, a, sol))
            metrics.update(score_parametric(p.mesh, sol, a.frames[0] @ m.true_frames[0].T))
        return metrics

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        p, m, a, sol = run.result("plan"), run.result("measure"), run.result("estimate"), run.result("solve")
        truth = true_egi(p, m, a) if p.observed is None and m.true_frames is not None else {}
        write_egi(p, m, a, sol, truth, metrics, run)
        write_parametric(sol, run.out_dir)

    def headline(self, metrics: dict[str, Any], run: Run) -> str:
        typ = metrics.get("heldout_typical_over_noise")
        shape = {"parts": ", the box-wing with its parts", "plain": ", the box-wing"}.get(metrics.get("parametric_family"), "")
        return ("inversion: {} samples over {} nights, {}{}, EGI {} normals{}, held-out rms {}× noise{}".format(
            metrics["n_samples"], metrics["n_nights_observed"], _attitude_line(metrics),
            f", pole error {metrics['pole_error_deg']:.2f}°" if "pole_error_deg" in metrics else "",
            metrics["egi_n_normals"], shape, f"{metrics['heldout_rms_over_noise']:.2f}" if metrics.get("heldout_rms_over_noise") else "-",
            f" (typical sample {typ:.2f}×)" if typ is not None else ""))


def _attitude_line(m: dict[str, Any]) -> str:
    """The attitude found, from the metrics: the spin's pole and period, the tumbler's ``L`` and
    periods (each with its 1σ, reduced χ² and verdict), or "attitude known (oracle)"."""
    def said(verdict: Any) -> str:  # ", reliable" or ", unreliable (no 1σ)"; nothing without a verdict
        return (f", {verdict}" + (" (no 1σ)" if verdict == "unreliable" else "")) if verdict else ""

    tail = said(m.get("spin_verdict", m.get("tumble_verdict")))

    def pm(key: str, unit: str) -> str:  # "± 1σ", or nothing where it is withheld (an unreliable fit)
        v = m.get(key)
        return f" ± {v:.2g}{unit}" if v is not None and math.isfinite(v) else ""

    if m.get("spin") == "search":
        refined = ""
        if m.get("parametric_spin_pole_lon_deg") is not None:  # inversion.parametric.refine_spin
            refined = (f"; through the shadowed box-wing ({m['parametric_spin_pole_lon_deg']:.2f}°, "
                       f"{m['parametric_spin_pole_lat_deg']:.2f}°){pm('parametric_spin_pole_err_deg', '°')}"
                       f"{said(m['parametric_spin_verdict'])}")
        return (f"spin pole ({m['spin_pole_lon_deg']:.2f}°, {m['spin_pole_lat_deg']:.2f}°){pm('spin_pole_err_deg', '°')}, "
                f"period {m['spin_period_s']:.6f}{pm('spin_period_err_s', '')} s, reduced χ² {m['spin_reduced_chi2']:.3g}"
                f"{', ambiguous' if m['spin_ambiguous'] else ''}{tail}{refined}")
    if m.get("spin") == "tumbling":
        return (f"tumbling L ({m['tumble_L_lon_deg']:.2f}°, {m['tumble_L_lat_deg']:.2f}°){pm('tumble_err_L_err_deg', '°')}, "
                f"P_ω {m['tumble_P_omega_s']:.4f} s, P_φ {m['tumble_P_phi_s']:.4f} s, {m['tumble_mode']}, "
                f"reduced χ² {m['tumble_reduced_chi2']:.3g}{tail}")
    return "attitude known (oracle)"

def _resolve(spin_mode: str, attitude: Any, observed: Any) -> str:
    """``auto``: a spin attitude is searched as one, a tumbling one as one, a file as a spin (the
    2-D series' BIC also prefers two periods for a spinner seen over changing geometry: a file's
    tumbling search is asked for, ``inversion.spin=tumbling``, not guessed); else known."""
    if spin_mode != "auto":
        return spin_mode
    if isinstance(attitude, Tumbling):
        return "tumbling"
    return "search" if observed is not None or isinstance(attitude, Spin) else "known"


def _scene(p: EGIPlan) -> tuple[Any, np.ndarray, dict[str, Any]]:
    """The scenario and its observable samples (the file's time stamps, or ``nights.n`` days), and
    what they record."""
    cfg, observed, nights = p.cfg, p.observed, p.settings.nights
    if observed is not None:
        scenario = build_scenario(cfg, observed.times_utc)
        keep = np.isfinite(observed.fluxes()) & (scenario.sunlit > 0)
    else:
        from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

        step = float_param(cfg.scenario.step_s, "scenario.step_s", 0.0, open_lo=True)
        cfg2 = OmegaConf.create({"scenario": OmegaConf.to_container(cfg.scenario, resolve=True)})
        with open_dict(cfg2):
            cfg2.scenario.n_steps = int(round(nights.n * 86400.0 / step))
            cfg2.scenario.times = None
        scenario = build_scenario(cfg2)
        keep = night_mask(scenario, nights.sun_alt_max_deg, nights.min_elevation_deg)
    if not keep.any():
        raise FieldError("nights", "no sample is observable (night, elevation, sunlit): widen nights.* or check scenario.*")
    seconds_all = (scenario.times - scenario.times[0]) / np.timedelta64(1, "s")
    t = seconds_all[keep]
    night = night_index(t)
    metrics: dict[str, Any] = dict(n_samples=int(keep.sum()), n_nights_observed=int(night.max() + 1))
    validate_solver(p.solver, int(keep.sum()), p.settings.inversion.n_normals)
    if observed is not None:
        check_constrained(observed, t, night)
        if p.spin_mode != "known":
            check_search(p.settings.inversion.search(), span_seconds(observed, nights.n))
        if observed.ranges_km is not None:  # the file's own range against the element set's
            metrics["range_diff_km_median"] = float(np.median(np.abs(scenario.range_km - observed.ranges_km)[keep]))
    return scenario, keep, t, night, metrics


def _light_curve(p: EGIPlan, seed: int, sc: Any, keep: np.ndarray, t: np.ndarray, night: np.ndarray,
                 metrics: dict[str, Any]) -> EGIMeasured:
    """The light curve per unit irradiance and range, its 1σ, the fitted and held-out nights."""
    noise, observed, attitude = p.noise, p.observed, p.attitude
    unit = ((sc.range_km * 1e3) ** 2 / SOLAR_IRRADIANCE_W_M2)[keep]  # W/m² → per unit irradiance and range
    sun_in, obs_in = sc.sun_dir[keep], sc.obs_dir[keep]
    true_frames = None
    if attitude is not None or observed is None:
        frames_all = attitude.frames(sc) if attitude is not None else nadir_pointing_frame(sc.r_sat, sc.v_sat)
        true_frames = frames_all[keep]
    if observed is not None:
        flux_w = observed.fluxes()[keep]
        err = observed.flux_errors()
        sigma_w = err[keep] if err is not None else None
        clean_w = None
    else:
        lc = simulate_light_curve(p.mesh, sc, shadows=p.settings.shadows, attitude=attitude, brdf=p.brdf,
                                  shadow_resolution_m=p.settings.shadow_resolution_m)
        clean_w = lc.flux.numpy()[keep]
        gen = torch.Generator().manual_seed(seed)
        y = torch.as_tensor(clean_w, dtype=torch.float64)[None]
        ref = y.mean(-1) if getattr(noise, "magnitude", None) is not None else None
        flux_w = noise(y, gen, flux=ref)[0].numpy() if ref is not None else noise(y, gen)[0].numpy()
        var = noise.variance(torch.as_tensor(flux_w)[None], flux=ref)[0].numpy() if hasattr(noise, "variance") else None
        sigma_w = np.sqrt(var) if var is not None and np.all(var > 0) else None
    y_unit = flux_w * unit
    sigma = sigma_w * unit if sigma_w is not None else None
    n_fit = max(int(night.max()), 1) if p.settings.nights.fit is None else p.settings.nights.fit
    fit = night < n_fit
    held = ~fit
    metrics.update(n_fit=int(fit.sum()), n_heldout=int(held.sum()), **noise.describe())
    if sigma is not None:
        metrics["noise_relative_median"] = float(np.median(sigma / np.maximum(np.abs(y_unit), 1e-300)))
    return EGIMeasured(sc, keep, t, night, unit, sun_in, obs_in, true_frames, flux_w, sigma_w, clean_w, y_unit, sigma, fit,
                       held, metrics)


def _two_periods(p: EGIPlan, m: EGIMeasured) -> dict[str, Any]:
    """One period or two: a tumbling (non-principal-axis) light curve has two fundamental frequencies."""
    fit, sigma, inv = m.fit, m.sigma, p.settings.inversion
    metrics: dict[str, Any] = {}
    try:
        tp = estimate_tumbling_periods(m.t[fit], m.y[fit], sigma=None if sigma is None else sigma[fit],
                                       min_period_s=float(inv.min_period_s or 60.0),
                                       max_period_s=float(inv.max_period_s or 86400.0))
        metrics.update(lc_tumbling=tp["tumbling"], lc_delta_bic=tp["delta_bic"], lc_aperiodic=tp["aperiodic"],
                       lc_periods_s=[float(x) for x in tp["periods_s"]], lc_single_period_s=tp["single_period_s"])
        if tp["tumbling"] and p.spin_mode == "search" and (not p.auto or p.observed is not None):
            log.warning("inversion: no single period folds the light curve (aperiodic fraction %.3f; two periods "
                        "%.1f s, %.1f s): it looks tumbling, and the spin search assumes a principal-axis rotation "
                        "(inversion.spin=tumbling searches a torque-free tumbling state)", tp["aperiodic"], *tp["periods_s"])
    except FieldError as e:  # too few samples or no second frequency: the period analysis is skipped
        log.info("inversion: no two-period analysis (%s)", e)
    return metrics


def _attitude(p: EGIPlan, m: EGIMeasured, metrics: dict[str, Any]) -> EGIAttitude:
    """The frames of the fitted attitude, and the body-frame Sun and observer: the EGI operator's geometry."""
    fit, sigma, spin_mode, inv = m.fit, m.sigma, p.spin_mode, p.settings.inversion
    if spin_mode == "known" and m.true_frames is None:
        raise FieldError("inversion.spin", "'known' needs an attitude model (attitude=...) for a measured light curve")
    args = (m.t[fit], m.y[fit], m.sun_in[fit], m.obs_in[fit])
    kw = dict(sigma=None if sigma is None else sigma[fit], brdf=p.model_brdf, frame=getattr(p.attitude, "frame", "ecliptic"))
    sol = None
    held = m.held if sigma is not None and m.held.any() else None  # the nights held out test the model
    heldout = None if held is None else (m.t[held], m.y[held], m.sun_in[held], m.obs_in[held], sigma[held])
    if spin_mode == "search":
        sol = estimate_spin(*args, **kw, n_normals=inv.search_normals, heldout=heldout, **inv.search())
        frames = sol.frames(m.t)
        metrics.update(sol.describe())
        # the synodic period the search started from (the period search's best candidate, whatever its verdict)
        metrics["spin_synodic_period_s"] = float(sol.synodic.get("best_period_s", sol.synodic["period_s"]))
        metrics["spin_synodic_verdict"] = sol.synodic.get("verdict", "given")
    elif spin_mode == "tumbling":
        sol = estimate_tumbling(*args, **kw, heldout=heldout, **inv.tumbling_options())
        frames = sol.frames(m.t)
        metrics.update(sol.describe())
    else:
        frames = m.true_frames
    if sol is not None and sol.get("verdict") == "unreliable":
        log.warning("inversion: unreliable — %s", sol["verdict_why"])
    elif sol is not None and sol.model_fits is False:
        kind, what, err = (("spin", "the pole's", sol.pole_err_deg) if spin_mode == "search"
                           else ("tumbling", "the angular momentum's", sol.errors["L_err_deg"]))
        log.warning("inversion: the %s model misses the light curve by more than its noise (reduced χ² %.3g): "
                    "shadows, glints or materials it does not have; %s 1σ (%.2g°) counts that misfit as white "
                    "noise and can miss the truth by many times itself", kind, sol.reduced_chi2, what, err)
    metrics.update(spin=spin_mode, attitude_known=spin_mode == "known")
    return EGIAttitude(sol, frames, to_body(frames, m.sun_in), to_body(frames, m.obs_in), metrics)
