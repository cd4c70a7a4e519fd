"""The light-curve inversion experiment (``cssat experiment=inversion``, issue 24): shape, spin
and observability of a satellite from its light curve — compressed sensing whose sensing matrix
is known and real (:mod:`cssat.inversion`).

Stages: the ``model`` in the ``attitude`` over ``nights.n`` nights of the ground station
(``scenario``: the samples where the Sun is below ``nights.sun_alt_max_deg`` at the station, the
object above ``nights.min_elevation_deg`` and fully sunlit), its light curve with the ``brdf``
group's surface and ``shadows``, photometric noise (``noise``: a 1 m telescope at the object's
own magnitude by default) → the first ``nights.fit`` nights fitted (null: all but the last), the others held out →
the spin (``inversion.spin``: ``search`` — the pole and sidereal period by
:func:`~cssat.inversion.estimate_spin` —, ``tumbling`` — the torque-free state by
:func:`~cssat.inversion.estimate_tumbling`, options under ``inversion.tumbling`` —, ``known`` —
the true attitude, an **oracle** —, or ``auto``: search for a ``spin`` attitude or a measured
file, tumbling for a ``tumbling`` attitude, known otherwise) → the EGI on
``inversion.n_normals`` normals and its convex shape (:func:`~cssat.inversion.invert_convex`)
→ the held-out nights predicted → scores against the truth and the observability of the
fitted geometry.

``observations=<file>`` inverts a measured light curve instead (read with the ``observed``
settings; its time stamps give the scenario; the ``scenario.tle`` must be the object's): every
night but the last is fitted (``nights.fit``; nights are split by gaps over 6 h), and no truth is
scored.

Outputs: ``arrays.npz``, ``shape.obj`` (the recovered convex shape, metres), ``egi.csv``
(normals and areas in the fitted body frame), ``lightcurve.csv`` and the figures
``inversion_lightcurve``, ``inversion_egi``, ``inversion_shapes``, ``inversion_observability``.
Assumptions: those of :func:`~cssat.inversion.egi_operator` (no shadowing in the model,
single scattering, one BRDF shape) and :func:`~cssat.inversion.estimate_spin` (a
principal-axis spin) or :func:`~cssat.inversion.estimate_tumbling` (torque-free rotation); the
simulated truth has shadows when ``shadows`` is true.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param

log = logging.getLogger("cssat")

#: a recovered normal "carries weight" when it holds at least this share of the recovered area
EGI_WEIGHT_SHARE = 0.01
#: the true EGI's area within this angle of a weighted recovered normal is "recovered"
EGI_MATCH_DEG = 10.0


def _opts(node: Any) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else dict(node or {})


def night_mask(scenario: Any, sun_alt_max_deg: float, min_elevation_deg: float) -> np.ndarray:
    """``(T,)`` the samples of a night's observation: the Sun below ``sun_alt_max_deg`` at the
    station (the geocentric vertical: within 0.2° of the geodetic one), the object above
    ``min_elevation_deg`` and wholly sunlit."""
    up = scenario.r_obs / np.linalg.norm(scenario.r_obs, axis=1, keepdims=True)
    d = scenario.r_sun - scenario.r_obs
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sun_alt = np.degrees(np.arcsin(np.clip((d * up).sum(1), -1, 1)))
    return (sun_alt < sun_alt_max_deg) & (scenario.elevation_deg > min_elevation_deg) & (scenario.sunlit >= 1)


def night_index(seconds: np.ndarray, gap_s: float = 6 * 3600.0) -> np.ndarray:
    """``(T,)`` the night of each sample: a new night after a gap longer than ``gap_s``."""
    return np.concatenate([[0], np.cumsum(np.diff(seconds) > gap_s)]).astype(int)


def egi_recovered_share(true_normals: np.ndarray, true_areas: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                        *, within_deg: float = EGI_MATCH_DEG, weight_share: float = EGI_WEIGHT_SHARE) -> float:
    """The share of the true EGI's area within ``within_deg`` of a recovered normal holding at
    least ``weight_share`` of the recovered area (both EGIs in one frame)."""
    if areas.size == 0 or true_areas.sum() <= 0:
        return 0.0
    heavy = normals[areas >= weight_share * areas.sum()]
    if heavy.size == 0:
        return 0.0
    near = (true_normals @ heavy.T).max(1) >= np.cos(np.radians(within_deg))
    return float(true_areas[near].sum() / true_areas.sum())


def _check_search(search: dict[str, Any]) -> None:
    """The spin search's settings (``inversion.*``), each in its range."""
    for key, lo in (("n_poles", 1), ("n_starts", 1), ("n_refine", 1), ("coarse_normals", 16), ("coarse_samples", 16),
                    ("max_samples", 16)):
        if key in search:
            int_param(search[key], f"inversion.{key}", lo, 10**6)
    lo = float_param(search.get("min_period_s", 60.0), "inversion.min_period_s", 0.0, open_lo=True)
    float_param(search.get("max_period_s", 86400.0), "inversion.max_period_s", lo, open_lo=True)


