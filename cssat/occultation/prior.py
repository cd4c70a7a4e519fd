"""The silhouette's prior chosen by telescopes held out of the fit, and the union of superellipses
fitted as a multi-start: :func:`choose_prior`, :func:`shape_starts`.

A fit of a few superellipses (:mod:`cssat.occultation.shapes`) from one start is bimodal: started
from the pixel reconstruction's connected components, the number of components decides the
optimum, and that number flips with the last bits of the pixel fit (a 1e-9 change of a constant,
or the thread count's order of the floating-point sums). So the shapes are fitted here from
*every* number of components in ``components`` (1–4 by default) and ``n_starts`` seeded starts
each, and the candidate kept is the one that best predicts telescopes it was not fitted to:

- **Starts** (:func:`shape_starts`): a weighted k-means of the pixel reconstruction's pixels into
  ``K`` clusters (weights ``clip(2m − 0.5, 0, 1)``: continuous in the mask, no threshold's
  connectivity), seeded k-means++ starts, each cluster's second moments a superellipse (the
  half-axes of the equivalent ellipse, exponent 6); starts after the first also jittered
  (centres by 0.2 of the minor half-axis, half-axes by 20 %, angles by 0.2 rad).
- **Every candidate on all telescopes**: each (number of shapes, start) fitted through the full
  forward model (:func:`~cssat.occultation.fit_shape_params`); per number of shapes the start
  with the lowest χ² (rounded to ``decimals``; equal optima tie, the first start kept).
- **Held-out χ²**: the telescopes split into two folds (alternate rows); on each fold the pixels
  (TV, from the empty mask) fitted and, per number of shapes, its best start's index started
  from that fold's pixels and fitted; each scored by the χ² of the other fold's series, summed
  over the folds (one refit per number of shapes and fold, not per start: the starts are told
  apart by the χ² on all telescopes, the number of shapes by telescopes held out).
- **The choice**: the fewest shapes whose held-out χ² is within ``parsimony`` (Δχ² = 1) of the
  lowest; the answer is that number's best start on all telescopes. ``auto``: the shapes are
  kept when their held-out χ² (rounded) is below the pixels'.
- **The spread**: over the *near-best* candidates (their number of shapes' held-out χ² within
  ``near`` = 4 of the lowest, their χ² on all telescopes within 4 of that number's best: what the
  data cannot tell from the answer), the range of the held-out χ², of the silhouette's area (m²,
  pixels ≥ 0.5) and of its centroid (east, north, m).

Why this flips far less: no discrete decision is taken on a quantity that moves with the last
bits — the number of components is enumerated, not read off a thresholded mask; the starts are
continuous in the mask; the choices compare χ² differences of order 1 and more (rounded), which a
1e-9 change or another thread count does not reach unless an L-BFGS path itself diverges into
another local optimum (possible: then the best of the starts, not one start, decides). Tested at
one and two threads and after a 1e-9 change. What it does not fix: two optima whose χ² agree to
within the rounding are told apart by the tie rules, not by the data (the spread says so).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import torch

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.occultation.invert import invert_silhouette, recorded
from cssat.occultation.results import PriorChoice
from cssat.occultation.shapes import fit_shape_params, heldout_inputs

__all__ = ["shape_starts", "choose_prior"]


def shape_starts(mask: Any, pixel_m: float, k: int, *, n_starts: int = 1, seed: int = 0,
                 min_area_m2: float = 0.5) -> list[np.ndarray]:
    """``n_starts`` starting unions of ``k`` superellipses, each ``(k, 6)`` (rows as in
    :func:`~cssat.occultation.render_shapes`), from a pixel reconstruction ``mask (H, W)`` in
    [0, 1] on centred pixels of ``pixel_m`` (m; columns east, rows north): a weighted k-means of
    the pixels (weights ``clip(2m − 0.5, 0, 1)``, seeded k-means++ with the seed
    ``(seed, k, start)``, 50 Lloyd steps), each cluster's weighted centroid and second moments
    (``a, b = 2√λ``: the equivalent ellipse's half-axes, at least one pixel; the angle of the major
    axis from north towards east; exponent 6); starts after the first jittered (the module's
    docstring). Clusters ordered by weight. Raises :class:`~cssat._checks.FieldError`
    (``init_mask``) when the weighted area is below ``min_area_m2``."""
    m = np.clip(np.asarray(mask, dtype=np.float64), 0.0, 1.0)
    if m.ndim != 2:
        raise FieldError("init_mask", f"expected a 2-D mask, got shape {m.shape}")
    px = float_param(pixel_m, "pixel_m", 0.0, open_lo=True)
    k = int_param(k, "components", 1, 16)
    n_starts = int_param(n_starts, "n_starts", 1, 100)
    H, W = m.shape
    w_all = np.clip(2.0 * m - 0.5, 0.0, 1.0)
    if w_all.sum() * px * px < float(min_area_m2):
        raise FieldError("init_mask", f"no component of at least {min_area_m2} m² to start the shapes from")
    rr, cc = np.nonzero(w_all > 0)
    w = w_all[rr, cc]
    X = np.stack([(cc + 0.5 - W / 2) * px, (rr + 0.5 - H / 2) * px], axis=1)  # (N, 2) east, north
    out = []
    for s in range(n_starts):
        rng = np.random.default_rng([int(seed) & 0x7FFFFFFF, k, s])
        # k-means++ (weighted): the first centre drawn by weight, the next by weight × squared distance
        centres = [X[rng.choice(len(X), p=w / w.sum())]]
        for _ in range(1, k):
            d2 = np.min([((X - c) ** 2).sum(1) for c in centres], axis=0)
            p = w * d2
            centres.append(X[rng.choice(len(X), p=p / p.sum())] if p.sum() > 0 else X[rng.integers(len(X))])
        C = np.array(centres)
        for _ in range(50):
            lab = np.argmin(((X[:, None, :] - C[None]) ** 2).sum(-1), axis=1)
            newC = C.copy()
            for j in range(k):
                sel = lab == j
                if w[sel].sum() > 0:
                    newC[j] = (w[sel, None] * X[sel]).sum(0) / w[sel].sum()
            if np.array_equal(newC, C):
                break
            C = newC
        lab = np.argmin(((X[:, None, :] - C[None]) ** 2).sum(-1), axis=1)
        rows = []
        for j in range(k):
            sel = lab == j
            wj = w[sel]
            if wj.sum() <= 0:  # an empty cluster: a one-pixel shape at its centre (the fit may grow it or leave it)
                rows.append((float(wj.sum()), [C[j, 0], C[j, 1], math.log(px), math.log(px), 0.0, math.log(4.0)]))
                continue
            mu = (wj[:, None] * X[sel]).sum(0) / wj.sum()
            d = X[sel] - mu
            cov = (wj[:, None, None] * d[:, :, None] * d[:, None, :]).sum(0) / wj.sum() + px * px / 12 * np.eye(2)
            lam, vec = np.linalg.eigh(cov)
            a, b = max(2 * math.sqrt(max(lam[1], 0.0)), px), max(2 * math.sqrt(max(lam[0], 0.0)), px)
            e = vec[:, 1] if vec[1, 1] >= 0 else -vec[:, 1]  # the major axis, pointing north (the angle mod π)
            rows.append((float(wj.sum()), [mu[0], mu[1], math.log(a), math.log(b), math.atan2(e[0], e[1]), math.log(4.0)]))
        rows.sort(key=lambda r: -r[0])
        P = np.array([r[1] for r in rows], dtype=np.float64)
        if s > 0:
            b = np.exp(P[:, 3])
            P[:, 0:2] += 0.2 * b[:, None] * rng.standard_normal((k, 2))
            P[:, 2:4] += math.log(1.2) * rng.standard_normal((k, 2))
            P[:, 4] += 0.2 * rng.standard_normal(k)
        out.append(P)
    return out


def _area_centroid(mask: np.ndarray, pixel_m: float) -> tuple[float, float, float]:
    """The area (m², pixels ≥ 0.5) and the centroid (east, north; m) of those pixels."""
    H, W = mask.shape
    rr, cc = np.nonzero(mask >= 0.5)
    if not len(rr):
        return 0.0, math.nan, math.nan
    return (float(len(rr) * pixel_m * pixel_m), float(((cc + 0.5 - W / 2) * pixel_m).mean()),
            float(((rr + 0.5 - H / 2) * pixel_m).mean()))


def choose_prior(series: Any, sigma: Any, shape: tuple[int, int], pixel_m: float, wavelength_m: Any, distance_m: float,
                 positions_m: Any, velocity_m_s: Any, times_s: Any, *, init_mask: Any, prior: str = "auto",
                 kernel: Any = None, weights: Any = None, ground: Any = None, tv: float = 0.3, iters: int = 300,
                 shape_iters: int = 200, components: Sequence[int] = (1, 2, 3, 4), n_starts: int = 3, seed: int = 0,
                 parsimony: float = 1.0, near: float = 4.0, decimals: int = 2) -> tuple[np.ndarray, PriorChoice]:
    """The silhouette under the prior ``prior`` — ``pixels`` (``init_mask`` returned as it is),
    ``shapes`` (the multi-start union of superellipses, always) or ``auto`` (the shapes where
    held-out telescopes prefer them to the pixels) — for the recording ``series (J, K)``, 1σ
    ``sigma`` and the geometry's arguments of :func:`~cssat.occultation.invert_silhouette`
    (``kernel``, ``weights``, ``ground`` likewise); ``init_mask (H, W)`` the pixel reconstruction
    on all telescopes; ``tv``, ``iters`` the folds' pixel fits, ``shape_iters`` the shapes'
    L-BFGS iterations a stage; ``components`` the numbers of superellipses tried, ``n_starts``
    the seeded starts each. The choice and the spread: the module's docstring.

    Returns ``(mask (H, W), choice)``, ``choice`` a :class:`~cssat.occultation.results.PriorChoice`:
    ``used`` (``pixels`` or ``shapes``), ``params (K, 6)`` of the kept shapes (None for pixels),
    ``n_shapes``, ``start``, ``chi2_per_sample_shapes``, ``heldout_chi2_pixels``,
    ``heldout_chi2_shapes``, ``candidates`` (per candidate: ``n_shapes``, ``start``,
    ``heldout_chi2``, ``chi2_per_sample``, ``area_m2``, ``centroid_east_m``, ``centroid_north_m``),
    ``candidate_masks (C, H, W)``, ``near_best`` (the near-best candidates' indices) and
    ``spread`` (their ranges). Raises :class:`~cssat._checks.FieldError` (``init_mask``) for
    ``shapes`` when no start can be made (for ``auto`` the pixels are kept)."""
    prior = choice_param(prior, "invert.prior", ("auto", "pixels", "shapes"))
    m0 = np.asarray(init_mask, dtype=np.float64)
    empty = {"used": "pixels", "params": None, "n_shapes": None, "start": None, "chi2_per_sample_shapes": None,
             "heldout_chi2_pixels": None, "heldout_chi2_shapes": None, "candidates": [], "candidate_masks": None,
             "kept_candidate": None, "near_best": [], "spread": None}
    if prior == "pixels":
        return m0, PriorChoice(empty)
    Ks = sorted({int_param(k, "components", 1, 16) for k in components})
    if not Ks:
        raise FieldError("components", "give at least one number of superellipses to try")
    n_starts = int_param(n_starts, "n_starts", 1, 100)
    parsimony, near = float_param(parsimony, "parsimony", 0.0), float_param(near, "near", 0.0)
    y, s, P = heldout_inputs(series, sigma, positions_m)
    J = len(P)
    kw = {"kernel": kernel, "weights": weights, "ground": ground}
    n = y.size

    def starts(mask):
        return {k: shape_starts(mask, pixel_m, k, n_starts=n_starts, seed=seed) for k in Ks}

    try:
        full_starts = starts(m0)
    except FieldError:
        if prior == "shapes":
            raise
        return m0, PriorChoice(empty)

    # every candidate (number of shapes, start) on all telescopes: the answer is one of them
    geo = (y, s, shape, pixel_m, wavelength_m, distance_m, P, velocity_m_s, times_s)
    rows, masks, params = [], [], []
    for k in Ks:
        for j, st in enumerate(full_starts[k]):
            mk, th, info = fit_shape_params(*geo, start=st, iters=shape_iters, **kw)
            area, ce, cn = _area_centroid(mk, pixel_m)
            rows.append({"n_shapes": k, "start": j, "chi2": info["chi2_per_sample"] * n,
                         "chi2_per_sample": info["chi2_per_sample"], "area_m2": area, "centroid_east_m": ce,
                         "centroid_north_m": cn})
            masks.append(mk)
            params.append(th)
    # per number of shapes, the start that fits all telescopes best (χ² rounded: equal optima tie, the first start kept)
    best_of = {k: min((i for i, r in enumerate(rows) if r["n_shapes"] == k),
                      key=lambda i: (round(rows[i]["chi2"], decimals), rows[i]["start"])) for k in Ks}

    # the held-out χ²: per number of shapes, its best start refitted on one fold from that fold's pixels, scored on the other
    held = {k: 0.0 for k in Ks}
    held_pixels = 0.0
    for fold in (0, 1):
        train, test = np.arange(J) % 2 != fold, np.arange(J) % 2 == fold
        geo_f = (y[train], s[train], shape, pixel_m, wavelength_m, distance_m, P[train], velocity_m_s, times_s)

        def heldout(mask):
            with torch.no_grad():
                pred = recorded(torch.as_tensor(mask), pixel_m, wavelength_m, distance_m, P[test], velocity_m_s, times_s,
                                **kw).numpy()
            return float((((pred - y[test]) / s[test]) ** 2).sum())

        mp, _ = invert_silhouette(*geo_f, tv=tv, iters=iters, seed=seed, **kw)
        held_pixels += heldout(mp)
        try:
            fold_starts = starts(mp)
        except FieldError:  # no start on this fold: the shapes cannot be tested
            held = {k: math.inf for k in Ks}
            continue
        for k in Ks:
            if math.isfinite(held[k]):
                mk, _, _ = fit_shape_params(*geo_f, start=fold_starts[k][rows[best_of[k]]["start"]], iters=shape_iters, **kw)
                held[k] += heldout(mk)
    for r in rows:
        r["heldout_chi2"] = held[r["n_shapes"]]
    if not any(math.isfinite(h) for h in held.values()):
        if prior == "shapes":
            raise FieldError("init_mask", "no fold's pixel fit has a component to start the shapes from")
        return m0, PriorChoice({**empty, "heldout_chi2_pixels": held_pixels, "heldout_chi2_shapes": math.inf})
    best = min(held.values())
    k_best = min((k for k in Ks if held[k] <= best + parsimony), key=lambda k: (k, round(held[k], decimals)))
    i = best_of[k_best]
    near_best = [j for j, r in enumerate(rows) if held[r["n_shapes"]] <= best + near
                 and r["chi2"] <= rows[best_of[r["n_shapes"]]]["chi2"] + near]

    def rng(key):
        v = [rows[j][key] for j in near_best]
        return [float(min(v)), float(max(v))]

    spread = {"n_near_best": len(near_best), "n_shapes": sorted({rows[j]["n_shapes"] for j in near_best}),
              "heldout_chi2": rng("heldout_chi2"), "area_m2": rng("area_m2"), "centroid_east_m": rng("centroid_east_m"),
              "centroid_north_m": rng("centroid_north_m")}
    hv = np.array([r["heldout_chi2"] for r in rows])
    used = "shapes" if prior == "shapes" or round(float(hv[i]), decimals) < round(held_pixels, decimals) else "pixels"
    out = {"used": used, "params": params[i] if used == "shapes" else None, "n_shapes": rows[i]["n_shapes"],
           "start": rows[i]["start"], "chi2_per_sample_shapes": rows[i]["chi2_per_sample"], "heldout_chi2_pixels": held_pixels,
           "heldout_chi2_shapes": float(hv[i]), "candidates": rows, "candidate_masks": np.array(masks),
           "kept_candidate": i, "near_best": near_best, "spread": spread}
    return (masks[i] if used == "shapes" else m0), PriorChoice(out)
