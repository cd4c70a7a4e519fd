"""The EGI forward model's optional non-convex stage (``inversion.shape=parametric``):
a box-wing (:mod:`cssat.inversion.parametric`) fitted through its Embree-shadowed light
curve, started from the convex EGI (in a searched spin's frame, turned about the pole first so
that the EGI's panels lie along ±y: :func:`~cssat.inversion.parametric_fit.box_wing_yaw`,
``inversion.parametric.yaw``; with ``inversion.parametric.aspects`` and ``plain_keep`` a multi-start over
the wings' aspect too: :func:`~cssat.inversion.parametric_fit.box_wing_starts`), then — with ``inversion.parametric.dishes``, ``wing_panels``, ``booms``,
``deck`` — the finer family from it and from its unfitted start (``parts_from``; :func:`~cssat.inversion.parametric_parts.fit_parts`: the
parts at generic places — a free pair's dishes at every pairing of them with ``parts_pairs`` —,
each start fitted briefly, the best ``parts_keep`` in full) — with ``inversion.parametric.shadow_resolution_m`` then polished with each
sub-facet's shadows resolved; its prediction of the held-out nights replaces the convex
one in the headline metrics (the convex one kept as ``convex_*``), its mesh written as
``shape_parametric.obj`` and scored by volume IoU against the true mesh (``shape_iou_true``)."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat._threads import one_thread, thread_map
from cssat._tmpfiles import atomic_write
from cssat.experiments.forward.egi_score import chi2_n, night_chi2_n, rms, typical
from cssat.scene.mesh import Mesh

__all__ = ["solve_parametric", "score_parametric", "write_parametric"]

log = logging.getLogger("cssat")


def solve_parametric(o: Any, m: Any, a: Any, sol: Any) -> None:
    """Fit the box-wing (settings ``o``: :class:`~cssat.models.egi.config.ParametricConfig`) on
    the fitted nights of ``m`` (the measured samples) in the attitude ``a``, started from the
    convex EGI of ``sol`` (:class:`~cssat.experiments.forward.egi_score.EGISolution`), and
    predict every sample: the convex model's metrics move to ``convex_*`` and the box-wing's take
    the headline keys (``sol`` updated in place: its ``model_unit``, ``convex_model_unit``,
    ``param_mesh`` and ``metrics``).

    The answer does not depend on the run's ``threads``: every fit's torch operations run on one
    thread, and the threads run independent fits at once instead (the plain multi-start, the parts'
    bases and brief fits, the twins' descents: :func:`cssat._threads.thread_map`)."""
    with one_thread() as workers:
        _solve(o, m, a, sol, workers)


def _solve(o: Any, m: Any, a: Any, sol: Any, workers: int) -> None:
    """:func:`solve_parametric` with torch on one thread and ``workers`` fits at once."""
    import torch  # heavy: torch, only to fit the box-wing

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility  # heavy: torch
    from cssat.inversion.parametric_fit import box_wing_starts, box_wing_yaw, fit_box_wing  # heavy: torch
    from cssat.scene.attitude import rot_z  # heavy: cssat.scene imports torch

    res, fit, held, sigma, y = sol.res, m.fit, m.held, m.sigma, m.y
    geo = dict(panels=o.panels, divisions=o.divisions)  # the plain box-wing's
    searched = a.metrics.get("spin") == "search"  # z on the pole, the phase about it arbitrary: the panels' axis unknown
    yaws = box_wing_yaw(res.normals, res.areas, panels=o.panels) if o.yaw == "egi" or (o.yaw == "auto" and searched) \
        else (0.0,)
    # the starts (turns × wing aspects) told apart by a brief fit's misfit on the fitted nights (or the start's:
    # yaw_brief=0), the best `plain_keep` fitted in full and the lowest loss kept: a multi-start
    starts = box_wing_starts(res.normals, res.areas, y[fit], a.sun_b[fit], a.obs_b[fit],
                             None if sigma is None else sigma[fit], yaws=yaws, aspects=o.aspects, cd0=o.cd0,
                             brief=o.yaw_brief, **geo)
    fit_kw = dict(sigma=None if sigma is None else sigma[fit], outer=o.outer, inner=o.inner, huber=o.huber,
                  visibility=o.visibility, softness=o.softness, albedos=o.albedos,
                  fixed=("cd_bus",) if o.albedo_prior else (),
                  resolution_m=o.shadow_resolution_m if o.resolved_search else None)

    def turned(psi_k):  # the box-wing's frame: the fitted body frame turned by R_z(−ψ) (rot_z is passive)
        R_k = rot_z(np.array([psi_k]))[0]
        return R_k, a.sun_b @ R_k.T, a.obs_b @ R_k.T

    def fit_from(psi_k, p0):  # (ψ, start, fitted p, its info)
        _, S_k, V_k = turned(psi_k)
        return (psi_k, p0, *fit_box_wing(y[fit], S_k[fit], V_k[fit], p0, **fit_kw, **geo))

    fits = thread_map(lambda s_k: fit_from(s_k[1], s_k[2]), starts[:o.plain_keep], workers)
    psi, p0, p, info = min(fits, key=lambda f: f[3]["loss"])  # the first on a tie
    R, S, V = turned(psi)
    parts, family, start, base = o.parts(), "plain", None, None
    if parts:  # the finer family from the plain fit and/or its start: its parts at generic places, each fitted briefly
        bases = {"fit": (("plain fit", p),), "start": (("plain start", p0),),
                 "both": (("plain fit", p), ("plain start", p0))}[o.parts_from]
        share = max(1, workers // len(bases))  # the bases at once, each base's fits on its share of the threads
        runs = thread_map(lambda lb: (lb[0], *_fit_parts_from(o, y[fit], S[fit], V[fit], lb[1], parts, fit_kw, lb[0],
                                                              share)), bases, workers)
        on, q, qi = min(runs, key=lambda r: r[2]["loss"])  # the first on a tie
        if qi["loss"] <= info["loss"]:  # it holds the plain box-wing (parts shrunk away): a higher loss is a local minimum
            p, info, family, start, base, geo = q, qi, "parts", qi["start"], on, o.family()
        else:
            log.warning("inversion.parametric: the finer family %s ended above the plain box-wing's loss (%.4g > %.4g, "
                        "a local minimum from its %d starts): the plain box-wing is kept", parts, qi["loss"],
                        info["loss"], sum(len(r[2]["briefs"]) for r in runs))
    res_m = o.shadow_resolution_m
    if res_m is not None:  # the shadows resolved below a sub-facet: a polish whose scored model is the resolved one
        p, info = fit_box_wing(y[fit], S[fit], V[fit], p, **dict(fit_kw, outer=o.resolved_outer, resolution_m=res_m),
                               **geo)
    kw = dict(range_km=1e-3, irradiance=1.0, **geo)
    if o.refine_spin and searched:  # a searched spin: a.sol is its SpinSolution
        p, R, S, V, refined = _refine_spin(o, m, a, p, psi, geo, workers)
        info = dict(info, params=dict(zip(info["params"], map(float, p))))
        sol.metrics.update(refined)
    elif o.refine_spin:
        log.warning("inversion.parametric.refine_spin: no searched spin to refine (the attitude was %s)",
                    a.metrics.get("spin"))
    vis = box_wing_visibility(p, S, V, resolution_m=res_m, **geo)
    sol.convex_model_unit = sol.model_unit
    sol.model_unit = box_wing_light_curve(torch.as_tensor(p), S, V, vis, **kw).numpy()
    bw = box_wing_mesh(p, **geo)
    sol.param_mesh = Mesh(np.asarray(bw.vertices) @ R, np.asarray(bw.faces), bw.cd, bw.cs, name=bw.name, part=bw.part,
                          part_names=bw.part_names)  # the fitted frame
    mt = sol.metrics
    for k in ("fit_rms", "fit_rms_over_noise", "heldout_rms", "heldout_rms_over_noise", "heldout_chi2_n", "fit_chi2_n",
              "night_chi2_n", "heldout_rms_relative", "fit_typical_over_noise", "heldout_typical_over_noise"):
        mt[f"convex_{k}"] = mt.get(k)
    resid = y - sol.model_unit
    rf, rh = rms(resid, fit), rms(resid, held)
    nf = rms(sigma, fit) if sigma is not None else None
    nh = rms(sigma, held) if sigma is not None else None
    mt.update(shape="parametric", fit_rms=rf, fit_rms_over_noise=rf / nf if nf else None, heldout_rms=rh,
              heldout_rms_over_noise=rh / nh if nh and held.any() else None, heldout_chi2_n=chi2_n(resid, sigma, held),
              fit_chi2_n=chi2_n(resid, sigma, fit), night_chi2_n=night_chi2_n(resid, sigma, m.night),
              heldout_rms_relative=rh / float(np.sqrt(np.mean(y[held] ** 2))) if held.any() else None,
              fit_typical_over_noise=typical(resid, sigma, fit), heldout_typical_over_noise=typical(resid, sigma, held),
              parametric_yaw_deg=float(np.degrees(psi)), parametric_start_aspect=float(p0[3] / p0[4]), parametric_family=family,
              parametric_parts_start=start, parametric_parts_base=base, parametric_shadow_resolution_m=res_m,
              **{f"parametric_{k}": v for k, v in info["params"].items()})


def _fit_parts_from(o: Any, y: np.ndarray, S: np.ndarray, V: np.ndarray, base: np.ndarray, parts: dict,
                    fit_kw: dict, label: str, workers: int = 1) -> tuple[np.ndarray, dict]:
    """:func:`~cssat.inversion.parametric_parts.fit_parts` on the fitted samples ``y``, ``S``, ``V``
    from the box-wing ``base (9,)`` (``label``: which one, for the log), with the stage's settings
    ``o`` (its starts: the mirror images, or every pairing with ``parts_pairs``): ``(p, info)``."""
    from cssat.inversion.parametric_parts import fit_parts, part_starts  # heavy: torch

    paired = part_starts(base, parts, pairs=True, cd0=o.cd0) if o.parts_pairs else None  # None: the mirror images
    q, qi = fit_parts(y, S, V, base, parts, cd0=o.cd0, starts=paired, keep=o.parts_keep, workers=workers, **fit_kw,
                      **{k: v for k, v in o.family().items() if k not in parts})
    log.info("inversion.parametric: the finer family on the %s: brief fits' losses %s; fitted in full %s", label,
             ", ".join(f"{lab} {loss:.4g}" for lab, loss in qi["briefs"]),
             ", ".join(f"{lab} {loss:.4g}" for lab, loss in qi["fulls"]))
    return q, qi


def _refine_spin(o: Any, m: Any, a: Any, p: np.ndarray, psi: float, family: dict, workers: int = 1) -> tuple:
    """The searched spin refined with the box-wing ``p`` (its ``family``'s keywords: panels, cells,
    parts) fitted in its frame turned by ``ψ``
    (:func:`~cssat.inversion.parametric_spin.refine_spin`, ``shape=True``; the held-out nights its
    verdict): ``(p, R, S, V, metrics)`` — the refined family, the turn ``R (3, 3)`` from the searched
    spin's body frame to the refined one at the first sample (vectors ``v @ R.T``), the body-frame Sun
    and observer ``(T, 3)`` of the refined spin, and ``parametric_spin_*`` metrics."""
    from cssat.inversion.parametric import box_wing_twin  # heavy: torch
    from cssat.inversion.parametric_spin import refine_spin  # heavy: torch
    from cssat.scene.attitude import spin_frame, to_body  # heavy: cssat.scene imports torch

    fit, held, sigma, sp = m.fit, m.held, m.sigma, a.sol
    ho = None if sigma is None or not held.any() else (m.t[held], m.y[held], m.sun_in[held], m.obs_in[held], sigma[held])
    series = (m.t[fit], m.y[fit], m.sun_in[fit], m.obs_in[fit])
    kw = dict(sigma=None if sigma is None else sigma[fit], frame=sp.frame, fixed=("cd_bus",) if o.albedo_prior else (),
              shape=True, heldout=ho, huber=o.huber, resolution_m=o.shadow_resolution_m, **family)

    def descend(q, phase_deg):  # the searched spin refined with the family q in the frame at that phase
        return refine_spin(*series, q, sp.pole_lon_deg, sp.pole_lat_deg, sp.period_s, phase_deg, **kw)

    phase = float(np.degrees(psi))
    starts = [(p, phase)]
    if o.spin_twin and family["panels"] == 2:  # the same object turned 180° about the pole: its own descent
        parts = {k: v for k, v in family.items() if k not in ("divisions", "dish_rings", "dish_segments")}
        starts.append((box_wing_twin(p, **parts), phase + 180.0))
    runs = thread_map(lambda st: descend(*st), starts, workers)
    r = min(runs, key=lambda q: q["loss"])  # the first on a tie
    frames = spin_frame(m.t, r["pole_lon_deg"], r["pole_lat_deg"], r["period_s"], r["phase_deg"], sp.frame)
    keys = ("pole_lon_deg", "pole_lat_deg", "period_s", "phase_deg", "pole_err_deg", "period_err_s", "formal_pole_err_deg",
            "formal_period_err_s", "softness_pole_shift_deg", "softness_period_shift_s", "rms_over_noise", "verdict",
            "verdict_why", "heldout_chi2", "heldout_n", "heldout_threshold", "kept_start")
    if r["kept_start"]:
        log.warning("inversion.parametric.refine_spin: the refinement ended above its start's loss (%.4g > %.4g): "
                    "%s kept", r["refined_loss"], r["start_loss"],
                    "the twin's start (the family turned 180° about the searched pole) is" if r is not runs[0]
                    else "the searched spin and the family's fit in its frame are")
    out = {f"parametric_spin_{k}": (None if isinstance(r[k], float) and not np.isfinite(r[k]) else r[k]) for k in keys}
    out.update(parametric_spin_twin=r is not runs[0], parametric_spin_losses=[float(q["loss"]) for q in runs])
    return (np.asarray(r["params"]), frames[0] @ a.frames[0].T, to_body(frames, m.sun_in), to_body(frames, m.obs_in),
            out)


def score_parametric(mesh: Any, sol: Any, to_fit: np.ndarray) -> dict[str, Any]:
    """``shape_iou_true``: the volume IoU of the true ``mesh`` (turned into the fitted body frame
    by ``to_fit (3, 3)``) and the box-wing of ``sol`` (closed bodies only: zero-thickness panels
    have no volume), and ``convex_iou_true`` for the convex shape; ``None`` (logged) where
    :func:`~cssat.inversion.volume.volume_iou` refuses (too few points inside either closed
    body for an estimate, or no closed body)."""
    from cssat.inversion.volume import volume_iou  # heavy: cssat.inversion imports torch

    def iou(key: str, fit: Any) -> None:
        try:
            out[key] = volume_iou(true, fit, n_points=100_000, seed=0)
        except FieldError as err:  # too few points in the union, no closed body: no number, not a wrong one
            log.warning("%s not scored: %s", key, err)
            out[key] = None

    out: dict[str, Any] = {}
    true = Mesh(np.asarray(mesh.vertices) @ to_fit.T, np.asarray(mesh.faces), 0.5, 0.0)
    if sol.param_mesh is not None:
        iou("shape_iou_true", sol.param_mesh)
    if sol.res.mesh is not None:
        iou("convex_iou_true", Mesh(np.asarray(sol.res.mesh.vertices), np.asarray(sol.res.mesh.faces), 0.5, 0.0))
    return out


def write_parametric(sol: Any, out: Any) -> None:
    """``shape_parametric.obj`` (metres, the fitted body frame) when the box-wing was fitted."""
    if sol.param_mesh is None:
        return
    atomic_write(out / "shape_parametric.obj", lambda tmp: sol.param_mesh.to_trimesh().export(str(tmp), file_type="obj"))
