"""The finer parametric family fitted from a plain box-wing: reflector dishes, panelled wings,
booms and an Earth-deck module (:func:`~cssat.inversion.parametric.param_names`' ``parts``)
started at generic places on the fitted bus and wing, each start fitted briefly, the best in full.

The path :func:`fit_parts` takes (measured in BENCHMARKS.md, "A finer family" and "Albedos solved",
on three box-wing-with-dishes meshes the family does not contain)::

    p9, _ = fit_box_wing(y, sun, obs, box_wing_start(egi.normals, egi.areas), sigma=sigma)
    p9 = with_albedo_prior(p9, param_names(), cd_bus=0.3)          # optional: the absolute size
    p, info = fit_parts(y, sun, obs, p9, parts, sigma=sigma, fixed=("cd_bus",))

ASSUMPTIONS: the parts asked for (how many dishes, panels a wing, booms, a deck) are given — a
topology the light curve does not choose here; the starts are generic fractions of the fitted bus
and wing, the same for every object (:func:`part_starts`); the best of the brief fits by its loss
on the fitted samples leads to the global minimum's basin — a heuristic, not a global search
(BENCHMARKS.md: it fails on a spacebus-like platform with two unequal dishes).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cssat._checks import FieldError, int_param
from cssat._threads import thread_map

__all__ = ["dish_starts", "fit_parts", "part_starts", "with_albedo_prior"]


def dish_starts(p9: Any, dishes: int, *, cd0: float = 0.3) -> list[tuple[str, np.ndarray]]:
    """Generic dish placements on a fitted box-wing ``p9 (9,)``: ``(label, p (17,))`` — ``p9``
    then one dish (:data:`~cssat.inversion.parametric.DISH_PARAM_NAMES`) of radius 0.6 × the bus's
    mean half-size ``(a + b + c) / 3``, depth 0.3 × radius, albedo ``cd0``. One dish: on the
    centre of the ±z and ±x faces, facing out (4 starts). A pair (mirror images through the
    y–z plane): on the ±x faces facing out, or beyond the ±x edges facing +z or −z (3 starts)."""
    p9 = np.asarray(p9, dtype=np.float64)
    if p9.shape != (9,):
        raise FieldError("p9", f"expected the 9 box-wing parameters, got shape {p9.shape}")
    dishes = int_param(dishes, "dishes", 1, 2)
    a, b, c = p9[:3]
    r = 0.6 * float(np.mean(p9[:3]))
    if dishes == 1:
        spots = {"+z face": (0, 0, c, 0.0, 0.0), "-z face": (0, 0, -c, math.pi, 0.0),
                 "+x face": (a, 0, 0, math.pi / 2, 0.0), "-x face": (-a, 0, 0, math.pi / 2, math.pi)}
    else:  # a pair mirrored through the y-z plane
        spots = {"±x faces, out": (a, 0, 0, math.pi / 2, 0.0), "±x edges, +z": (a + 0.5 * r, 0, 0, 0.0, 0.0),
                 "±x edges, -z": (a + 0.5 * r, 0, 0, math.pi, 0.0)}
    return [(k, np.r_[p9, v, r, 0.3 * r, cd0]) for k, v in spots.items()]


def _mirror_second(q: dict, src: dict, pre: str) -> None:
    """``q``'s second dish set to the mirror image (through the y–z plane) of ``src``'s dish
    ``pre``: vertex ``(−x, y, z)``, axis ``(−aₓ, a_y, a_z)`` (azimuth ``π − φ``)."""
    q.update({f"dish2_{k}": src[f"{pre}_{k}"] for k in ("y", "z", "tilt", "radius", "depth")},
             dish2_x=-src[f"{pre}_x"], dish2_azimuth=math.pi - src[f"{pre}_azimuth"])


def part_starts(p9: Any, parts: dict[str, Any], *, flip: bool = False, pairs: bool = False,
                cd0: float = 0.3) -> list[tuple[str, np.ndarray]]:
    """Starts of the finer family ``parts`` (:func:`~cssat.inversion.parametric.param_names`'
    keywords) from a fitted box-wing ``p9 (9,)``: ``(label, p)`` in ``param_names(**parts)``'
    order. Each wing's length split into ``wing_panels`` panels with gaps of 2 % of it; booms of
    side 5 % of the bus's mean half-size; a deck of a third of the bus's half-sizes and a fifth of
    its height; the dishes at :func:`dish_starts`' placements (a free pair, ``dish_pair="free"``,
    starting as mirror images). ``flip``: each placement also with its dishes' axes reversed
    (the concave side the other way); ``pairs`` (a free pair only): every combination of
    placements instead — the first dish at one, the second at another's mirror image (3 × 3)."""
    from cssat.inversion.parametric import param_names  # heavy: cssat.inversion.parametric imports torch

    if flip and pairs:
        raise FieldError("flip", "flip and pairs together are not defined (choose one)")
    names = param_names(**parts)  # checks the parts' keys and values
    p9 = np.asarray(p9, dtype=np.float64)
    if p9.shape != (9,):
        raise FieldError("p9", f"expected the 9 box-wing parameters, got shape {p9.shape}")
    a, b, c, L = p9[:4]
    n, dishes = parts.get("wing_panels", 1), parts.get("dishes", 0)
    g0 = 0.02 * L
    base = dict(zip(param_names(), map(float, p9)), length=(L - (n - 1) * g0) / n if n > 1 else L, panel_gap=g0,
                boom_width=0.05 * float(np.mean(p9[:3])), deck_a=a / 3, deck_b=b / 3, deck_h=2 * c / 5)
    out = []
    for label, p17 in (dish_starts(p9, dishes, cd0=cd0) if dishes else [("no dishes", p9)]):
        q = dict(base, **dict(zip(param_names(dishes), map(float, p17))))
        q["length"] = base["length"]
        if dishes:
            _mirror_second(q, q, "dish")
        out.append((label, np.array([q[k] for k in names])))
        if pairs and parts.get("dish_pair") == "free":
            out.pop()
            for label2, p2 in dish_starts(p9, dishes, cd0=cd0):
                _mirror_second(q, dict(zip(param_names(dishes), map(float, p2))), "dish")
                out.append((f"{label}; {label2}", np.array([q[k] for k in names])))
        if flip and dishes:
            for pre in ("dish", "dish2"):
                if f"{pre}_tilt" in q:
                    q[f"{pre}_tilt"] = math.pi - q[f"{pre}_tilt"]
                    q[f"{pre}_azimuth"] = q[f"{pre}_azimuth"] + math.pi
            out.append((label + ", flipped", np.array([q[k] for k in names])))
    return out


