"""The EGI forward model's last stages (:class:`~cssat.experiments.forward.egi.EGILightCurve`):
the EGI and its convex shape solved from the fitted nights and the held-out nights predicted;
the scores against the truth (the true EGI and hull in the fitted body frame, the pole and
periods of the true attitude); the arrays, tables and figures."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cssat._tmpfiles import atomic_write
from cssat.experiments.context import Run
from cssat.experiments.files import write_csv, write_npz
from cssat.plots import save_figure
from cssat.scene.attitudes import Spin, Tumbling
from cssat.scene.mesh import Mesh

__all__ = ["EGISolution", "solve_egi", "true_egi", "score_truth", "write_egi", "egi_recovered_share", "rms", "typical", "chi2_n",
           "night_chi2_n", "EGI_WEIGHT_SHARE", "EGI_MATCH_DEG"]

#: a recovered normal "carries weight" when it holds at least this share of the recovered area
EGI_WEIGHT_SHARE = 0.01
#: the true EGI's area within this angle of a weighted recovered normal is "recovered"
EGI_MATCH_DEG = 10.0


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


def _grid(n: int) -> np.ndarray:
    from cssat.inversion import fibonacci_sphere  # heavy: cssat.inversion imports torch

    return fibonacci_sphere(min(n, 2000)).numpy()


def rms(x: np.ndarray, m: np.ndarray) -> float | None:
    """The rms of ``x`` over the samples ``m`` (bool, like ``x``); None without samples."""
    return float(np.sqrt(np.mean(x[m] ** 2))) if m.any() else None


def typical(resid: np.ndarray, sigma: np.ndarray | None, m: np.ndarray) -> float | None:
    """The typical residual over the noise on the samples ``m``: ``median |r/σ| / 0.6745`` (1 for
    residuals at the noise, Gaussian), which a few unpredicted glints do not dominate as they do
    the rms; None without ``sigma`` or samples."""
    return float(np.median(np.abs(resid[m] / sigma[m])) / 0.6745) if sigma is not None and m.any() else None


def chi2_n(resid: np.ndarray, sigma: np.ndarray | None, m: np.ndarray) -> float | None:
    """``mean (r/σ)²`` over the samples ``m``: the reduced χ² a held-out test reads (1 for a model
    at the noise; a misfit on the faint samples, where σ is smallest, weighs more here than in the
    rms); None without ``sigma`` or samples."""
    return float(np.mean((resid[m] / sigma[m]) ** 2)) if sigma is not None and m.any() else None


def night_chi2_n(resid: np.ndarray, sigma: np.ndarray | None, night: np.ndarray) -> list[float] | None:
    """:func:`chi2_n` over each night's samples, in the nights' order (``night (T,)`` each
    sample's night): whether the held-out night is worse than the fitted ones (a model that
    overfits) or all alike (a model whose misfit is its own, everywhere); None without ``sigma``."""
    if sigma is None:
        return None
    return [chi2_n(resid, sigma, night == k) for k in np.unique(night)]


_rms, _typical = rms, typical  # the old private names, kept for old imports


@dataclass
class EGISolution:
    """What the EGI model's ``solve`` stage hands on (``T`` samples, ``K`` normals with area)."""

    res: Any  #: :func:`~cssat.inversion.invert_convex`'s result: ``normals (K, 3)``, ``areas (K,)``, the convex ``mesh``
    model_unit: np.ndarray  #: ``(T,)`` the fitted model over every sample, per unit irradiance and range (m²)
    grid: np.ndarray  #: ``(G, 3)`` the normals of the observability grid
    obs_info: dict[str, Any]  #: :func:`~cssat.inversion.observability` on the fitted samples
    metrics: dict[str, Any] = field(default_factory=dict)
    convex_model_unit: Any = None  #: ``(T,)`` the convex model's, when a box-wing replaced it (``inversion.shape=parametric``)
    param_mesh: Any = None  #: the fitted box-wing's mesh (metres, the fitted body frame), if fitted


