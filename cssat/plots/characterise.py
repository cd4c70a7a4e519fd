"""The figure of the characterisation experiment (:mod:`cssat.experiments.forward.observed`): the
light curve with its gaps shown as gaps, the periodogram with the alternatives and the file's
published period marked, the phase-folded curve with the model, and the residuals. Titled with
the object, its NORAD id, the track(s) and the UTC start; the magnitude axes say which magnitude
(band, apparent or reduced to 1000 km) and the time axes the epoch. Returns a Figure (no pyplot)."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

__all__ = ["characterise_figure", "figure_labels"]


def _with_gaps(t: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``t, v`` with a NaN after each gap (a step over 10× the median), so a line breaks there."""
    if len(t) < 3:
        return t, v
    gap = np.flatnonzero(np.diff(t) > 10 * np.median(np.diff(t))) + 1
    return np.insert(t.astype(float), gap, np.nan), np.insert(v.astype(float), gap, np.nan)


def _grouped(alternatives: list[dict[str, Any]], chosen: float, rtol: float = 0.03,
             near: float = 0.01) -> list[tuple[float, list[str]]]:
    """The alternatives' periods (s) grouped within ``rtol`` of each other, each with its
    relations' names; those within ``near`` of the ``chosen`` period left out (its own line)."""
    groups: list[tuple[float, list[str]]] = []
    for alt in sorted(alternatives, key=lambda a: a["period_s"]):
        p = float(alt["period_s"])
        if not np.isfinite(p) or abs(p / chosen - 1) < near:
            continue
        if groups and abs(p / groups[-1][0] - 1) < rtol:
            if alt["relation"] not in groups[-1][1]:
                groups[-1][1].append(alt["relation"])
        else:
            groups.append((p, [alt["relation"]]))
    return groups


def figure_labels(meta: dict[str, Any], metrics: dict[str, Any], kind: str = "magnitude",
                  band: str | None = None) -> dict[str, Any]:
    """The words of the figure from the file's metadata ``meta`` (``object_id`` — the NORAD id
    —, ``name``, ``format``, ``published_period_s``) and the run's ``metrics`` (``track``,
    ``start_utc``, ``magnitude_system``, ``period_magnitudes``): ``title``, ``ylabel``,
    ``epoch`` (the UTC start the time axes count from), ``published_period_s`` (s, or None) and
    ``published_label`` (``"MMT"`` for an MMT-9 file, else ``"published"``). ``band``: the
    magnitudes' band (e.g. MMT's ``Clear``; None: not named)."""
    obj = str(meta.get("object_id") or "").strip()
    who = " ".join(x for x in (f"NORAD {obj}" if obj.isdigit() else obj, str(meta.get("name") or "").strip()) if x)
    tracks = [x for x in str(metrics.get("track") or "").split(";") if x]
    track = ("track " + tracks[0] if len(tracks) == 1 else f"tracks {', '.join(tracks[:3])}"
             + (f" (+{len(tracks) - 3} more)" if len(tracks) > 3 else "")) if tracks else ""
    start = str(metrics.get("start_utc") or "")
    epoch = start.replace("T", " ")[:23] + " UTC" if start else "the first sample"
    title = " · ".join(x for x in (who or "the light curve", track, epoch if start else "") if x)
    if kind == "magnitude":
        system = metrics.get("period_magnitudes") or metrics.get("magnitude_system") or "apparent"
        system = {"apparent, reduced to a range of 1000 km": "apparent, reduced to 1000 km",
                  "normalised: 1000 km, phase 90°": "reduced to 1000 km and phase 90°"}.get(system, system)
        ylabel = f"{band + ' ' if band else ''}magnitude ({system})"
    else:
        ylabel = "flux (the file's unit)"
    pub = meta.get("published_period_s")
    return {"title": title, "ylabel": ylabel, "epoch": epoch, "published_period_s": float(pub) if pub else None,
            "published_label": "MMT" if meta.get("format") == "mmt" else "published"}


