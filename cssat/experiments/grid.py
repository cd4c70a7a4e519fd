"""A grid: one image run per cell of a declared grid, in one job (the solver comparison, the
realism maps), run by the image forward model (:class:`~cssat.experiments.forward.PixelSensing`)
as a list of cell configs (:class:`GridRun`).

``grid.axes`` is a list; the first axis varies slowest. An axis is either a config key and its
values (``{name: m, key: cs.ratio, values: [0.088, 0.25, 0.807], label: m}``: each cell sets
``cs.ratio``; ``label`` names a metric of the cell that labels it, ``m1444``; default the value),
labelled cells of settings (``{name: solver, cells: {omp: {solver: …, denoiser: null}, …}}``:
each label's settings — dotted keys, whole nodes replaced — applied to the run's config), or
both (the labelled cells first: realism's ``paper`` column before its angular sizes). Every
cell is a copy of the experiment's config with its settings: no cell edits another's, and a
cell's measurement is reused by the next cell with the same forward settings (Φ drawn once).

Writes ``grid.csv`` (``grid.csv_name``; one row per cell: its labels, ``psnr``/``ssim`` of its
final image — denoised when it has a denoiser —, ``seconds`` of its reconstruction, and its
``phi_*``, ``noise_*``, ``geometry_*`` metrics), ``arrays.npz`` (``truth`` and each cell's image
under ``grid.name``'s name), the figures of ``grid.figures`` (``images``: reconstructions and error
maps, rows = the first axis; ``maps``: a PSNR map over the first two axes per label of the third;
``curves``: the ``grid.curves`` metrics against the first axis). Every row says whether the
cell scored more than 0.1 dB below the flat image of the true total flux (``below_flux_only``: a solver that lost
to the flux, not a limit of the physics; the maps mark it ``<``) and whether its detector
saturated (``unreachable``; marked ``sat``). Metrics: ``psnr_<cell>`` for
every cell; the headline ``psnr``/``ssim``: the best cell over the ``grid.headline.over`` axis at
the ``grid.headline.at`` index of the others (default the last).
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from cssat._checks import FieldError, choice_param
from cssat.experiments.files import write_csv, write_npz
from cssat.experiments.pipeline import execute, metrics_of, plan
from cssat.metrics import psnr
from cssat.plots import grid_curves_figure, grid_images_figure, grid_maps_figure, save_figure

log = logging.getLogger("cssat")

__all__ = ["GridRun", "GridMeasured", "cells"]

#: a cell is below the flat image of the true flux when it scores more than this under it (dB): the
#: flux-only solver's own flat image, of a *fitted* flux, loses ~1e-3 dB to it
FLUX_TOLERANCE_DB = 0.1

#: metric prefixes copied into every row of ``grid.csv``
ROW_PREFIXES = ("phi_", "noise_", "geometry_", "atmosphere_", "solver_", "info_", "motion_")


def _axes(grid: Any) -> list[dict[str, Any]]:
    """The axes as ``{name, label, settings: [(label, {key: value})]}``, checked."""
    out = []
    for i, ax in enumerate(grid.get("axes") or []):
        where = f"grid.axes[{i}]"
        cells = [(str(k), dict(v or {})) for k, v in (ax.get("cells") or {}).items()]
        if ax.get("key") is not None:
            values = list(ax.get("values") or [])
            if not values and not cells:
                raise FieldError(f"{where}.values", "expected at least one value")
            cells += [(v, {str(ax["key"]): v}) for v in values]
        if not cells:
            raise FieldError(where, "expected {key, values} and/or {cells: {label: settings}}")
        name = str(ax.get("name") or (str(ax["key"]).rsplit(".", 1)[-1] if ax.get("key") else f"axis{i}"))
        out.append({"name": name, "label": ax.get("label"), "cells": cells})
    if not out:
        raise FieldError("grid.axes", "expected at least one axis")
    return out


def cells(cfg: Any) -> list[tuple[dict[str, Any], Any]]:
    """``[(labels by axis, cell config)]`` of ``cfg``'s grid, the first axis slowest."""
    from omegaconf import OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    base = OmegaConf.to_container(cfg, resolve=True)
    base.pop("grid", None)
    base.pop("hydra", None)
    out = []
    axes = _axes(cfg.grid)
    for combo in itertools.product(*[ax["cells"] for ax in axes]):
        c = OmegaConf.create(base)
        labels = {}
        for ax, (label, settings) in zip(axes, combo):
            labels[ax["name"]] = label
            for key, value in settings.items():
                OmegaConf.update(c, key, value, merge=False, force_add=True)
        out.append((labels, c))
    return out


def _name(fmt: str | None, labels: dict[str, Any]) -> str:
    if not fmt:
        return "_".join(str(v) for v in labels.values())
    try:
        return str(fmt).format(**labels)
    except (KeyError, IndexError, ValueError) as err:
        raise FieldError("grid.name", f"{fmt!r} names an axis that is not in {list(labels)} ({err})") from None


@dataclass
class GridMeasured:
    """What a grid's ``measure`` hands on: a row of metrics per cell, each cell's denoised image
    ``(n, n)`` by its name, and the truth ``(n, n)``."""

    rows: list[dict[str, Any]]
    images: dict[str, Any]
    truth: Any