def solve_egi(p: Any, m: Any, a: Any) -> EGISolution:
    """The EGI on ``inversion.n_normals`` normals by the ``solver`` group's solver and its convex
    shape from the fitted samples (:func:`~cssat.inversion.invert_convex`), the model over every
    sample, the fit and held-out residuals against the noise, and the observability of the
    fitted geometry; ``p``, ``m``, ``a``: the plan, the measured samples and the attitude."""
    from cssat.inversion import invert_convex, observability  # heavy: cssat.inversion imports torch
    from cssat.inversion.egi import Lobes  # heavy: cssat.inversion.egi imports torch

    fit, held, sigma, y, inv = m.fit, m.held, m.sigma, m.y, p.settings.inversion
    res = invert_convex(y[fit], a.sun_b[fit], a.obs_b[fit], brdf=p.model_brdf or "lambert", n_normals=inv.n_normals,
                        sigma=None if sigma is None else sigma[fit], closure=inv.closure, solver=p.solver)
    model_unit = res.predict(a.sun_b, a.obs_b)
    resid = y - model_unit
    noise_fit = rms(sigma, fit) if sigma is not None else None
    noise_held = rms(sigma, held) if sigma is not None else None
    rms_fit, rms_held = rms(resid, fit), rms(resid, held)
    metrics: dict[str, Any] = dict(
        egi_n_normals=int(res.areas.size), egi_area_m2=float(res.areas.sum()), fit_rms=rms_fit,
        fit_rms_over_noise=(rms_fit / noise_fit) if noise_fit else None,
        heldout_rms=rms_held, heldout_rms_over_noise=(rms_held / noise_held) if noise_held and held.any() else None,
        heldout_chi2_n=chi2_n(resid, sigma, held), fit_chi2_n=chi2_n(resid, sigma, fit),
        night_chi2_n=night_chi2_n(resid, sigma, m.night),
        heldout_rms_relative=(rms_held / float(np.sqrt(np.mean(y[held] ** 2)))) if held.any() else None,
        fit_typical_over_noise=typical(resid, sigma, fit), heldout_typical_over_noise=typical(resid, sigma, held),
        shape_volume_m3=float(res.mesh.volume) if res.mesh is not None else None,
        **{f"inversion_{k}": v for k, v in res.info.items() if isinstance(v, (int, float, str)) or v is None})
    grid = _grid(inv.n_normals)
    # the observability of the EGI on the grid: for an EGI per lobe, of its diffuse one (the geometry's)
    obs_info = observability(a.sun_b[fit], a.obs_b[fit], grid, brdf=None if isinstance(p.model_brdf, Lobes) else p.model_brdf)
    metrics.update(observability_rank=obs_info["effective_rank"], observability_seen_share=float(obs_info["seen"].mean()))
    return EGISolution(res, model_unit, grid, obs_info, metrics)


def true_egi(p: Any, m: Any, a: Any) -> dict[str, np.ndarray]:
    """The true EGI (``true_normals (N, 3)``, ``true_areas (N,)``, m²) in the fitted body frame
    at t = 0; ``p``, ``m``, ``a``: the plan, the measured samples (with the true frames), the attitude."""
    from cssat.inversion import egi  # heavy: cssat.inversion imports torch

    mesh = p.mesh
    if p.brdf is not None:  # one BRDF object reflects every facet alike (cd unused): the true EGI is the bare areas
        mesh = Mesh(mesh.vertices, mesh.faces, 1.0, 0.0, name=mesh.name)
    tn, ta = egi(mesh)
    to_fit = a.frames[0] @ m.true_frames[0].T  # the true body normals in the fitted body frame at t = 0
    return {"true_normals": tn @ to_fit.T, "true_areas": ta}


def score_truth(p: Any, m: Any, a: Any, sol: EGISolution) -> dict[str, Any]:
    """The recovered EGI and shape against the truth (:func:`true_egi`), in the fitted body frame
    at t = 0, and the attitude's pole and periods against the true spin or tumbling state."""
    from cssat.inversion.shape import convex_iou  # heavy: cssat.inversion.shape imports torch

    res, attitude, spin = sol.res, p.attitude, a.sol
    metrics: dict[str, Any] = {}
    truth = true_egi(p, m, a)
    tn_fit, ta = truth["true_normals"], truth["true_areas"]
    to_fit = a.frames[0] @ m.true_frames[0].T
    metrics["egi_recovered_share"] = egi_recovered_share(tn_fit, ta, res.normals, res.areas)
    if m.clean_w is not None and m.held.any():  # what the true mesh itself reaches on the held-out nights, at this noise
        true_resid = m.y - m.clean_w * m.unit
        true_rms = rms(true_resid, m.held)
        metrics["true_heldout_rms"] = true_rms
        if m.sigma is not None:
            metrics["true_heldout_rms_over_noise"] = true_rms / rms(m.sigma, m.held)
            metrics["true_heldout_chi2_n"] = chi2_n(true_resid, m.sigma, m.held)
            metrics["true_fit_chi2_n"] = chi2_n(true_resid, m.sigma, m.fit)
            metrics["true_night_chi2_n"] = night_chi2_n(true_resid, m.sigma, m.night)
        if sol.metrics.get("heldout_rms") is not None and true_rms > 0:
            metrics["heldout_rms_over_true"] = sol.metrics["heldout_rms"] / true_rms
    if res.mesh is not None:
        import trimesh  # heavy: trimesh, only for score_truth()

        hull = trimesh.convex.convex_hull(np.asarray(p.mesh.vertices) @ to_fit.T)
        metrics["shape_iou_hull"] = convex_iou(hull, res.mesh)
    if isinstance(attitude, Tumbling) and p.spin_mode == "tumbling":
        metrics.update(_tumbling_errors(attitude, spin.state))
    if isinstance(attitude, Spin) and spin is not None:
        from cssat.inversion.spin_errors import separation_deg  # heavy: cssat.inversion imports torch

        metrics["period_error_relative"] = abs(spin.period_s - abs(attitude.period_s)) / abs(attitude.period_s)
        lon, lat = attitude.pole_lon_deg, attitude.pole_lat_deg
        if attitude.period_s < 0:  # a retrograde spin is a prograde one about the opposite pole
            lon, lat = lon + 180.0, -lat
        metrics["pole_error_deg"] = separation_deg((spin.pole_lon_deg, spin.pole_lat_deg), (lon, lat))
        refined = sol.metrics.get("parametric_spin_pole_lon_deg")
        if refined is not None:  # the spin refined through the shadowed box-wing (inversion.parametric.refine_spin)
            metrics["parametric_spin_pole_error_deg"] = separation_deg(
                (refined, sol.metrics["parametric_spin_pole_lat_deg"]), (lon, lat))
    return metrics


