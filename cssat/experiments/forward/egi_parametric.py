"""The EGI forward model's optional non-convex stage (``inversion.shape=parametric``):
a box-wing (:mod:`cssat.inversion.parametric`) fitted through its Embree-shadowed light
curve, started from the convex EGI; its prediction of the held-out nights replaces the convex
one in the headline metrics (the convex one kept as ``convex_*``), its mesh written as
``shape_parametric.obj`` and scored by volume IoU against the true mesh (``shape_iou_true``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat._tmpfiles import atomic_write
from cssat.experiments.forward.egi_score import rms, typical
from cssat.scene.mesh import Mesh

__all__ = ["check_shape_settings", "solve_parametric", "score_parametric", "write_parametric"]


def check_shape_settings(inv: Any) -> dict[str, Any]:
    """``inversion.shape`` and its ``inversion.parametric.*`` settings, checked before any work."""
    par = dict(inv.get("parametric") or {})
    unknown = sorted(set(par) - {"panels", "divisions", "outer", "inner", "huber", "cd0"})
    if unknown:
        raise FieldError(f"inversion.parametric.{unknown[0]}", "unknown; allowed: panels, divisions, outer, inner, huber, cd0")
    return dict(shape=choice_param(inv.get("shape", "convex"), "inversion.shape", ("convex", "parametric")),
                panels=int_param(par.get("panels", 2), "inversion.parametric.panels", 1, 2),
                divisions=int_param(par.get("divisions", 4), "inversion.parametric.divisions", 1, 16),
                outer=int_param(par.get("outer", 6), "inversion.parametric.outer", 1, 50),
                inner=int_param(par.get("inner", 40), "inversion.parametric.inner", 1, 500),
                huber=float_param(par.get("huber", 3.0), "inversion.parametric.huber", 0.0, open_lo=True),
                cd0=float_param(par.get("cd0", 0.3), "inversion.parametric.cd0", 0.0, 1.0, open_lo=True))


def solve_parametric(f: Any) -> None:
    """Fit the box-wing on the fitted nights (``f.fit``) and predict every sample; the convex
    model's metrics move to ``convex_*`` and the box-wing's take the headline keys."""
    import torch  # heavy: torch, only to fit the box-wing

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_mesh, box_wing_visibility  # heavy: torch
    from cssat.inversion.parametric_fit import box_wing_start, fit_box_wing  # heavy: torch

    o, res, fit, held, sigma, y = f.shape_opts, f.res, f.fit, f.held, f.sigma, f.y
    geo = dict(panels=o["panels"], divisions=o["divisions"])
    p0 = box_wing_start(res.normals, res.areas, panels=o["panels"], cd0=o["cd0"])
    p, info = fit_box_wing(y[fit], f.sun_b[fit], f.obs_b[fit], p0, sigma=None if sigma is None else sigma[fit],
                           outer=o["outer"], inner=o["inner"], huber=o["huber"], **geo)
    vis = box_wing_visibility(p, f.sun_b, f.obs_b, **geo)
    f.convex_model_unit = f.model_unit
    f.model_unit = box_wing_light_curve(torch.as_tensor(p), f.sun_b, f.obs_b, vis, range_km=1e-3, irradiance=1.0, **geo).numpy()
    f.param_mesh = box_wing_mesh(p, **geo)
    m = f.metrics
    for k in ("fit_rms", "fit_rms_over_noise", "heldout_rms", "heldout_rms_over_noise", "heldout_rms_relative",
              "fit_typical_over_noise", "heldout_typical_over_noise"):
        m[f"convex_{k}"] = m.get(k)
    resid = y - f.model_unit
    rf, rh = rms(resid, fit), rms(resid, held)
    nf = rms(sigma, fit) if sigma is not None else None
    nh = rms(sigma, held) if sigma is not None else None
    m.update(shape="parametric", fit_rms=rf, fit_rms_over_noise=rf / nf if nf else None, heldout_rms=rh,
             heldout_rms_over_noise=rh / nh if nh and held.any() else None,
             heldout_rms_relative=rh / float(np.sqrt(np.mean(y[held] ** 2))) if held.any() else None,
             fit_typical_over_noise=typical(resid, sigma, fit), heldout_typical_over_noise=typical(resid, sigma, held),
             **{f"parametric_{k}": v for k, v in info["params"].items()})


def score_parametric(f: Any, to_fit: np.ndarray) -> None:
    """``shape_iou_true``: the volume IoU of the true mesh (in the fitted body frame) and the
    box-wing (closed bodies only: zero-thickness panels have no volume), and ``convex_iou_true``
    for the convex shape."""
    from cssat.inversion.volume import volume_iou  # heavy: cssat.inversion imports torch

    true = Mesh(np.asarray(f.mesh.vertices) @ to_fit.T, np.asarray(f.mesh.faces), 0.5, 0.0)
    if getattr(f, "param_mesh", None) is not None:
        f.metrics["shape_iou_true"] = volume_iou(true, f.param_mesh, n_points=100_000, seed=0)
    if f.res.mesh is not None:
        cm = f.res.mesh
        f.metrics["convex_iou_true"] = volume_iou(true, Mesh(np.asarray(cm.vertices), np.asarray(cm.faces), 0.5, 0.0),
                                                  n_points=100_000, seed=0)


def write_parametric(f: Any, out: Any) -> None:
    """``shape_parametric.obj`` (metres, the fitted body frame) when the box-wing was fitted."""
    if getattr(f, "param_mesh", None) is None:
        return
    atomic_write(out / "shape_parametric.obj", lambda tmp: f.param_mesh.to_trimesh().export(str(tmp), file_type="obj"))
