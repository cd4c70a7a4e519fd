"""Figures of the experiments and sweeps, as matplotlib ``Figure`` objects.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot, so nothing here
switches matplotlib's backend or touches a notebook's open figures: show one in a notebook by
leaving it as a cell's value, save it with :func:`save_figure` (atomic) or ``fig.savefig``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from cssat._checks import FieldError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["image_panels", "error_panels", "FIGURE_FORMATS", "sim1_figure", "sim2_figure", "sim3_figures", "grid_images_figure", "grid_maps_figure",
           "grid_curves_figure", "lightcurve_figure",
           "atmosphere_figure", "sweep_figure", "light_curve_image", "save_figure"]


def _figure(figsize):
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


#: the file formats :func:`save_figure` writes (the config's ``figure_format``)
FIGURE_FORMATS = ("png", "pdf", "svg")


def save_figure(fig: Figure, path: str | os.PathLike, dpi: int = 120) -> None:
    """Save ``fig`` atomically (a reader sees the old file or the new one, never a part) in the
    format of ``path``'s suffix: ``.png`` (``dpi``), ``.pdf`` or ``.svg`` (vector)."""
    from cssat._tmpfiles import atomic_write

    fmt = Path(path).suffix.lstrip(".").lower()
    if fmt not in FIGURE_FORMATS:
        raise FieldError("figure_format", f"expected one of {list(FIGURE_FORMATS)}, got {fmt!r} (from {path})")
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format=fmt))


def light_curve_image(y: np.ndarray) -> np.ndarray:
    """The light curve ``y (m,)`` laid out row by row in a ``⌈√m⌉ × ⌈√m⌉`` image, padded with NaN
    (the paper's Fig. 9, first column)."""
    side = math.ceil(math.sqrt(len(y)))
    img = np.full(side * side, np.nan)
    img[: len(y)] = y
    return img.reshape(side, side)


#: the colour-bar label of a target-like image (the targets are scaled to [0, 1])
INTENSITY = "intensity (target scale, 0–1)"


def image_panels(
    panels: Sequence[tuple],
    *,
    ncols: int | None = None,
    title: str | None = None,
    panel_size: tuple[float, float] = (3.1, 3.4),
    row_labels: Sequence[str] | None = None,
    title_size: int = 10,
    colorbar_label: str | None = INTENSITY,
) -> Figure:
    """A grid of images, each with a colour bar: ``panels`` are ``(image, title[, limits[, label[,
    cmap]]])`` — ``limits`` ``(vmin, vmax)`` (default ``(0, 1)``; ``None``: the image's own
    range), ``label`` the colour bar's (default ``colorbar_label``; ``None``: no bar), ``cmap``
    (default gray). A ``None`` image leaves the cell empty. Filled row by row into ``ncols``
    columns (default: all in one row)."""
    n = len(panels)
    ncols = ncols or n
    nrows = -(-n // ncols)
    fig = _figure((panel_size[0] * ncols, panel_size[1] * nrows))
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False, gridspec_kw={"wspace": 0.45})).reshape(nrows, ncols)
    for k, ax in enumerate(axes.flat):
        ax.set_xticks([])
        ax.set_yticks([])
        if k >= n or panels[k][0] is None:
            ax.axis("off")
            continue
        img, text, *rest = panels[k]
        lim = rest[0] if len(rest) > 0 else (0.0, 1.0)
        label = rest[1] if len(rest) > 1 else colorbar_label
        cmap = rest[2] if len(rest) > 2 else "gray"
        kw = {"vmin": lim[0], "vmax": lim[1]} if lim is not None else {}
        im = ax.imshow(img, cmap=cmap, interpolation="nearest", **kw)
        ax.set_title(text, fontsize=9)
        if label is not None:
            cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
            cb.set_label(label, fontsize=7)
            cb.ax.tick_params(labelsize=7)
    for i, label in enumerate(row_labels or []):
        axes[i, 0].set_ylabel(label, fontsize=9)
    if title:
        fig.suptitle(title, fontsize=title_size)
    return fig


def error_panels(truth: np.ndarray, estimates: Sequence[tuple[Any, str]]) -> list[tuple]:
    """Panels of the error maps ``|x̂ − x|`` of ``estimates`` (``(image, title)``) against
    ``truth``, on one colour scale (0 to the largest error of any of them) so they compare."""
    errs = [None if e is None else np.abs(np.asarray(e, dtype=float) - np.asarray(truth, dtype=float)) for e, _ in estimates]
    top = max([float(e.max()) for e in errs if e is not None] + [1e-12])
    return [(None, "") if e is None else (e, f"|x̂ − x|: {t}", (0.0, top), "absolute error (target scale)", "magma")
            for e, (_, t) in zip(errs, estimates)]