def characterise_figure(t: np.ndarray, y: np.ndarray, sigma: np.ndarray | None, res: dict[str, Any] | None,
                        model: np.ndarray | None, kind: str = "magnitude", trend: np.ndarray | None = None,
                        labels: dict[str, Any] | None = None, verdict: str | None = None) -> Figure:
    """Four panels: ``y (T,)`` against ``t (T,)`` s (the model over it), the periodogram (the
    chosen period, its alternatives and the published period marked), the curve less each
    track's offset and trend (``trend (T,)``) folded at the best period with the model, and the
    residuals ``y − model`` in units of ``sigma`` (or the rms). ``labels``: the words of
    :func:`figure_labels` (title, magnitude axis, epoch, published period); ``verdict``: the
    period verdict's word (default: from ``res["periodic"]``)."""
    lab = {"title": None, "ylabel": "magnitude" if kind == "magnitude" else "flux", "epoch": "the first sample",
           "published_period_s": None, "published_label": "published", **(labels or {})}
    fig = Figure(figsize=(12, 8))
    if lab["title"]:
        fig.suptitle(lab["title"], fontsize=11)
    (a, b), (c, d) = fig.subplots(2, 2)
    tlabel = f"s since {lab['epoch']}"
    a.plot(*_with_gaps(t, y), "-", lw=0.6, color="0.3")
    a.plot(t, y, ".", ms=1.5, color="k")
    if model is not None:
        a.plot(*_with_gaps(t, model), "-", lw=0.8, color="tab:orange", label="model")
        a.legend(fontsize=8, loc="best")
    a.set_xlabel(tlabel)
    a.set_ylabel(lab["ylabel"], fontsize=9)
    a.set_title("light curve (gaps left open)", fontsize=10)
    for ax in (a, c):
        if kind == "magnitude":
            ax.invert_yaxis()
    pub, who = lab["published_period_s"], lab["published_label"]
    if res is None or not len(res["periodogram"]["frequency_hz"]):
        for ax in (b, c, d):
            ax.text(0.5, 0.5, "no period analysis", ha="center", va="center", transform=ax.transAxes)
        fig.tight_layout()
        return fig
    f, p = res["periodogram"]["frequency_hz"], res["periodogram"]["power"]
    b.plot(1.0 / f, p, lw=0.7, color="k")
    b.set_xscale("log")
    P = res["best_period_s"]
    if verdict is None:
        verdict = res.get("verdict") or ("undetermined" if res["periodic"] is None else
                                          "periodic" if res["periodic"] else "not periodic")
    b.axvline(P, color="tab:red", lw=1.2, label=f"{'chosen' if verdict == 'periodic' else 'best'} {P:.4g} s")
    lo, hi = float(np.min(1.0 / f)), float(np.max(1.0 / f))
    shown = [a for a in res["alternatives"] if lo <= a["period_s"] <= hi]  # the periodogram's range only
    for alt in shown:
        b.axvline(alt["period_s"], color="tab:blue", ls=":", lw=0.9)
    # one label per group of alternatives within 2 % of the log axis' width (P/2 and a peak at the same
    # period; two peaks a hair apart), the labels staggered down the panel: no two overprint
    width = 10 ** (0.02 * np.log10(max(hi / lo, 1.0 + 1e-9))) - 1.0
    for k, (period, names) in enumerate(_grouped(shown, P, rtol=max(width, 0.01))):
        left_edge = np.log(period / lo) < 0.04 * np.log(max(hi / lo, 1.0 + 1e-9))  # the label inside the axes
        b.text(period, 0.98 - 0.14 * (k % 2), " · ".join(names), fontsize=7, color="tab:blue", rotation=90,
               va="top", ha="left" if left_edge else "right", transform=b.get_xaxis_transform())
    pub_in = pub is not None and lo <= pub <= hi
    if pub is not None:
        b.axvline(pub, color="tab:green", ls="--", lw=1.2,
                  label=f"{who} {pub:.4g} s" if pub_in else None)
        if not pub_in:
            b.plot([], [], color="tab:green", ls="--", label=f"{who} {pub:.4g} s (outside {lo:.3g}–{hi:.3g} s)")
    b.set_xlim(lo, hi)
    b.set_ylim(0.0, 1.6 * float(np.max(p)) if np.max(p) > 0 else 1.0)  # the top third for the labels and the legend
    b.set_xlabel("period (s)")
    b.set_ylabel("Lomb–Scargle power")
    b.set_title(f"periodogram: {verdict}, FAP {res['fap']:.2g}", fontsize=10)
    b.legend(fontsize=8, loc="best", framealpha=0.9)
    phase = (t / P) % 1.0
    base = trend if trend is not None else np.zeros_like(y)
    c.plot(phase, y - base, ".", ms=1.5, color="k", label=f"data folded at {P:.4g} s")
    if model is not None:
        order = np.argsort(phase)
        c.plot(phase[order], (model - base)[order], ".", ms=1, color="tab:orange", label="model")
    if pub is not None:
        c.plot([], [], color="tab:green", ls="--", label=f"{who} {pub:.4g} s (ours {P / pub - 1:+.1%})")
    c.legend(fontsize=8, loc="best", framealpha=0.9, markerscale=4)
    c.set_xlabel(f"phase at {P:.6g} s")
    c.set_ylabel(lab["ylabel"] + (",\nless each track's offset and slope" if trend is not None else ""), fontsize=9)
    c.set_title(f"folded; χ²/N {res['chi2_per_sample']:.3g}, {res['n_harmonics']} harmonics", fontsize=10)
    if model is not None:
        scale = sigma if sigma is not None else np.full_like(y, np.sqrt(np.mean((y - model) ** 2)) or 1.0)
        d.plot(t, (y - model) / scale, ".", ms=1.5, color="tab:blue")
        d.axhline(0, color="0.5", lw=0.8)
        d.set_ylabel("residual / σ" if sigma is not None else "residual / rms")
    d.set_xlabel(tlabel)
    d.set_title("residuals", fontsize=10)
    fig.tight_layout()
    return fig
