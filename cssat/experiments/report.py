"""The scoring and figures stage: ``arrays.npz``, the figures the experiment's ``figures`` list
names, and the summary of a stack of repeats.

Figures (``figures: [...]`` in an experiment's YAML): ``fig9_sim1`` (light curve, reconstruction,
denoised, truth, error maps), ``fig11_sim2`` (truth, reconstruction from Φ̂, denoised),
``fig13_sim3_results`` (every repeat) and ``fig14_sim3_denoised`` (the best repeat, its 2-D and
3-D denoised versions). A single run shows its one reconstruction, a stack its best repeat.
"""

from __future__ import annotations

import logging
from typing import Any, Callable

import numpy as np

from cssat.experiments.files import write_npz
from cssat.plots import save_figure, sim1_figure, sim2_figure, sim3_figures

log = logging.getLogger("cssat")

__all__ = ["FIGURES", "write", "repeats_summary", "log_headline"]


def _best(res: dict[str, Any]) -> int:
    return int(np.argmax([r["psnr"] for r in res["rows"]]))


def _fig9(res, metrics):
    rec = res["recs"][_best(res)]
    return sim1_figure(res["measured"].y.cpu().numpy(), rec.image, rec.denoised, res["measured"].truth, metrics)


def _fig11(res, metrics):
    rec = res["recs"][_best(res)]
    return sim2_figure(res["measured"].truth, rec.image, rec.denoised, metrics)


def _stack(res):
    if "stack" in res:
        return res["stack"], res["den2"], res["den3"], res["psnr3"]
    st = np.stack([r.image for r in res["recs"]])
    den = np.stack([r.denoised for r in res["recs"]])
    return st, den, den, [r["psnr_denoised"] for r in res["rows"]]


def _fig13(res, metrics):
    stack, den2, den3, psnr3 = _stack(res)
    return sim3_figures(res["measured"].truth, stack, den2, den3, res["rows"], psnr3, _best(res), _sim3_labels(res, metrics))[0]


def _fig14(res, metrics):
    stack, den2, den3, psnr3 = _stack(res)
    return sim3_figures(res["measured"].truth, stack, den2, den3, res["rows"], psnr3, _best(res), _sim3_labels(res, metrics))[1]


def _sim3_labels(res, metrics):
    b = _best(res)
    row, psnr3 = res["rows"][b], _stack(res)[3]
    return {"reference_n": metrics.get("reference_n"), "gain_2d": row["psnr_denoised"] - row["psnr"],
            "gain_3d_over_2d": psnr3[b] - row["psnr_denoised"]}


#: figure stem -> maker(result, metrics) -> Figure
FIGURES: dict[str, Callable] = {"fig9_sim1": _fig9, "fig11_sim2": _fig11, "fig13_sim3_results": _fig13,
                                "fig14_sim3_denoised": _fig14}


def write(p: Any, run: Any, res: dict[str, Any], metrics: dict[str, Any]) -> None:
    """``arrays.npz`` (``truth``, ``y``; one run: ``reconstruction``, ``reconstruction_unclipped``,
    ``denoised`` and the solver's tensors; a stack: ``reconstructions``, ``denoised_2d``,
    ``denoised_3d``) and the figures of ``p.figures``."""
    m = res["measured"]
    arrays: dict[str, Any] = {"truth": m.truth, "y": m.y.to(run.dtype)}
    if p.reference.repeated:
        arrays.update(reconstructions=res["stack"], denoised_2d=res["den2"], denoised_3d=res["den3"])
    else:
        r = res["recs"][0]
        arrays.update(reconstruction=r.image, reconstruction_unclipped=r.raw, denoised=r.denoised, **r.arrays)
    write_npz(run.out_dir / "arrays.npz", **arrays)
    for name in p.figures:
        save_figure(FIGURES[name](res, metrics), run.figure(name))


def repeats_summary(per: list[dict], psnr3: list[float]) -> dict[str, Any]:
    """The headline (the best repeat's), the means over the repeats and the per-repeat lists."""
    best = int(np.argmax([p["psnr"] for p in per]))
    out: dict[str, Any] = {k: per[best][k] for k in ("psnr", "ssim", "psnr_denoised", "ssim_denoised")}
    out.update(psnr_denoised_3d=psnr3[best], best_repeat=best, gain_2d=per[best]["psnr_denoised"] - per[best]["psnr"],
               gain_3d_over_2d=psnr3[best] - per[best]["psnr_denoised"], psnr_mean_denoised_3d=float(np.mean(psnr3)))
    means = {"psnr": "psnr_mean", "psnr_denoised": "psnr_mean_denoised", "phi_relative_error": "phi_relative_error_mean",
             "phi_relative_error_min_norm": "phi_relative_error_min_norm_mean", "psnr_min_norm": "psnr_min_norm_mean"}
    for key, name in means.items():  # over the repeats that have the value (the baseline may be on the first only)
        vals = [p[key] for p in per if key in p]
        if vals:
            out[name] = float(np.mean(vals))
    keys = list(dict.fromkeys(k for p in per for k in p))
    out.update({f"repeat_{key}": [p.get(key) for p in per] for key in keys})
    out["repeat_psnr_denoised_3d"] = psnr3
    return out


def log_headline(p: Any, metrics: dict[str, Any]) -> None:
    """One line with the run's headline numbers."""
    seconds = sum(v for k, v in metrics.items() if k.startswith("seconds_"))
    if p.reference.repeated:
        three_d = (f"3-D {metrics['psnr_denoised_3d']:.2f} dB ({metrics['gain_3d_over_2d']:+.2f} over 2-D)"
                   if p.denoiser3d is not None else "no 3-D denoising")
        log.info("%s: best repeat %d: PSNR %.2f dB, 2-D %.2f dB (%+.2f), %s, %.1f s", p.name, metrics["best_repeat"],
                 metrics["psnr"], metrics["psnr_denoised"], metrics["gain_2d"], three_d, seconds)
        return
    what = (f"K={metrics['omp_atoms']}" if "omp_atoms" in metrics
            else f"{metrics['solver']} {metrics.get('solver_iterations')} it.")
    extra = f", ‖Φ̂−Φ‖/‖Φ‖ = {metrics['phi_relative_error']:.2e}" if "phi_relative_error" in metrics else ""
    log.info("%s: PSNR %.2f dB (denoised %.2f dB, %s), SSIM %.3f, m=%d (%.0f%% of N=%d), %s%s, %.1f s", p.name,
             metrics["psnr"], metrics["psnr_denoised"], metrics["denoiser"], metrics["ssim"], p.m, 100 * metrics["measurement_ratio"],
             metrics["n_pixels"], what, extra, seconds)
