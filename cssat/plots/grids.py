"""Sweep and grid figures: a metric against swept values, maps, and the grid of reconstructions."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from cssat.plots.base import _figure, error_panels, image_panels

if TYPE_CHECKING:
    from matplotlib.figure import Figure


#: swept config keys, and metrics, in words for the sweep plots
#: metric keys in words (the axis labels of the figures)
WORDS = {"psnr": "PSNR (dB)", "ssim": "SSIM", "psnr_denoised": "PSNR after denoising (dB)",
         "ssim_denoised": "SSIM after denoising", "phi_effective_rank_centered": "effective rank of Φ's fluctuations",
         "phi_effective_rank": "effective rank of Φ", "phi_scintillation_index": "scintillation index σ_I²",
         "info_modes": "measurable modes (Cramér–Rao SNR ≥ 1)"}


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
                     metric: str = "psnr", *, title: str | None = None, below: bool = True,
                     fmt: str = ".1f") -> dict[str, Figure]:
    """``metric`` over the first two axes of a grid (columns × rows), one map per label of the
    third axis (or one map): ``{label: Figure}``; ``flux_only`` (the flat image's PSNR) in the
    title. Cells are marked ``<`` where the row says ``below_flux_only`` (when ``below``) and
    hatched ``sat`` where it says ``unreachable``; ``title`` replaces the label's, ``fmt`` formats
    the values."""
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
        marks = set()
        for i, ln in enumerate(lines):
            for j, c in enumerate(cols):
                if np.isnan(grid[i, j]):
                    continue
                key = tuple(v for v in (c, ln, third) if v is not None) if len(axes) > 1 else (c,)
                row = by.get(key, {})
                tag = ("<" if below and row.get("below_flux_only") else "") + (" sat" if row.get("unreachable") else "")
                marks.update(t for t in ("<", "sat") if t in tag)
                ax.text(j, i, f"{grid[i, j]:{fmt}}{tag}", ha="center", va="center", color="w", fontsize=8)
                if row.get("unreachable"):
                    ax.add_patch(_hatch(j, i))
        ax.set_xlabel(_words(axes[0]["name"]))
        fig.colorbar(im, ax=ax, label=_words(metric))
        legend = "; ".join(t for t, on in (("< below the flux alone: the solver lost", "<" in marks),
                                            ("sat: the detector saturates (unreachable)", "sat" in marks)) if on)
        head = title if title is not None else f"{third if third is not None else ''}: {_words(metric).split(' (')[0]}"
        ax.set_title(head
                     + (f"\n(the total flux alone gives {flux_only:.1f} dB)" if flux_only is not None else "")
                     + (f"\n{legend}" if legend else ""), fontsize=9)
        fig.tight_layout()
        figs[str(third) if third is not None else "map"] = fig
    return figs


def _hatch(j: int, i: int):
    """A hatched cell at column ``j``, row ``i`` of an ``imshow`` map."""
    from matplotlib.patches import Rectangle  # heavy: matplotlib, only for figures

    return Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="//", edgecolor="0.85", linewidth=0)


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