def _tumbling_errors(attitude: Any, st: Any) -> dict[str, Any]:
    """A searched torque-free state ``st`` against the attitude's own invariants."""
    from cssat.inversion.spin_errors import separation_deg  # heavy: cssat.inversion imports torch
    from cssat.inversion.tumble import torque_free_invariants  # heavy: cssat.inversion.tumble imports torch

    tr = torque_free_invariants(attitude.inertia, attitude.q0, attitude.omega0, st.frame)
    if tr is None:
        return {}
    e_w, e_p = abs(st.f_omega_hz / tr["f_omega_hz"] - 1), abs(st.f_phi_hz / tr["f_phi_hz"] - 1)
    return dict(pole_error_deg=separation_deg((st.lon_deg, st.lat_deg), (tr["L_lon_deg"], tr["L_lat_deg"])),
                period_error_relative=max(e_w, e_p), tumble_P_omega_error_relative=e_w,
                tumble_P_phi_error_relative=e_p, tumble_i1_error=st.i1 - tr["i1"], tumble_i2_error=st.i2 - tr["i2"],
                tumble_true_P_omega_s=1 / tr["f_omega_hz"], tumble_true_P_phi_s=1 / tr["f_phi_hz"],
                tumble_true_i1=tr["i1"], tumble_true_i2=tr["i2"], tumble_mode_correct=st.short_axis == tr["short_axis"])


def write_egi(p: Any, m: Any, a: Any, sol: EGISolution, truth: dict[str, np.ndarray], metrics: dict[str, Any],
              run: Run) -> None:
    """``arrays.npz``, ``egi.csv``, ``lightcurve.csv``, ``shape.obj`` and the figures."""
    out, res, t, sigma = run.out_dir, sol.res, m.t, m.sigma
    write_npz(out / "arrays.npz", times=t, epoch_utc=np.array(str(m.scenario.times[0])), night=m.night, fit=m.fit,
              flux=m.y, sigma=sigma if sigma is not None else np.full_like(t, np.nan),
              clean=m.clean_w * m.unit if m.clean_w is not None else np.full_like(t, np.nan), model=sol.model_unit,
              normals=res.normals, areas=res.areas, sun_body=a.sun_b, obs_body=a.obs_b,
              singular_values=sol.obs_info["singular_values"], leverage=sol.obs_info["leverage"], grid_normals=sol.grid,
              **truth)
    write_csv(out / "egi.csv", [{"nx": float(n[0]), "ny": float(n[1]), "nz": float(n[2]), "area_m2": float(ar)}
                                for n, ar in zip(res.normals, res.areas)])
    sigma_w = m.sigma_w if m.sigma_w is not None else np.full_like(t, np.nan)
    write_csv(out / "lightcurve.csv", [
        {"time_utc": f"{np.datetime_as_string(tt, unit='ms')}Z", "flux_W_m2": float(v), "flux_err_W_m2": float(s) if s == s else "",
         "model_W_m2": float(mu), "night": int(n), "fitted": bool(ff)}
        for tt, v, s, mu, n, ff in zip(m.scenario.times[m.keep], m.flux_w, sigma_w, sol.model_unit / m.unit, m.night, m.fit)])
    if res.mesh is not None:
        atomic_write(out / "shape.obj", lambda tmp: res.mesh.export(str(tmp), file_type="obj"))
    _figures(p, m, a, sol, truth, metrics, run)


def _figures(p: Any, m: Any, a: Any, sol: EGISolution, truth: dict[str, np.ndarray], metrics: dict[str, Any],
             run: Run) -> None:
    from cssat.plots.inversion import (  # heavy: cssat.plots.inversion imports matplotlib
        egi_figure, inversion_lightcurve_figure, observability_figure, shapes_figure)

    res, obs_info = sol.res, sol.obs_info
    save_figure(inversion_lightcurve_figure(m.t / 3600.0, m.y, m.sigma, sol.model_unit, m.fit), run.figure("inversion_lightcurve"))
    save_figure(egi_figure(res.normals, res.areas, truth.get("true_normals"), truth.get("true_areas")), run.figure("inversion_egi"))
    if res.mesh is not None:
        true_mesh = None
        if truth:
            true_mesh = (np.asarray(p.mesh.vertices) @ (a.frames[0] @ m.true_frames[0].T).T, np.asarray(p.mesh.faces))
        save_figure(shapes_figure(res.mesh, true_mesh, metrics.get("shape_iou_hull")), run.figure("inversion_shapes"))
    save_figure(observability_figure(sol.grid, obs_info["leverage"], obs_info["seen"], obs_info["singular_values"]),
                run.figure("inversion_observability"))