def _scale_bar(ax, fov_m: float, size: int) -> None:
    """A white scale bar of a round length (1, 2 or 5 × 10ᵏ m) near a quarter of the field."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    target = fov_m / 4
    k = 10 ** math.floor(math.log10(target))
    length = max((f * k for f in (1, 2, 5) if f * k <= target), default=k)
    text = f"{length:g} m" if length >= 1 else f"{length * 100:g} cm"
    ax.add_artist(AnchoredSizeBar(ax.transData, length / fov_m * size, text, "lower left", pad=0.3, color="w",
                                  frameon=False, size_vertical=max(size / 120, 0.5), fontproperties={"size": 7}))


def lightcurve_figure(minutes: np.ndarray, mag: np.ndarray, images: np.ndarray, marks: Sequence[int], times: np.ndarray,
                      sunlit: np.ndarray, fov_m: float | None = None) -> Figure:
    """The paper's Fig. 4: rendered images at the marked steps (pixel flux in W/m² at the
    observer, a scale bar in metres when ``fov_m``, the field of view, is given) above the
    atmosphere-free light curve in magnitudes, with the Earth's shadow shaded."""
    n = len(marks)
    fig = _figure((2.5 * n, 6.4))
    gs = fig.add_gridspec(2, n, height_ratios=[1, 1.25])
    for k, (step, img) in enumerate(zip(marks, images)):
        ax = fig.add_subplot(gs[0, k])
        im = ax.imshow(img, cmap="gray", interpolation="nearest", vmin=0, vmax=max(float(img.max()), 1e-300))
        ax.set_title(f"({k + 1}) {str(times[step])[11:16]} UTC", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03, orientation="horizontal")
        cb.set_label("pixel flux (W/m²)", fontsize=7)
        cb.ax.tick_params(labelsize=6)
        if fov_m is not None:
            _scale_bar(ax, float(fov_m), img.shape[-1])
    ax = fig.add_subplot(gs[1, :])
    ax.plot(minutes, mag, color="k", lw=1)
    ax.plot(minutes[marks], mag[marks], "o", color="tab:red")
    for k, step in enumerate(marks):
        ax.annotate(f"({k + 1})", (minutes[step], mag[step]), textcoords="offset points", xytext=(4, 6), fontsize=8, color="tab:red")
    ecl = np.asarray(sunlit) < 1
    if ecl.any():
        ax.axvspan(minutes[ecl][0], minutes[ecl][-1], color="0.85", label="Earth shadow")
        ax.legend(loc="lower right", fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel(_since(times[0]))
    ax.set_ylabel("apparent magnitude (V; brighter up)")
    ax.set_title("(b) simulated atmosphere-free light curve", fontsize=10)
    fig.suptitle("(a) synthetic images of the satellite at the marked times", fontsize=10, y=0.99)
    fig.tight_layout()
    return fig


def _since(epoch) -> str:
    return "minutes since " + str(epoch)[:16].replace("T", " ") + " UTC"


def atmosphere_figure(minutes: np.ndarray, mag: np.ndarray, mag_facetwise: np.ndarray, mag_pixelwise: np.ndarray,
                      atmosphere: str = "gaussian", epoch: np.datetime64 | str | None = None) -> Figure:
    """The paper's Fig. 5: the atmosphere-free light curve against the facet-wise (Eq. 11) and
    pixel-wise (Eq. 12) attenuated noisy ones, as magnitudes of the flux's size ``|I|`` (the
    paper's zero-mean Φ makes the attenuated flux negative at times); ``epoch`` (UTC) labels the
    time axis."""
    fig = _figure((9, 4))
    ax = fig.subplots()
    ax.plot(minutes, mag_pixelwise, color="tab:orange", lw=0.6, label=f"simplified attenuated noisy LC (pixel-wise, Eq. 12, {atmosphere})")
    ax.plot(minutes, mag_facetwise, color="tab:blue", lw=0.6, label=f"attenuated noisy LC (facet-wise, Eq. 11, {atmosphere})")
    ax.plot(minutes, mag, color="k", lw=1.2, label="atmosphere-free (Eq. 10)")
    ax.invert_yaxis()
    ax.set_xlabel(_since(epoch) if epoch is not None else "minutes")
    ax.set_ylabel("measured flux |I| as apparent magnitude\n(V; brighter up)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Atmosphere-free light curve and attenuated noisy light curves", fontsize=10)
    fig.tight_layout()
    return fig


#: swept config keys, and metrics, in words for the sweep plots
#: metric keys in words (the axis labels of the figures)
WORDS = {"psnr": "PSNR (dB)", "ssim": "SSIM", "psnr_denoised": "PSNR after denoising (dB)",
         "ssim_denoised": "SSIM after denoising", "phi_effective_rank_centered": "effective rank of Φ's fluctuations",
         "phi_effective_rank": "effective rank of Φ", "phi_scintillation_index": "scintillation index σ_I²"}


def _words(key: str) -> str:
    """``key`` in words: :data:`WORDS`, else its last part with spaces (``atmosphere.r0_m`` → ``r0 m``)."""
    return WORDS.get(key, key.rsplit(".", 1)[-1].replace("_", " "))


def sweep_figure(rows: list[dict], swept: list[str], metric: str = "psnr", labels: dict[str, str] | None = None) -> Figure | None:
    """The sweep plot: ``metric`` against one swept value (and ``<metric>_denoised`` dashed), or
    a map over the first two numeric swept values; ``rows`` hold the values to plot under the
    ``swept`` names, ``labels`` their axis labels (default: the names in words). ``None`` when no
    row has the metric."""
    labels = labels or {}

    def _axis(rows: Sequence[dict], key: str) -> tuple[list[Any], str]:
        return [r.get(key) for r in rows], labels.get(key, _words(key))

    ok = [r for r in rows if r.get("status") == "ok" and isinstance(r.get(metric), (int, float))]
    if not ok or not swept:
        return None
    numeric = [k for k in swept if all(isinstance(r.get(k), (int, float)) for r in ok)]
    unit = _words(metric) if metric in WORDS else (f"{metric} (dB)" if "psnr" in metric else metric)
    what = unit.split(" (")[0]
    if len(numeric) >= 2:  # a phase-transition map over the first two numeric keys
        kx, ky = numeric[0], numeric[1]
        xs, lx = _axis(ok, kx)
        ys, ly = _axis(ok, ky)
        ux, uy = sorted(set(xs)), sorted(set(ys))
        grid = np.full((len(uy), len(ux)), np.nan)
        for x, y, r in zip(xs, ys, ok):
            grid[uy.index(y), ux.index(x)] = r[metric]
        fig = _figure((6, 4.5))
        ax = fig.subplots()
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        ax.set_xticks(range(len(ux)), [f"{v:.3g}" for v in ux])
        ax.set_yticks(range(len(uy)), [f"{v:.3g}" for v in uy])
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                if not np.isnan(grid[i, j]):
                    ax.text(j, i, f"{grid[i, j]:.1f}", ha="center", va="center", color="w", fontsize=8)
        ax.set_xlabel(lx)
        ax.set_ylabel(ly)
        fig.colorbar(im, ax=ax, label=unit)
        ax.set_title(f"{what} over {lx.split(' (')[0]} × {ly.split(' (')[0]}", fontsize=10)
        return fig
    key = numeric[0] if numeric else swept[0]
    xs, label = _axis(ok, key)
    others = [k for k in swept if k != key]
    groups: dict[tuple, list[int]] = {}
    for i, r in enumerate(ok):
        groups.setdefault(tuple(r.get(k) for k in others), []).append(i)
    fig = _figure((6, 4))
    ax = fig.subplots()
    for g, idx in groups.items():
        idx = sorted(idx, key=lambda i: (str(type(xs[i])), xs[i]))
        name = ", ".join(f"{labels.get(k, _words(k))} = {v}" for k, v in zip(others, g))
        ax.plot([xs[i] for i in idx], [ok[i][metric] for i in idx], "o-", label=f"{what} {name}".strip())
        den = f"{metric}_denoised"
        if all(isinstance(ok[i].get(den), (int, float)) for i in idx):
            ax.plot([xs[i] for i in idx], [ok[i][den] for i in idx], "s--", label=f"{what}, denoised {name}".strip())
    ax.set_xlabel(label)
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{what} against {label.split(' (')[0]}", fontsize=10)
    return fig


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


def _grid_lookup(axes: Sequence[dict], rows: Sequence[dict]) -> tuple[list[list[Any]], dict[tuple, dict]]:
    """The labels of each axis in order, and ``{labels tuple: row}``."""
    labels = [list(dict.fromkeys(r[ax["name"]] for r in rows)) for ax in axes]
    return labels, {tuple(r[ax["name"]] for ax in axes): r for r in rows}


def grid_images_figure(truth: np.ndarray, axes: Sequence[dict], rows: Sequence[dict], images: dict) -> Figure:
    """A grid's reconstructions: per label of the first axis a row of the cells' images (the
    other axes' labels across, PSNR and seconds in each panel) and the truth, over a row of their
    error maps (one colour scale for the figure). ``rows``: the grid's rows (``cell``, ``psnr``,
    ``seconds`` and one key per axis name); ``images``: cell name → image."""
    labels, by = _grid_lookup(axes, rows)
    first, rest = labels[0], list(__import__("itertools").product(*labels[1:]))
    panels, row_labels, k = [], [], len(rest)
    name0 = axes[0]["name"]
    for a in first:
        cells = [by[(a, *b)] for b in rest]
        recs = [(images[c["cell"]], f"{' '.join(map(str, b)) or c['cell']}\n{c['psnr']:.2f} dB, {c['seconds']:.0f} s")
                for c, b in zip(cells, rest)]
        errs = error_panels(truth, [(images[c["cell"]], c["cell"]) for c in cells])
        panels += recs + [(truth, "truth")] + errs + [(None, "")]
        row_labels += [f"{name0} = {a}", f"{name0} = {a}: error"]
    return image_panels(panels, ncols=k + 1, panel_size=(2.7, 2.6), row_labels=row_labels,
                        title=f"Reconstructions over {' × '.join(ax['name'] for ax in axes)}")


def grid_maps_figure(axes: Sequence[dict], rows: Sequence[dict], flux_only: float | None = None,
                     metric: str = "psnr") -> dict[str, Figure]:
    """``metric`` over the first two axes of a grid (columns × rows), one map per label of the
    third axis (or one map): ``{label: Figure}``; ``flux_only`` (the flat image's PSNR) in the title."""
    labels, by = _grid_lookup(axes, rows)
    cols, lines = labels[0], labels[1] if len(labels) > 1 else [None]
    figs = {}
    for third in (labels[2] if len(labels) > 2 else [None]):
        grid = np.full((len(lines), len(cols)), np.nan)
        for i, ln in enumerate(lines):
            for j, c in enumerate(cols):
                key = tuple(v for v in (c, ln, third) if v is not None) if len(axes) > 1 else (c,)
                if key in by and isinstance(by[key].get(metric), (int, float)):
                    grid[i, j] = by[key][metric]
        fig = _figure((1.3 * len(cols) + 2.5, 0.55 * len(lines) + 2.2))
        ax = fig.subplots()
        im = ax.imshow(grid, origin="upper", aspect="auto", cmap="viridis")
        ax.set_xticks(range(len(cols)), [str(c) for c in cols], fontsize=8)
        ax.set_yticks(range(len(lines)), [f"{axes[1]['name']} = {v}" if len(axes) > 1 else "" for v in lines], fontsize=8)
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                if not np.isnan(grid[i, j]):
                    ax.text(j, i, f"{grid[i, j]:.1f}", ha="center", va="center", color="w", fontsize=8)
        ax.set_xlabel(_words(axes[0]["name"]))
        fig.colorbar(im, ax=ax, label=_words(metric))
        ax.set_title(f"{third if third is not None else ''}: {_words(metric).split(' (')[0]}"
                     + (f"\n(the total flux alone gives {flux_only:.1f} dB)" if flux_only is not None else ""), fontsize=10)
        fig.tight_layout()
        figs[str(third) if third is not None else "map"] = fig
    return figs


def grid_curves_figure(axes: Sequence[dict], rows: Sequence[dict], metrics: Sequence[str]) -> Figure:
    """The ``metrics`` of a grid's rows against the labels of its first axis (log scale where
    positive), one line per metric; the first value of the other axes."""
    labels, by = _grid_lookup(axes, rows)
    rest = tuple(lab[0] for lab in labels[1:])
    fig = _figure((6.5, 3.6))
    ax = fig.subplots()
    xs = list(range(len(labels[0])))
    for key in metrics:
        vals = [by[(a, *rest)].get(key) for a in labels[0]]
        ax.plot(xs, [np.nan if v is None else v for v in vals], "o-", label=_words(key))
    ax.set_xticks(xs, [str(a) for a in labels[0]])
    if all(isinstance(v, (int, float)) and v > 0 for r in rows for k, v in r.items() if k in metrics):
        ax.set_yscale("log")
    ax.set_xlabel(_words(axes[0]["name"]))
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"{', '.join(_words(k) for k in metrics)} over {_words(axes[0]['name'])}", fontsize=10)
    fig.tight_layout()
    return fig