class GridRun:
    """A grid run of the image forward models: a list of cell configs, each planned, executed and
    scored as one image run, then the grid's metrics, table and figures (the module's docstring)."""

    def __init__(self, cfg: Any, run_: Any):
        """Every cell of ``cfg.grid`` planned before any work."""
        self.cfg = cfg
        g = self.g = cfg.grid
        self.axes = _axes(g)
        self.todo = cells(cfg)
        self.plans = [plan(c, run_) for _, c in self.todo]  # every cell checked before any work
        self.figures = [choice_param(f, "grid.figures", ("images", "maps", "curves", "information"))
                        for f in (g.get("figures") or [])]

    def measure(self, run_: Any) -> GridMeasured:
        """Every cell executed and scored, in order (a cell's Φ reused by the next with the same forward settings)."""
        cfg, g, axes = self.cfg, self.g, self.axes
        cache: dict = {}
        rows, images, truth = [], {}, None
        for (labels, _), p in zip(self.todo, self.plans):
            before = {k: run_.seconds.get(k, 0.0) for k in ("solver", "dictionary", "denoise")}
            res = execute(p, run_, cache)
            with run_.stage("score"):
                met = metrics_of(p, run_, res)
                t = res["measured"].truth
                met["psnr_flux_only"] = psnr(t, np.full_like(t, t.mean()), data_range=1.0)
            seconds = sum(run_.seconds.get(k, 0.0) - v for k, v in before.items())
            for ax in axes:  # a value axis labelled by a metric of the cell (cs.ratio -> m1444)
                if ax["label"] is not None:
                    labels[ax["name"]] = met.get(ax["label"], labels[ax["name"]])
            name = _name(g.get("name"), labels)
            rec = res["recs"][0]
            truth = res["measured"].truth
            images[name] = rec.denoised
            row = {**labels, "cell": name, "psnr": met["psnr_denoised"], "ssim": met["ssim_denoised"], "psnr_raw": met["psnr"],
                   "seconds": seconds, "iterations": met.get("solver_iterations", met.get("omp_atoms"))}
            row.update({k: v for k, v in met.items() if k.startswith(ROW_PREFIXES) and isinstance(v, (int, float, str, type(None)))})
            row["below_flux_only"] = bool(row["psnr"] < met["psnr_flux_only"] - FLUX_TOLERANCE_DB)  # the true flux's flat image
            row["unreachable"] = met.get("noise_reachable") is False or bool(met.get("noise_saturated") or 0)
            rows.append(row)
            log.info("%s: %s PSNR %.2f dB, SSIM %.3f, %.1f s", cfg.get("experiment_name"), name, row["psnr"], row["ssim"], seconds)
        return GridMeasured(rows, images, truth)

    def score(self, run_: Any, m: GridMeasured) -> dict[str, Any]:
        return _metrics(self.g, self.axes, m.rows, self.plans[0], m.truth)

    def write(self, run_: Any, m: GridMeasured, metrics: dict[str, Any]) -> None:
        g = self.g
        write_csv(run_.out_dir / str(g.get("csv_name") or "grid.csv"), m.rows)
        write_npz(run_.out_dir / "arrays.npz", truth=m.truth, **m.images)
        _figures(g, self.figures, self.axes, m.rows, m.images, m.truth, run_, metrics)

    def headline(self, metrics: dict[str, Any]) -> None:
        """None: each cell's line is logged as it is scored."""
        return None


def _metrics(g: Any, axes: list[dict], rows: list[dict], p: Any, truth: Any) -> dict[str, Any]:
    """Every cell's PSNR and the headline: the best over ``headline.over`` at ``headline.at``."""
    names = [ax["name"] for ax in axes]
    head = g.get("headline") or {}
    over = choice_param(head.get("over", names[-1]), "grid.headline.over", names)
    at = dict(head.get("at") or {})
    pick = {}
    for ax in axes:
        if ax["name"] == over:
            continue
        values = list(dict.fromkeys(r[ax["name"]] for r in rows))
        pick[ax["name"]] = values[int(at.get(ax["name"], -1))]
    best = max((r for r in rows if all(r[k] == v for k, v in pick.items())), key=lambda r: r["psnr"])
    out: dict[str, Any] = {"psnr": best["psnr"], "ssim": best["ssim"], f"best_{over}": best[over], "best_cell": best["cell"],
                           "grid_axes": names, "n": int(truth.shape[0]), "n_pixels": int(truth.size),
                           "psnr_flux_only": psnr(truth, np.full_like(truth, truth.mean()), data_range=1.0)}
    out.update({k: v for k, v in pick.items()})
    first = names[0]
    for label in dict.fromkeys(r[first] for r in rows):  # Φ's statistics per label of the first axis
        row = next(r for r in rows if r[first] == label)
        out.update({f"{k}_{label}": v for k, v in row.items() if k.startswith("phi_")})
    for r in rows:
        out[f"psnr_{r['cell']}"] = r["psnr"]
        out[f"cell_seconds_{r['cell']}"] = r["seconds"]
    return out


def _figures(g, figures, axes, rows, images, truth, run_, metrics) -> None:
    stem = str(g.get("figure_name") or "grid")
    if "images" in figures:
        save_figure(grid_images_figure(truth, axes, rows, images), run_.figure(stem))
    if "maps" in figures:
        for label, fig in grid_maps_figure(axes, rows, metrics.get("psnr_flux_only")).items():
            save_figure(fig, run_.figure(f"{stem}_{label}"))
    if "information" in figures:  # solver-independent: the first label of the third axis
        title = (f"modes (of the {rows[0].get('info_n_modes')} lowest DCT modes, flux excluded) measurable at "
                 "Cramér–Rao SNR ≥ 1\nΦ and the other modes known exactly: an optimistic (oracle) bound")
        first = next(iter(grid_maps_figure(axes, rows, None, metric="info_modes", title=title, below=False,
                                           fmt=".0f").values()))
        save_figure(first, run_.figure(f"{stem}_information"))
    if "curves" in figures:
        save_figure(grid_curves_figure(axes, rows, list(g.get("curves") or [])), run_.figure(f"{stem}_curves"))
