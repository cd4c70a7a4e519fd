"""The figure of the characterisation experiment (:mod:`cssat.experiments.forward.observed`): the
light curve with its gaps shown as gaps, the periodogram with the alternatives marked, the
phase-folded curve with the model, and the residuals. Returns a Figure (no pyplot)."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

__all__ = ["characterise_figure"]


def _with_gaps(t: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``t, v`` with a NaN after each gap (a step over 10× the median), so a line breaks there."""
    if len(t) < 3:
        return t, v
    gap = np.flatnonzero(np.diff(t) > 10 * np.median(np.diff(t))) + 1
    return np.insert(t.astype(float), gap, np.nan), np.insert(v.astype(float), gap, np.nan)


def characterise_figure(t: np.ndarray, y: np.ndarray, sigma: np.ndarray | None, res: dict[str, Any] | None,
                        model: np.ndarray | None, kind: str = "magnitude", trend: np.ndarray | None = None) -> Figure:
    """Four panels: ``y (T,)`` against ``t (T,)`` s (the model over it), the periodogram (the
    chosen period and its alternatives marked), the curve less each track's offset and trend
    (``trend (T,)``) folded at the best period with the model, and the residuals ``y − model``
    in units of ``sigma`` (or the rms)."""
    fig = Figure(figsize=(11, 7.5))
    (a, b), (c, d) = fig.subplots(2, 2)
    ylab = "magnitude" if kind == "magnitude" else "flux"
    a.plot(*_with_gaps(t, y), "-", lw=0.6, color="0.3")
    a.plot(t, y, ".", ms=1.5, color="k")
    if model is not None:
        a.plot(*_with_gaps(t, model), "-", lw=0.8, color="tab:orange", label="model")
        a.legend(fontsize=8)
    a.set_xlabel("seconds since the first sample")
    a.set_ylabel(ylab)
    a.set_title("light curve (gaps left open)", fontsize=10)
    for ax in (a, c):
        if kind == "magnitude":
            ax.invert_yaxis()
    if res is None or not len(res["periodogram"]["frequency_hz"]):
        for ax in (b, c, d):
            ax.text(0.5, 0.5, "no period analysis", ha="center", va="center", transform=ax.transAxes)
        return fig
    f, p = res["periodogram"]["frequency_hz"], res["periodogram"]["power"]
    b.plot(1.0 / f, p, lw=0.7, color="k")
    b.set_xscale("log")
    P = res["best_period_s"]
    b.axvline(P, color="tab:red", lw=1.2, label=f"chosen {P:.6g} s")
    for alt in res["alternatives"]:
        b.axvline(alt["period_s"], color="tab:blue", ls=":", lw=0.9)
        b.text(alt["period_s"], p.max() * 0.95, alt["relation"], fontsize=7, color="tab:blue", rotation=90, va="top")
    b.set_xlabel("period (s)")
    b.set_ylabel("Lomb–Scargle power")
    verdict = "periodic" if res["periodic"] else "not periodic"
    b.set_title(f"periodogram: {verdict}, FAP {res['fap']:.2g}", fontsize=10)
    b.legend(fontsize=8)
    phase = (t / P) % 1.0
    base = trend if trend is not None else np.zeros_like(y)
    c.plot(phase, y - base, ".", ms=1.5, color="k")
    if model is not None:
        order = np.argsort(phase)
        c.plot(phase[order], (model - base)[order], ".", ms=1, color="tab:orange")
    c.set_xlabel(f"phase at {P:.6g} s")
    c.set_ylabel(ylab + (" less each track's trend" if trend is not None else ""))
    c.set_title(f"folded; χ²/N {res['chi2_per_sample']:.3g}, {res['n_harmonics']} harmonics", fontsize=10)
    if model is not None:
        scale = sigma if sigma is not None else np.full_like(y, np.sqrt(np.mean((y - model) ** 2)) or 1.0)
        d.plot(t, (y - model) / scale, ".", ms=1.5, color="tab:blue")
        d.axhline(0, color="0.5", lw=0.8)
        d.set_ylabel("residual / σ" if sigma is not None else "residual / rms")
    d.set_xlabel("seconds since the first sample")
    d.set_title("residuals", fontsize=10)
    fig.tight_layout()
    return fig