def with_albedo_prior(p: Any, names: tuple[str, ...], cd_bus: float = 0.3) -> np.ndarray:
    """``p (len(names),)`` rescaled so that its bus albedo is ``cd_bus`` with the same light
    curve: every length times ``s = sqrt(cd/cd_bus)``, every albedo over ``s²`` (flux is albedo ×
    area; the shadows are scale-free), the other albedos clipped at 1. The family's one exactly
    flat direction fixed by an albedo prior (an assumption: the absolute size rests on it)."""
    from cssat.inversion.parametric_fit import SIZE_NAMES  # heavy: cssat.inversion.parametric_fit imports torch

    if not 0.0 < float(cd_bus) <= 1.0:
        raise FieldError("cd_bus", f"expected an albedo in (0, 1], got {cd_bus!r}")
    q = dict(zip(names, map(float, np.asarray(p, dtype=np.float64))))
    if len(q) != len(names) or "cd_bus" not in q:
        raise FieldError("names", f"expected one name per entry of p, cd_bus among them, got {names!r}")
    s2 = q["cd_bus"] / cd_bus
    for k in q:
        if k in SIZE_NAMES or k == "gap" or k.endswith(("_x", "_y", "_z")):
            q[k] *= math.sqrt(s2)
        elif k.startswith("cd_"):
            q[k] = min(q[k] / s2, 1.0)
    return np.array([q[k] for k in names])


def fit_parts(y: Any, sun: Any, observer: Any, p9: Any, parts: dict[str, Any], *, sigma: Any = None,
              starts: list[tuple[str, np.ndarray]] | None = None, brief: dict[str, Any] | None = None, keep: int = 1,
              cd0: float = 0.3, workers: int = 1, **fit_kw: Any) -> tuple[np.ndarray, dict[str, Any]]:
    """The finer family ``parts`` fitted to ``y (T,)`` (flux per unit irradiance at 1 m, m²) at
    body-frame ``sun, observer (T, 3)`` from a fitted box-wing ``p9 (9,)``: each of ``starts``
    (default :func:`part_starts`, ``cd0`` its dishes' albedo) fitted briefly by
    :func:`~cssat.inversion.parametric_fit.fit_box_wing` with ``fit_kw`` updated by ``brief``
    (default ``outer`` 2, ``inner`` 20), the ``keep`` best by their loss fitted in full with
    ``fit_kw`` (its ``panels``, ``divisions``, ``outer``, ``inner``, ``visibility``, ``albedos``,
    ``fixed``, ``dish_rings``, ``dish_segments``, ...), the lowest loss kept. Returns ``(p, info)``:
    ``p`` in ``param_names(**parts)``' order, ``info`` the full fit's (``loss``,
    ``rms_over_noise``, ``params``) with ``start`` (the winning start's label), ``briefs``
    (every start's ``(label, loss)``, lowest first) and ``fulls`` (the ``keep`` full fits'
    ``(label, loss)``, in the briefs' order). The finer family holds ``p9`` (its parts
    shrunk away), yet from these starts its fit can end at a higher loss than ``p9``'s — a local
    minimum: compare ``info["loss"]`` with the plain fit's and keep the lower, as the inversion
    experiment's stage does (``parametric_family``). ``workers``: the brief fits, then the full
    ones, run that many at once (:func:`cssat._threads.thread_map`; within
    :func:`cssat._threads.one_thread` the answer is the serial one's, bit for bit)."""
    from cssat.inversion.parametric_fit import fit_box_wing  # heavy: torch

    keep = int_param(keep, "keep", 1)
    workers = int_param(workers, "workers", 1)
    starts = part_starts(p9, parts, cd0=cd0) if starts is None else list(starts)
    if not starts:
        raise FieldError("starts", "expected at least one (label, p) start, got none")
    brief = dict(outer=2, inner=20) if brief is None else dict(brief)

    def run(p0: np.ndarray, **over: Any) -> tuple[np.ndarray, dict]:
        return fit_box_wing(y, sun, observer, p0, sigma=sigma, **dict(fit_kw, **parts, **over))

    outs = thread_map(lambda s: run(s[1], **brief), starts, workers)
    briefs = sorted(((i_s["loss"], label, p_s) for (label, _), (p_s, i_s) in zip(starts, outs)), key=lambda b: b[0])
    best = briefs[:keep]
    fulls = [(label, *out) for (_, label, _), out in zip(best, thread_map(lambda b: run(b[2]), best, workers))]
    label, p, info = min(fulls, key=lambda f: f[2]["loss"])
    return p, dict(info, start=label, briefs=[(lab, float(loss)) for loss, lab, _ in briefs],
                   fulls=[(lab, float(f_info["loss"])) for lab, _, f_info in fulls])