#: the most time steps a simulated scenario may hold (nights.n × 86400 / scenario.step_s)
MAX_STEPS = 2_000_000


def _check_size(cfg: Any, n_nights: int, n_faces: int, searched: bool = True) -> None:
    """The simulated scenario's steps against the periods searched (the shortest at least two
    cadences: Nyquist) and the memory of its light curve (facet brightness and visibility per
    step), before any is computed."""
    from cssat.experiments.resources import check_memory

    if cfg.get("observations"):
        return
    step = float_param(cfg.scenario.step_s, "scenario.step_s", 0.0, open_lo=True)
    inv = cfg.get("inversion") or {}
    for key, node in (("inversion.min_period_s", inv), ("inversion.tumbling.min_period_s", inv.get("tumbling") or {})):
        lo = node.get("min_period_s")
        if lo is not None and float(lo) < 2 * step:
            raise FieldError(key, f"{float(lo):g} s is under two cadences (scenario.step_s = {step:g} s): a shorter period "
                                  f"is aliased; raise it to {2 * step:g} s or more, or shorten the cadence")
    n_steps = int(n_nights * 86400.0 / step) + 1
    if n_steps > MAX_STEPS:
        raise FieldError("scenario.step_s", f"{step:g} s over {n_nights} nights is {n_steps:.3g} steps, more than "
                                            f"{MAX_STEPS:.0e}: lengthen the cadence")
    parts = {"scenario (T, ~20 values)": n_steps * 20 * 8, "facet brightness and visibility (T, F)": n_steps * max(n_faces, 1) * 8 * 4}
    check_memory(parts, None if cfg.get("memory_limit_gb") is None else float(cfg.memory_limit_gb),
                 "lengthen scenario.step_s or lower nights.n")


#: a measured light curve's least for an inversion: samples, nights (one pass holds one geometry)
MIN_OBSERVED_SAMPLES = 50
MIN_OBSERVED_NIGHTS = 2


def _check_constrained(observed: Any, t: np.ndarray, night: np.ndarray) -> None:
    """Refuse a measured light curve the inversion cannot constrain: too few usable samples, or
    one night (a pass holds one Sun–observer geometry: the pole and the shape are then not
    determined), naming what is missing."""
    n_nights = int(night.max() + 1) if len(night) else 0
    missing = []
    if len(t) < MIN_OBSERVED_SAMPLES:
        missing.append(f"at least {MIN_OBSERVED_SAMPLES} sunlit samples (the file gives {len(t)})")
    if n_nights < MIN_OBSERVED_NIGHTS:
        missing.append(f"at least {MIN_OBSERVED_NIGHTS} nights (the file holds {n_nights}: one pass does not constrain a "
                       "pole or a shape)")
    if missing:
        raise FieldError("observations", f"{Path(observed.source).name or 'the light curve'} cannot constrain an "
                                         f"inversion: it needs {' and '.join(missing)}; experiment=characterise "
                                         "gives what it does hold")


