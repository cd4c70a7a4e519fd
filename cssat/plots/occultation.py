"""Figures of the shadow-imaging (occultation) forward model: the ground shadow, the recorded
series and the silhouettes (true, the shadow's dark region, reconstructed)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["occultation_figures"]


def _panel(img: np.ndarray, size: tuple[float, float], label: str, xlabel: str, ylabel: str, title: str, **show: Any) -> Any:
    from matplotlib.figure import Figure  # heavy: matplotlib, only for figures

    fig = Figure(figsize=size)
    ax = fig.add_subplot()
    fig.colorbar(ax.imshow(img, cmap="gray", **show), ax=ax, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def occultation_figures(truth: np.ndarray, pattern: np.ndarray, series: np.ndarray, recon: np.ndarray,
                        geometric: np.ndarray, pixel: float, times: np.ndarray, metrics: dict[str, Any]) -> dict[str, Any]:
    """``{stem: Figure}``: ``occultation_shadow`` (the ground intensity ``pattern (G, G)`` on a
    ``pixel``-metre grid), ``occultation_series`` (``series (J, K)`` against ``times`` in s) and
    ``occultation_silhouette`` (``truth``, ``geometric``, ``recon``, each ``(H, W)``); ``metrics``
    gives the titles' numbers (``fresnel_scale_m``, ``n_telescopes``, ``star_magnitude``,
    ``iou_geometric``, ``iou``)."""
    from matplotlib.figure import Figure  # heavy: matplotlib, only for figures

    ext = [-truth.shape[1] * pixel / 2, truth.shape[1] * pixel / 2, -truth.shape[0] * pixel / 2, truth.shape[0] * pixel / 2]
    gext = [-pattern.shape[1] * pixel / 2, pattern.shape[1] * pixel / 2, -pattern.shape[0] * pixel / 2, pattern.shape[0] * pixel / 2]
    out = {"occultation_shadow": _panel(pattern, (6, 5), "intensity / unocculted star", "east (m)", "north (m)",
                                        f"Ground shadow (Fresnel scale {metrics['fresnel_scale_m']:.1f} m)", origin="lower",
                                        extent=gext),
           "occultation_series": _panel(series, (7, 4), "recorded / unocculted", "time (ms)", "telescope",
                                        f"Recorded series: {metrics['n_telescopes']} telescopes, V = {metrics['star_magnitude']:g}",
                                        aspect="auto", extent=[times[0] * 1e3, times[-1] * 1e3, len(series) - 0.5, -0.5])}
    fig = Figure(figsize=(12, 4))
    for i, (img, title) in enumerate(((truth, "true silhouette"),
                                      (geometric, f"shadow's dark region (IoU {metrics['iou_geometric']:.2f})"),
                                      (recon, f"reconstructed (IoU {metrics['iou']:.2f})"))):
        ax = fig.add_subplot(1, 3, i + 1)
        ax.imshow(img, origin="lower", extent=ext, cmap="gray_r", vmin=0, vmax=1)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("east (m)")
    fig.tight_layout()
    out["occultation_silhouette"] = fig
    return out
