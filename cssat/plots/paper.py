"""The paper's reconstruction figures (Fig. 9–14) of Simulations 1–3."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cssat.plots.base import error_panels, image_panels, light_curve_image

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _solver_title(metrics: dict) -> str:
    if metrics.get("solver") == "omp":
        eps = metrics.get("solver_epsilon")
        return f"batch-OMP, K = {metrics.get('solver_n_nonzero_coefs')}" + (f", ε = {eps:.3g}" if eps is not None else "")
    it = metrics.get("solver_iterations")
    text = f"{metrics.get('solver')}" + (f", {it} iterations" if it is not None else "")
    if "solver_lam" in metrics:
        text += f", λ = {metrics['solver_lam']:g}·‖Aᵀy‖∞"
    elif "solver_denoiser" in metrics:
        text += f", denoiser {metrics['solver_denoiser']}"
    return text


def sim1_figure(y: np.ndarray, rec: np.ndarray, den: np.ndarray, truth: np.ndarray, metrics: dict) -> Figure:
    """The paper's Fig. 9 (one row): the light curve as an image, the reconstruction, the
    denoised reconstruction and the truth; below them the error maps ``|x̂ − x|``."""
    return image_panels([
        (light_curve_image(np.asarray(y)), f"light curve y (m = {metrics['m']})", None, "flux y (Φx, arbitrary units)"),
        (rec, f"reconstruction\nPSNR {metrics['psnr']:.2f} dB, SSIM {metrics['ssim']:.3f}"),
        (den, f"denoised ({metrics['denoiser']})\nPSNR {metrics['psnr_denoised']:.2f} dB, SSIM {metrics['ssim_denoised']:.3f}"),
        (truth, f"truth ({metrics['n']}×{metrics['n']})"),
        (None, ""), *error_panels(truth, [(rec, "reconstruction"), (den, "denoised")]), (None, ""),
    ], ncols=4, title="Simulation 1: " + _solver_title(metrics), panel_size=(3.4, 3.4))


def sim2_figure(truth: np.ndarray, rec: np.ndarray, den: np.ndarray, metrics: dict) -> Figure:
    """The paper's Fig. 11: truth, reconstruction from the full-rank Φ̂, denoised; below them
    the error maps."""
    return image_panels([
        (truth, f"truth ({metrics['n']}×{metrics['n']})"),
        (rec, f"reconstruction\nPSNR {metrics['psnr']:.2f} dB"),
        (den, f"denoised ({metrics['denoiser']})\nPSNR {metrics['psnr_denoised']:.2f} dB ({metrics['psnr_gain_denoised']:+.2f})"),
        (None, ""), *error_panels(truth, [(rec, "reconstruction"), (den, "denoised")]),
    ], ncols=3, title=f"Simulation 2: full-rank Φ̂ (N_ref = {metrics['reference_n']}, ‖Φ̂−Φ‖/‖Φ‖ = "
                      f"{metrics['phi_relative_error']:.1e}), m = {metrics['m']}, " + _solver_title(metrics),
       panel_size=(3.4, 3.5), title_size=9)


def sim3_figures(truth: np.ndarray, stack: np.ndarray, den2: np.ndarray, den3: np.ndarray, per: list[dict],
                 psnr3: list[float], best: int, metrics: dict) -> tuple[Figure, Figure]:
    """The paper's Fig. 13 (the repeats' raw results, each row of them over its row of error
    maps) and Fig. 14 (truth, best raw, its 2-D and 3-D denoised versions, over their error
    maps): two figures."""
    R = stack.shape[0]
    ncols = min(R, 3 if R <= 9 else 5)
    results = [(stack[k], f"slice {k + 1}: {per[k]['psnr']:.2f} dB") for k in range(R)]
    errors = error_panels(truth, [(stack[k], f"slice {k + 1}") for k in range(R)])
    panels = []
    for start in range(0, R, ncols):  # a row of results, then the row of their errors
        row = slice(start, start + ncols)
        pad = [(None, "")] * (ncols - len(results[row]))
        panels += results[row] + pad + errors[row] + pad
    fig13 = image_panels(panels, ncols=ncols, panel_size=(3.0, 2.9),
                         title=f"Simulation 3: {R} noisy results (N_ref = {metrics['reference_n']} references each)")
    fig14 = image_panels([
        (truth, "(a) truth"),
        (stack[best], f"(b) best raw (slice {best + 1})\nPSNR {per[best]['psnr']:.2f} dB"),
        (den2[best], f"(c) 2-D denoised\nPSNR {per[best]['psnr_denoised']:.2f} dB ({metrics['gain_2d']:+.2f})"),
        (den3[best], f"(d) 3-D denoised\nPSNR {psnr3[best]:.2f} dB ({metrics['gain_3d_over_2d']:+.2f} over 2-D)"),
        (None, ""), *error_panels(truth, [(stack[best], "(b)"), (den2[best], "(c)"), (den3[best], "(d)")]),
    ], ncols=4, panel_size=(3.3, 3.5))
    return fig13, fig14


