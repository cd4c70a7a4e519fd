"""Saving figures (atomically, in any of :data:`FIGURE_FORMATS`) and rows of image panels."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from cssat._checks import FieldError
from cssat._tmpfiles import atomic_write

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _figure(figsize):
    from matplotlib.figure import Figure  # heavy: matplotlib, only for figures

    return Figure(figsize=figsize)


#: the file formats :func:`save_figure` writes (the config's ``figure_format``)
FIGURE_FORMATS = ("png", "pdf", "svg")


def save_figure(fig: Figure, path: str | os.PathLike, dpi: int = 120) -> None:
    """Save ``fig`` atomically (a reader sees the old file or the new one, never a part) in the
    format of ``path``'s suffix: ``.png`` (``dpi``), ``.pdf`` or ``.svg`` (vector). The same
    figure gives the same bytes every time, in every format: no creation date, and the SVG's
    element ids drawn from a fixed salt."""
    import matplotlib  # heavy: matplotlib, only for figures

    fmt = Path(path).suffix.lstrip(".").lower()
    if fmt not in FIGURE_FORMATS:
        raise FieldError("figure_format", f"expected one of {list(FIGURE_FORMATS)}, got {fmt!r} (from {path})")
    metadata = {"pdf": {"CreationDate": None, "ModDate": None}, "svg": {"Date": None}}.get(fmt)

    def write(tmp):
        with matplotlib.rc_context({"svg.hashsalt": "cssat"}):
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format=fmt, metadata=metadata)

    atomic_write(path, write)


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
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar  # heavy: matplotlib, only for figures

    target = fov_m / 4
    k = 10 ** math.floor(math.log10(target))
    length = max((f * k for f in (1, 2, 5) if f * k <= target), default=k)
    text = f"{length:g} m" if length >= 1 else f"{length * 100:g} cm"
    ax.add_artist(AnchoredSizeBar(ax.transData, length / fov_m * size, text, "lower left", pad=0.3, color="w",
                                  frameon=False, size_vertical=max(size / 120, 0.5), fontproperties={"size": 7}))


