"""Figures of the light-curve inversion experiment (:mod:`cssat.experiments.inversion`): the
measured and fitted light curves, the EGI on the sphere, the true and recovered shapes, and the
geometry's observability map. Each returns a :class:`matplotlib.figure.Figure` (no pyplot)."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

__all__ = ["inversion_lightcurve_figure", "egi_figure", "shapes_figure", "observability_figure"]


def _lonlat(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.asarray(n, dtype=np.float64).reshape(-1, 3)
    return np.arctan2(n[:, 1], n[:, 0]), np.arcsin(np.clip(n[:, 2], -1, 1))


def inversion_lightcurve_figure(hours: np.ndarray, flux: np.ndarray, sigma: np.ndarray | None, model: np.ndarray,
                                fit: np.ndarray) -> Figure:
    """The light curve (per unit irradiance and range, m²) and the model's, fitted samples and
    held-out ones apart, over the residuals in units of the noise (or of the flux's rms)."""
    fig = Figure(figsize=(10, 5.5))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    for mask, label, color in ((fit, "fitted", "k"), (~fit, "held out", "tab:green")):
        if mask.any():
            top.plot(hours[mask], flux[mask], ".", ms=2, color=color, label=f"measured ({label})")
    top.plot(hours, model, ".", ms=1, color="tab:orange", label="EGI model")
    top.set_ylabel("flux × r² / I₀ (m²)")
    top.legend(fontsize=8, loc="best", markerscale=4)
    scale = sigma if sigma is not None else np.full_like(flux, np.sqrt(np.mean(flux ** 2)))
    r = (flux - model) / scale
    bottom.plot(hours[fit], r[fit], ".", ms=1.5, color="tab:blue")
    if (~fit).any():
        bottom.plot(hours[~fit], r[~fit], ".", ms=1.5, color="tab:green")
    bottom.axhline(0, color="0.5", lw=0.8)
    bottom.set_ylabel("residual / σ" if sigma is not None else "residual / rms")
    bottom.set_xlabel("hours since the first sample")
    top.set_title("Light curve and the EGI model's fit (green: nights held out of the fit)", fontsize=10)
    fig.tight_layout()
    return fig


def egi_figure(normals: np.ndarray, areas: np.ndarray, true_normals: np.ndarray | None = None,
               true_areas: np.ndarray | None = None) -> Figure:
    """The EGI on the sphere (Mollweide; longitude and latitude of the normal in the fitted body
    frame), the disc area ∝ the facet area: recovered (filled) over true (open rings)."""
    fig = Figure(figsize=(9, 4.8))
    ax = fig.add_subplot(projection="mollweide")
    scale = 600.0 / max(float(np.max(areas)) if np.size(areas) else 1.0,
                        float(np.max(true_areas)) if true_areas is not None and np.size(true_areas) else 0.0, 1e-300)
    if true_normals is not None and true_areas is not None:
        keep = true_areas > 1e-3 * true_areas.max()
        lo, la = _lonlat(true_normals[keep])
        ax.scatter(lo, la, s=true_areas[keep] * scale, facecolors="none", edgecolors="k", lw=0.8, label="true EGI")
    if np.size(areas):
        lo, la = _lonlat(normals)
        ax.scatter(lo, la, s=areas * scale, color="tab:orange", alpha=0.7, label="recovered EGI")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Extended Gaussian image: area per surface normal (body frame)", fontsize=10)
    fig.tight_layout()
    return fig


def _draw_mesh(ax: Any, vertices: np.ndarray, faces: np.ndarray, color: str, r: float) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # heavy: matplotlib, only for figures

    light = np.array([0.4, -0.5, 0.75])
    light /= np.linalg.norm(light)
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    shade = 0.35 + 0.65 * np.clip(n @ light, 0, 1)
    base = np.array({"orange": (1.0, 0.6, 0.2), "grey": (0.7, 0.7, 0.75)}[color])
    ax.add_collection3d(Poly3DCollection(tri, facecolors=shade[:, None] * base, edgecolors="none"))
    for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        set_lim(-r, r)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x (m)", fontsize=7)
    ax.set_ylabel("y (m)", fontsize=7)
    ax.set_zlabel("z (m)", fontsize=7)
    ax.tick_params(labelsize=6)


def shapes_figure(recovered: Any, truth: tuple[np.ndarray, np.ndarray] | None = None, iou: float | None = None) -> Figure:
    """The true model (``(vertices, faces)`` in the fitted body frame) and the recovered convex
    shape (a ``trimesh.Trimesh``), side by side, lit from one fixed direction."""
    n = 2 if truth is not None else 1
    fig = Figure(figsize=(5 * n, 4.8))
    v = np.asarray(recovered.vertices)
    v = v - v.mean(0)
    r = max(float(np.abs(v).max()), float(np.abs(truth[0]).max()) if truth is not None else 0.0)  # one scale for both
    if truth is not None:
        ax = fig.add_subplot(1, n, 1, projection="3d")
        _draw_mesh(ax, np.asarray(truth[0]), np.asarray(truth[1]), "grey", r)
        ax.set_title("true model", fontsize=10)
    ax = fig.add_subplot(1, n, n, projection="3d")
    _draw_mesh(ax, v, np.asarray(recovered.faces), "orange", r)
    ax.set_title("recovered convex shape" + (f" (volume IoU with the hull {iou:.2f})" if iou is not None else ""), fontsize=10)
    fig.tight_layout()
    return fig


def observability_figure(normals: np.ndarray, leverage: np.ndarray, seen: np.ndarray, singular_values: np.ndarray) -> Figure:
    """What the fitted geometry constrains: each normal's leverage (0 — invisible or confused,
    1 — determined) on the sphere (Mollweide, body frame; × never lit while seen), and the
    normalised singular spectrum of ``G``."""
    fig = Figure(figsize=(12, 4.6))
    ax = fig.add_subplot(1, 2, 1, projection="mollweide")
    lo, la = _lonlat(normals)
    sc = ax.scatter(lo[seen], la[seen], c=leverage[seen], s=8, cmap="viridis", vmin=0, vmax=1)
    if (~seen).any():
        ax.scatter(lo[~seen], la[~seen], marker="x", s=6, color="0.6", lw=0.5, label="never lit while seen")
        ax.legend(fontsize=7, loc="lower right")
    ax.grid(True, lw=0.3)
    fig.colorbar(sc, ax=ax, shrink=0.7, label="leverage")
    ax.set_title("Observability of the EGI (body frame)", fontsize=10)
    ax2 = fig.add_subplot(1, 2, 2)
    s = np.asarray(singular_values)
    ax2.semilogy(np.arange(1, len(s) + 1), np.clip(s, 1e-17, None), lw=1)
    ax2.set_xlabel("index")
    ax2.set_ylabel("σᵢ / σ₁")
    ax2.set_title("Singular spectrum of G", fontsize=10)
    ax2.grid(True, lw=0.3)
    fig.tight_layout()
    return fig