def run(cfg: Any, out_dir: Any) -> dict[str, Any]:
    """Run the inversion experiment ``cfg`` into ``out_dir`` and return its metrics."""
    import torch

    from cssat.experiments.build import build, build_model
    from cssat.experiments.context import Run
    from cssat.experiments.files import write_csv, write_npz
    from cssat.experiments.scene import build_scenario, read_observations
    from cssat.inversion import egi, estimate_spin, estimate_tumbling, estimate_tumbling_periods, invert_convex, observability
    from cssat.inversion.shape import convex_iou
    from cssat.optics.lightcurve import simulate_light_curve
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
    from cssat.scene.attitude import to_body
    from cssat.scene.attitudes import Spin, Tumbling

    run_ = Run.from_config(cfg, out_dir)
    with run_.stage("setup"):
        nights_cfg = cfg.get("nights") or {}
        inv = cfg.get("inversion") or {}
        n_nights = int_param(nights_cfg.get("n", 3), "nights.n", 1, 366)
        n_fit = nights_cfg.get("fit")  # null: all nights but the last
        n_fit = None if n_fit is None else int_param(n_fit, "nights.fit", 1, 366)
        sun_alt = float_param(nights_cfg.get("sun_alt_max_deg", -12.0), "nights.sun_alt_max_deg", -90.0, 90.0)
        min_el = float_param(nights_cfg.get("min_elevation_deg", 20.0), "nights.min_elevation_deg", -90.0, 90.0)
        spin_mode = choice_param(inv.get("spin", "auto"), "inversion.spin", ("auto", "search", "tumbling", "known"))
        tumble = {k: v for k, v in _opts(inv.get("tumbling")).items() if v is not None}
        from cssat.experiments.context import as_field
        from cssat.inversion.tumble import check_tumbling_options

        with as_field("inversion.tumbling"):  # every option of the tumbling search, before any work
            check_tumbling_options(**tumble)
        if n_fit is not None and n_fit > n_nights and not cfg.get("observations"):
            raise FieldError("nights.fit", f"{n_fit} nights fitted of the {n_nights} observed (nights.n): at most {n_nights}")
        n_normals = int_param(inv.get("n_normals", 2000), "inversion.n_normals", 16, 20000)
        search_normals = int_param(inv.get("search_normals", 1000), "inversion.search_normals", 16, 20000)
        from cssat.inversion.recover import METHODS, lam_param

        method = choice_param(inv.get("method", "nnls"), "inversion.method", METHODS)
        checks = {"lam": lam_param, "n_nonzero": lambda v, f: int_param(v, f, 1), "tv_neighbours": lambda v, f: int_param(v, f, 1, 32)}
        recover_opts = {k: check(inv[k], f"inversion.{k}") for k, check in checks.items() if inv.get(k) is not None}
        closure = float_param(inv.get("closure", 1.0), "inversion.closure", 0.0)
        search = {k: inv[k] for k in ("n_poles", "n_starts", "n_refine", "coarse_normals", "coarse_samples", "max_samples",
                                      "min_period_s", "max_period_s") if inv.get(k) is not None}
        _check_search(search)  # the spin search's settings, before any work, with their full keys
        mesh = build_model(cfg.model)
        _check_size(cfg, n_nights, len(mesh.faces) if hasattr(mesh, "faces") else 0, spin_mode != "known")
        attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        brdf = build(cfg.brdf, "brdf") if cfg.get("brdf") is not None and cfg.brdf.get("_target_") else None
        noise = build(cfg.get("noise"), "noise")
        observed = read_observations(cfg)
        if observed is not None:
            from cssat.experiments.scene import check_elements

            check_elements(cfg, observed)
    metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": mesh.name, "seed": run_.seed}

    with run_.stage("scene"):
        if observed is not None:
            scenario = build_scenario(cfg, observed.times_utc)
            keep = np.isfinite(observed.fluxes()) & (scenario.sunlit > 0)
        else:
            sc = cfg.scenario
            step = float_param(sc.step_s, "scenario.step_s", 0.0, open_lo=True)
            from omegaconf import OmegaConf, open_dict

            cfg2 = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
            with open_dict(cfg2):
                cfg2.scenario.n_steps = int(round(n_nights * 86400.0 / step))
                cfg2.scenario.times = None
            scenario = build_scenario(cfg2)
            keep = night_mask(scenario, sun_alt, min_el)
        if not keep.any():
            raise FieldError("nights", "no sample is observable (night, elevation, sunlit): widen nights.* or check scenario.*")
        seconds_all = (scenario.times - scenario.times[0]) / np.timedelta64(1, "s")
        t = seconds_all[keep]
        night = night_index(t)
        metrics.update(n_samples=int(keep.sum()), n_nights_observed=int(night.max() + 1))
        if observed is not None:
            _check_constrained(observed, t, night)
            if observed.ranges_km is not None:  # the file's own range against the element set's
                metrics["range_diff_km_median"] = float(np.median(np.abs(scenario.range_km - observed.ranges_km)[keep]))

    with run_.stage("light_curve"):
        unit = ((scenario.range_km * 1e3) ** 2 / SOLAR_IRRADIANCE_W_M2)[keep]  # W/m² → per unit irradiance and range
        sun_in, obs_in = scenario.sun_dir[keep], scenario.obs_dir[keep]
        true_frames = None
        if attitude is not None or observed is None:
            from cssat.scene.attitude import nadir_pointing_frame

            frames_all = attitude.frames(scenario) if attitude is not None else nadir_pointing_frame(scenario.r_sat, scenario.v_sat)
            true_frames = frames_all[keep]
        if observed is not None:
            flux_w = observed.fluxes()[keep]
            err = observed.flux_errors()
            sigma_w = err[keep] if err is not None else None
            clean_w = None
        else:
            lc = simulate_light_curve(mesh, scenario, shadows=bool(cfg.get("shadows", True)), attitude=attitude, brdf=brdf)
            clean_w = lc.flux.numpy()[keep]
            gen = torch.Generator().manual_seed(run_.seed)
            y = torch.as_tensor(clean_w, dtype=torch.float64)[None]
            ref = y.mean(-1) if getattr(noise, "magnitude", None) is not None else None
            flux_w = noise(y, gen, flux=ref)[0].numpy() if ref is not None else noise(y, gen)[0].numpy()
            var = noise.variance(torch.as_tensor(flux_w)[None], flux=ref)[0].numpy() if hasattr(noise, "variance") else None
            sigma_w = np.sqrt(var) if var is not None and np.all(var > 0) else None
        y_unit = flux_w * unit
        sigma = sigma_w * unit if sigma_w is not None else None
        if n_fit is None:
            n_fit = max(int(night.max()), 1)
        fit = night < n_fit
        held = ~fit
        metrics.update(n_fit=int(fit.sum()), n_heldout=int(held.sum()), **noise.describe())
        if sigma is not None:
            metrics["noise_relative_median"] = float(np.median(sigma / np.maximum(np.abs(y_unit), 1e-300)))

    with run_.stage("spin"):
        # one period or two: a tumbling (non-principal-axis) light curve has two fundamental frequencies
        try:
            tp = estimate_tumbling_periods(t[fit], y_unit[fit], sigma=None if sigma is None else sigma[fit],
                                           min_period_s=float(inv.get("min_period_s") or 60.0),
                                           max_period_s=float(inv.get("max_period_s") or 86400.0))
            metrics.update(lc_tumbling=tp["tumbling"], lc_delta_bic=tp["delta_bic"], lc_periods_s=[float(p) for p in tp["periods_s"]],
                           lc_single_period_s=tp["single_period_s"])
            if tp["tumbling"] and (spin_mode == "search" or (spin_mode == "auto" and observed is not None)):
                log.warning("inversion: the light curve has two fundamental periods (%.1f s, %.1f s; ΔBIC %.0f): it looks "
                            "tumbling, and the spin search assumes a principal-axis rotation (inversion.spin=tumbling "
                            "searches a torque-free tumbling state)", *tp["periods_s"], tp["delta_bic"])
        except FieldError as e:  # too few samples or no second frequency: the period analysis is skipped
            tp = None
            log.info("inversion: no two-period analysis (%s)", e)
        if spin_mode == "auto":  # a spin attitude is searched as one, a tumbling one as one, a file as a spin
            # (the 2-D series' BIC also prefers two periods for a spinner seen over changing geometry: a
            # file's tumbling search is asked for, inversion.spin=tumbling, not guessed)
            if isinstance(attitude, Tumbling):
                spin_mode = "tumbling"
            elif observed is not None or isinstance(attitude, Spin):
                spin_mode = "search"
            else:
                spin_mode = "known"
        if spin_mode == "known" and true_frames is None:
            raise FieldError("inversion.spin", "'known' needs an attitude model (attitude=...) for a measured light curve")
        sol = None
        if spin_mode == "search":
            sol = estimate_spin(t[fit], y_unit[fit], sun_in[fit], obs_in[fit], sigma=None if sigma is None else sigma[fit],
                                brdf=brdf, frame=getattr(attitude, "frame", "ecliptic"), n_normals=search_normals, **search)
            frames = sol.frames(t)
            metrics.update(sol.describe())
            metrics["spin_synodic_period_s"] = float(sol.synodic["period_s"])
        elif spin_mode == "tumbling":
            sol = estimate_tumbling(t[fit], y_unit[fit], sun_in[fit], obs_in[fit], sigma=None if sigma is None else sigma[fit],
                                    brdf=brdf, frame=getattr(attitude, "frame", "ecliptic"), **tumble)
            frames = sol.frames(t)
            metrics.update(sol.describe())
        else:
            frames = true_frames
        metrics.update(spin=spin_mode, attitude_known=spin_mode == "known")
        sun_b, obs_b = to_body(frames, sun_in), to_body(frames, obs_in)

    with run_.stage("invert"):
        res = invert_convex(y_unit[fit], sun_b[fit], obs_b[fit], brdf=brdf or "lambert", n_normals=n_normals,
                            sigma=None if sigma is None else sigma[fit], method=method, closure=closure,
                            **recover_opts)
        from cssat.inversion import egi_operator

        model_unit = egi_operator(sun_b, obs_b, res.normals, brdf).matrix().numpy() @ res.areas if res.areas.size else np.zeros_like(t)
        resid = y_unit - model_unit
        noise_rms = lambda m: float(np.sqrt(np.mean(sigma[m] ** 2))) if sigma is not None and m.any() else None  # noqa: E731
        rms = lambda m: float(np.sqrt(np.mean(resid[m] ** 2))) if m.any() else None  # noqa: E731
        metrics.update(egi_n_normals=int(res.areas.size), egi_area_m2=float(res.areas.sum()), fit_rms=rms(fit),
                       fit_rms_over_noise=(rms(fit) / noise_rms(fit)) if noise_rms(fit) else None,
                       heldout_rms=rms(held), heldout_rms_over_noise=(rms(held) / noise_rms(held)) if noise_rms(held) and held.any() else None,
                       heldout_rms_relative=(rms(held) / float(np.sqrt(np.mean(y_unit[held] ** 2)))) if held.any() else None,
                       shape_volume_m3=float(res.mesh.volume) if res.mesh is not None else None,
                       **{f"inversion_{k}": v for k, v in res.info.items() if isinstance(v, (int, float, str)) or v is None})
        obs_info = observability(sun_b[fit], obs_b[fit], res_grid := _grid(n_normals), brdf=brdf)
        metrics.update(observability_rank=obs_info["effective_rank"],
                       observability_seen_share=float(obs_info["seen"].mean()))

    truth = {}
    with run_.stage("score"):
        if observed is None and true_frames is not None:
            tn, ta = egi(mesh)
            # the true body normals in the fitted body frame at t = 0
            to_fit = frames[0] @ true_frames[0].T
            tn_fit = tn @ to_fit.T
            truth = {"true_normals": tn_fit, "true_areas": ta}
            metrics["egi_recovered_share"] = egi_recovered_share(tn_fit, ta, res.normals, res.areas)
            if res.mesh is not None:
                import trimesh

                hull = trimesh.convex.convex_hull(np.asarray(mesh.vertices) @ to_fit.T)
                metrics["shape_iou_hull"] = convex_iou(hull, res.mesh)
            if isinstance(attitude, Tumbling) and spin_mode == "tumbling":
                from cssat.inversion.spin import _separation_deg
                from cssat.inversion.tumble import torque_free_invariants

                tr = torque_free_invariants(attitude.inertia, attitude.q0, attitude.omega0, sol.state.frame)
                if tr is not None:
                    st = sol.state
                    e_w, e_p = abs(st.f_omega_hz / tr["f_omega_hz"] - 1), abs(st.f_phi_hz / tr["f_phi_hz"] - 1)
                    metrics.update(pole_error_deg=_separation_deg((st.lon_deg, st.lat_deg), (tr["L_lon_deg"], tr["L_lat_deg"])),
                                   period_error_relative=max(e_w, e_p), tumble_P_omega_error_relative=e_w,
                                   tumble_P_phi_error_relative=e_p, tumble_i1_error=st.i1 - tr["i1"], tumble_i2_error=st.i2 - tr["i2"],
                                   tumble_true_P_omega_s=1 / tr["f_omega_hz"], tumble_true_P_phi_s=1 / tr["f_phi_hz"],
                                   tumble_true_i1=tr["i1"], tumble_true_i2=tr["i2"], tumble_mode_correct=st.short_axis == tr["short_axis"])
            if isinstance(attitude, Spin) and sol is not None:
                metrics["period_error_relative"] = abs(sol.period_s - abs(attitude.period_s)) / abs(attitude.period_s)
                from cssat.inversion.spin import _separation_deg

                lon, lat = attitude.pole_lon_deg, attitude.pole_lat_deg
                if attitude.period_s < 0:  # a retrograde spin is a prograde one about the opposite pole
                    lon, lat = lon + 180.0, -lat
                metrics["pole_error_deg"] = _separation_deg((sol.pole_lon_deg, sol.pole_lat_deg), (lon, lat))

    with run_.stage("write"):
        out = Path(out_dir)
        write_npz(out / "arrays.npz", times=t, epoch_utc=np.array(str(scenario.times[0])), night=night, fit=fit,
                  flux=y_unit, sigma=sigma if sigma is not None else np.full_like(t, np.nan),
                  clean=clean_w * unit if clean_w is not None else np.full_like(t, np.nan), model=model_unit,
                  normals=res.normals, areas=res.areas, sun_body=sun_b, obs_body=obs_b,
                  singular_values=obs_info["singular_values"], leverage=obs_info["leverage"], grid_normals=res_grid,
                  **truth)
        write_csv(out / "egi.csv", [{"nx": float(n[0]), "ny": float(n[1]), "nz": float(n[2]), "area_m2": float(a)}
                                    for n, a in zip(res.normals, res.areas)])
        write_csv(out / "lightcurve.csv", [
            {"time_utc": f"{np.datetime_as_string(tt, unit='ms')}Z", "flux_W_m2": float(f), "flux_err_W_m2": float(s) if s == s else "",
             "model_W_m2": float(m), "night": int(n), "fitted": bool(ff)}
            for tt, f, s, m, n, ff in zip(scenario.times[keep], flux_w, sigma_w if sigma_w is not None else np.full_like(t, np.nan),
                                          model_unit / unit, night, fit)])
        if res.mesh is not None:
            from cssat._tmpfiles import atomic_write

            atomic_write(out / "shape.obj", lambda tmp: res.mesh.export(str(tmp), file_type="obj"))
        _figures(run_, t, night, fit, y_unit, sigma, model_unit, res, truth, mesh, frames, true_frames, obs_info, res_grid, metrics)
    metrics.update(run_.timings())
    log.info("inversion: %d samples over %d nights, %s%s, EGI %d normals, held-out rms %s× noise",
             metrics["n_samples"], metrics["n_nights_observed"],
             repr(sol) if sol is not None else "attitude known (oracle)",
             f", pole error {metrics['pole_error_deg']:.2f}°" if "pole_error_deg" in metrics else "",
             metrics["egi_n_normals"], f"{metrics['heldout_rms_over_noise']:.2f}" if metrics.get("heldout_rms_over_noise") else "-")
    return metrics


def _grid(n: int) -> np.ndarray:
    from cssat.inversion import fibonacci_sphere

    return fibonacci_sphere(min(n, 2000)).numpy()


def _figures(run_, t, night, fit, y, sigma, model, res, truth, mesh, frames, true_frames, obs_info, grid, metrics) -> None:
    from cssat.plots import save_figure
    from cssat.plots.inversion import egi_figure, inversion_lightcurve_figure, observability_figure, shapes_figure

    save_figure(inversion_lightcurve_figure(t / 3600.0, y, sigma, model, fit), run_.figure("inversion_lightcurve"))
    save_figure(egi_figure(res.normals, res.areas, truth.get("true_normals"), truth.get("true_areas")), run_.figure("inversion_egi"))
    if res.mesh is not None:
        true_mesh = None
        if truth:
            true_mesh = (np.asarray(mesh.vertices) @ (frames[0] @ true_frames[0].T).T, np.asarray(mesh.faces))
        save_figure(shapes_figure(res.mesh, true_mesh, metrics.get("shape_iou_hull")), run_.figure("inversion_shapes"))
    save_figure(observability_figure(grid, obs_info["leverage"], obs_info["seen"], obs_info["singular_values"]),
                run_.figure("inversion_observability"))
