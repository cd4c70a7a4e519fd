"""Benchmark: the shadow-aware parametric fit on satellites it does not contain.

Each truth is a mesh that the parametric family (:mod:`cssat.inversion.parametric`: an
axis-aligned box bus, two flat panels along ±y, 0–2 paraboloid dishes) does not hold exactly:

* ``astra_defunct``: cssat's Astra-like model (arrays frozen at 30°, two reflector dishes, yokes,
  a telemetry plate), its real materials' diffuse albedos (``cs`` set to 0);
* ``tess_like``: cssat's TESS-like model (a box bus, four capped lens-hood cylinders, a camera
  deck, two wings, a dish under the bus on a mast), real materials' ``cd``, ``cs`` 0;
* ``drum_dish``: a box-wing-with-dish built here with trimesh whose bus is a 24-sided drum
  (a cylinder of radius 1.1 m, 3 m tall along z), two 7 × 2 m wings hinged at 45° on 0.8 m
  yokes, one 1 m dish under the bus facing −z; ``cd`` 0.35 bus, 0.1 wings, 0.6 dish;
* ``b702_like``, ``spacebus_like``: two box-wing-with-dishes GEO platforms built in
  ``benchmarks/_platforms.py`` (wings of three and four separate panels with gaps, on booms; an
  Earth-deck tower or module with a small antenna; a mirror pair of dishes, or two unequal ones
  not mirror images; the family fitted with 2 dishes); ``cd`` 0.35 bus, 0.1 wings, 0.6 dishes;
* ``tess_obj``: NASA's TESS mesh (``../shared/models/tess.obj``, 16,161 facets, read in place,
  when present), uniform ``cd`` 0.3 (with either ``--surface``: the file has no materials). Its
  bus is not watertight: it has no volume to compare, so its volume IoU is not scored (``null``).

Geometry, as the inversion experiment's (``experiment=inversion``): the synthetic re-epoched
Astra 1KR element set, the observer at 51.17° N 10.45° E, 3 nights from 2020-04-01 12:00 UTC at
``--step`` s (default 120 s: 676 samples, 451 fitted; the experiment's 30 s is 4× the samples),
a night's samples where the Sun is below −12°, the object above 20° and wholly sunlit; the attitude the
experiment's ``spin_defunct`` (a spin about body +z, ecliptic pole (60°, 35°), 437 s), **known**
(the fit is given the true body-frame Sun and observer). The truth's light curve is
:func:`cssat.optics.simulate_light_curve` with Embree ray-cast self- and observer-shadowing
(Lambertian: the truths' ``cs`` is 0, so any misfit is shape, not glints), per unit irradiance at
1 m; noise Gaussian, ``σ_t = floor × y_t + 0.1 floor × median(y)`` (``--floor``, default 1.5 %).

Fit (the experiment's ``inversion.shape=parametric`` path, then the family with dishes): the convex
EGI (:func:`cssat.inversion.invert_convex`, 500 normals, σ-weighted) on the first 2 nights;
:func:`~cssat.inversion.parametric_fit.box_wing_start` from it (``cd0`` 0.3, the experiment's
default); :func:`~cssat.inversion.parametric_fit.fit_box_wing` with the experiment's defaults
(``divisions`` 4, ``outer`` 6, ``inner`` 40, ``huber`` 3; ``--visibility soft``: the shadows
differentiable, :mod:`cssat.inversion.soft_shadow`) → the **no dishes** row. Then, from that
fit's bus and panels, the family with the truth's number of dishes (the dish count is given: a
topology oracle) from each of a few generic dish placements (on the bus's ±x, ±z faces, facing
out, ``radius`` 0.6 × the bus's mean half-size, ``depth`` 0.3 × radius), each fitted briefly
(``outer`` 2, ``inner`` 20), the best by its fit-night loss fitted in full → the **dishes** row.
Dishes ``dish_rings`` 4 × ``dish_segments`` 16 cells. Diagnostic rows (oracles, to tell why a
row fails), where the truth's nearest family member (``Truth.nominal``) is known: the same
pipeline with the truth's albedos given and held (**true albedos given**: the size–albedo split
removed); the family at the nominal sizes with only its albedos fitted (**true geometry, albedos
fitted**: what the family itself can reach on this truth); every parameter fitted from the
nominal ones (**all fitted from the true geometry**: the fit without the start's problem).

``--family fine``: the finer family (:mod:`cssat.inversion.parametric`'s ``wing_panels``,
``booms``, ``deck``, ``dish_pair``) with each truth's parts given (``Truth.fine``, a topology oracle
as the dish count is; known for ``astra_defunct`` — four panels a wing on yokes, a mirror pair of
dishes — and the two platforms), by :func:`fit_fine`: the EGI start and the box-wing without
dishes as above, then :func:`cssat.inversion.parametric_parts.part_starts` (generic fractions of the fitted bus and wing, the dishes
at the generic placements) each fitted briefly, the best in full → the **fine, from the EGI** row;
the oracle rows **fine: true geometry, albedos fitted** and **fine: all fitted from the true
geometry**. What the finer family leaves out: the Astra-like's telemetry plate, the b702's tower
dish and engine, the spacebus's omni mast.

With ``--family fine`` also: ``--albedos profile`` (:func:`~cssat.inversion.parametric_fit.fit_box_wing`'s
albedos solved by bounded least squares at every evaluation instead of fitted by gradient),
``--albedo-prior`` (the bus albedo held at ``CD0`` = 0.3 after the no-dish fit, its start
rescaled by :func:`cssat.inversion.parametric_parts.with_albedo_prior`: the family's one exactly flat direction — every length × s,
every albedo ÷ s² — fixed by a prior, so the absolute size and the raw IoU rest on it; for the
``uniform`` truths that prior is their true albedo, for ``materials`` 0.3 against the bus's 0.35),
``--fine-pairs`` (a free dish pair: the 3 × 3 combinations of the generic placements),
``--fine-search N`` (N random starts, :func:`search_starts`, fitted briefly with cast shadows).

``--surface``: ``materials`` (the truths' parts' own ``cd``) and/or ``uniform`` (``cd`` 0.3 on
every facet: the family's one albedo per part then holds, so a misfit is shape).

Scored on the held-out third night: χ²/n of the fit (its visibility recast at the fitted
parameters) and of the TRUE mesh's clean curve against the same noisy data (what the true mesh
itself reaches: ≈ 1 by construction, since the truth is Lambertian), the ratio of their rms
(``rms_ratio``, the table's "ratio": the held-out residual against the true mesh's; target ≤ 1.5;
``ratio`` in the JSON is the χ² ratio, its square); the volume IoU of the fitted mesh's closed
body against the true mesh's closed bodies (:func:`cssat.inversion.volume.volume_iou`, centroids aligned, 100,000 points; target ≥ 0.7;
zero-thickness panels and dishes have no volume on either side, so it scores the bus and any
closed appendage), and, as a diagnostic only, the IoU with the fitted mesh scaled to the true
closed volume (flux is albedo × area: an absolute size needs an albedo prior); CPU seconds of
the whole fit (EGI start, no-dish fit, dish starts and the dishes fit; one thread; target ≤ 600 s).
The attitude is given, so no pole is estimated by the fit; ``--spin-search`` runs instead the convex
EGI's spin search on each truth (the attitude not given) and reports its pole, period and verdict.

Run from the repository root (one thread)::

    python benchmarks/bench_shadow_fit.py --meshes astra_defunct tess_like drum_dish tess_obj --seed 0 \\
        --surface materials uniform --out shadow_fit.json
"""

from __future__ import annotations

import os

if __name__ == "__main__":  # run as a script: one thread a library before numpy loads. Not when a test imports
    # it: numba's pool may already run there at another size, and a changed NUMBA_NUM_THREADS then fails its next compile
    for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
        os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

TESS_OBJ = Path(__file__).resolve().parents[2] / "shared" / "models" / "tess.obj"
MESHES = ("astra_defunct", "tess_like", "drum_dish", "tess_obj", "b702_like", "spacebus_like")
#: the experiment's ``spin_defunct`` attitude
SPIN = dict(pole_lon_deg=60.0, pole_lat_deg=35.0, period_s=437.0, phase_deg=17.0)
#: the experiment's parametric defaults (``inversion.parametric.*``)
FIT = dict(divisions=4, outer=6, inner=40, huber=3.0)
DISH_CELLS = dict(dish_rings=4, dish_segments=16)
CD0 = 0.3


@dataclass
class Geometry:
    """The observed samples: body-frame ``sun``, ``observer (T, 3)``, ``night (T,)`` (0, 1, 2, ...),
    ``unit (T,)`` (W/m² at the observer → per unit irradiance at 1 m), the scenario and its mask,
    the attitude and ``t (T,)`` the samples' times (s from the scenario's start)."""

    sun: np.ndarray
    observer: np.ndarray
    night: np.ndarray
    unit: np.ndarray
    scenario: Any
    keep: np.ndarray
    attitude: Any
    t: np.ndarray


def geometry(step_s: float = 120.0, nights: int = 3, start_utc: str = "2020-04-01T12:00:00") -> Geometry:
    """The inversion experiment's GEO geometry (module docstring) over ``nights`` at ``step_s``."""
    from cssat.scene import make_scenario
    from cssat.scene.attitude import to_body
    from cssat.scene.attitudes import Spin
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2

    sc = make_scenario(start_utc=start_utc, n_steps=int(round(nights * 86400.0 / step_s)), step_s=float(step_s))
    up = sc.r_obs / np.linalg.norm(sc.r_obs, axis=1, keepdims=True)
    d = sc.r_sun - sc.r_obs
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sun_alt = np.degrees(np.arcsin(np.clip((d * up).sum(1), -1, 1)))
    keep = (sun_alt < -12.0) & (sc.elevation_deg > 20.0) & (sc.sunlit >= 1)
    t = ((sc.times - sc.times[0]) / np.timedelta64(1, "s"))[keep]
    night = np.concatenate([[0], np.cumsum(np.diff(t) > 6 * 3600.0)]).astype(int)
    att = Spin(**SPIN)
    frames = att.frames(sc)[keep]
    unit = ((sc.range_km * 1e3) ** 2 / SOLAR_IRRADIANCE_W_M2)[keep]
    return Geometry(to_body(frames, sc.sun_dir[keep]), to_body(frames, sc.obs_dir[keep]), night, unit, sc, keep, att, t)


def _lambertian(mesh: Any, cd: Any = None, name: str | None = None) -> Any:
    from cssat.scene.mesh import Mesh

    return Mesh(mesh.vertices, mesh.faces, mesh.cd if cd is None else cd, 0.0, name=name or mesh.name, part=mesh.part,
                part_names=mesh.part_names)


def drum_dish() -> Any:
    """A box-wing-with-dish whose bus is not a box (module docstring), built with trimesh."""
    import trimesh

    from cssat.scene.mesh import Mesh, merge
    from cssat.scene.models import dish, panel

    cyl = trimesh.creation.cylinder(radius=1.1, height=3.0, sections=24)
    bus = Mesh(np.asarray(cyl.vertices), np.asarray(cyl.faces), 0.35, 0.0, name="bus")
    h = math.radians(45.0)
    w = 2.0 * np.array([math.sin(h), 0.0, math.cos(h)])
    parts = [bus]
    for side in (1, -1):
        u = np.array([0.0, side * 7.0, 0.0])
        origin = np.array([0.0, side * (1.1 + 0.8), 0.0]) - w / 2
        first, second = (u, w) if side > 0 else (w, u)
        parts.append(panel(first, second, origin, divisions=(4, 2), cd=0.1, cs=0.0))
    parts.append(dish(1.0, 0.3, center=(0.0, 0.0, -1.6), axis=(0.0, 0.0, -1.0), rings=6, segments=24, cd=0.6, cs=0.0))
    return merge(parts, name="drum_dish")


@dataclass
class Truth:
    """A truth mesh, the dishes it has (the family's ``dishes`` to fit), whether its volume IoU
    is defined, and the family's parameters nearest to it by construction (``nominal (9 + 8,)``:
    its bus's half-sizes or an equal-volume box's, its wings, its dish, its parts' area-weighted
    ``cd``; None where not known), the start of the oracle row."""

    mesh: Any
    dishes: int
    iou: bool
    nominal: np.ndarray | None
    note: str
    #: the finer family's parts and parameters by construction (``--family fine``), where known
    fine: tuple[dict, dict] | None = None


def _part_cd(mesh: Any, names: tuple) -> float:
    """The area-weighted ``cd`` of the mesh's parts ``names``."""
    sel = np.isin(mesh.part, [mesh.part_names.index(k) for k in names if k in mesh.part_names])
    return float((mesh.cd[sel] * mesh.areas[sel]).sum() / mesh.areas[sel].sum())


def truth(name: str, surface: str = "materials") -> Truth:
    """The truth ``name`` of :data:`MESHES` (module docstring), Lambertian (``cs`` 0);
    ``surface="uniform"``: every facet ``cd`` 0.3 instead of its part's."""
    import _platforms
    from cssat.scene import get_model, load_mesh

    if surface not in ("materials", "uniform"):
        raise ValueError(f"surface: expected 'materials' or 'uniform', got {surface!r}")
    if name == "astra_defunct":
        m = _lambertian(get_model("astra_like", array_angle_deg=30.0), name=name)
        cd = (_part_cd(m, ("mli", "osr")), _part_cd(m, ("solar_cell", "panel_back")),
              (_part_cd(m, ("ge_kapton",)) + _part_cd(m, ("panel_back",))) / 2)  # the dish: front and back
        t = Truth(m, 2, True, np.r_[1.3, 1.2, 1.8, 9.1, 2.4, math.radians(30), 1.5, cd[:2],
                                     1.65, 0.0, 0.6, math.atan2(0.35, 1.0), 0.0, 1.15, 0.35, cd[2]],
                  "real materials' cd (MLI bus, dark OSR on ±y, dark cells); yokes and plate not in the family")
        t.fine = _platforms.fine_params(t.nominal, dict(dishes=2, wing_panels=4, booms=True), length=2.2, panel_gap=0.1,
                                        boom_width=0.08)  # four 2.2 m panels a wing, 0.1 m apart, on 8 cm yokes
    elif name == "tess_like":
        m = _lambertian(get_model("tess_like"), name=name)
        cd = (_part_cd(m, ("mli",)), _part_cd(m, ("solar_cell", "panel_back")),
              (_part_cd(m, ("white_paint",)) + _part_cd(m, ("panel_back",))) / 2)
        t = Truth(m, 1, True, np.r_[0.6, 0.6, 0.5, 2.05, 1.3, 0.0, 0.1, cd[:2], 0.0, 0.0, -0.75, math.pi, 0.0, 0.35, 0.1, cd[2]],
                  "lens hoods, deck and mast not in the family")
    elif name == "drum_dish":
        h = 1.1 * math.sqrt(math.pi) / 2  # the box of the drum's cross-section
        t = Truth(drum_dish(), 1, True, np.r_[h, h, 1.5, 7.0, 2.0, math.radians(45), 1.9 - h, 0.35, 0.1,
                                             0.0, 0.0, -1.6, math.pi, 0.0, 1.0, 0.3, 0.6],
                  "a 24-sided drum bus (r 1.1 m, 3 m tall)")
    elif name in ("b702_like", "spacebus_like"):
        m, nominal = getattr(_platforms, name)()
        t = Truth(m, 2, True, nominal, "built in benchmarks/_platforms.py: panels with gaps, booms, a deck module"
                                       + (", unequal dishes" if name == "spacebus_like" else ", a tower dish, an engine"),
                  _platforms.FINE[name])
    elif name == "tess_obj":
        if not TESS_OBJ.is_file():
            raise FileNotFoundError(f"{TESS_OBJ} is not here")
        m = _lambertian(load_mesh(str(TESS_OBJ), scale=1.0, cd=0.3, cs=0.0), name=name)
        t = Truth(m, 1, False, None, "NASA's mesh; its bus is not watertight: no volume to score")
    else:
        raise ValueError(f"unknown mesh {name!r}: expected one of {MESHES}")
    if surface == "uniform":
        t.mesh = _lambertian(t.mesh, cd=0.3)
        if t.nominal is not None:
            t.nominal = t.nominal.copy()
            t.nominal[[7, 8, 16]] = 0.3
        if t.fine is not None:
            t.fine = (t.fine[0], {k: 0.3 if k.startswith("cd_") else v for k, v in t.fine[1].items()})
        t.note += "; uniform cd 0.3"
    return t


def simulate(mesh: Any, geo: Geometry, floor: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(y, sigma, clean) (T,)`` per unit irradiance at 1 m (m²): the truth through
    :func:`cssat.optics.simulate_light_curve` with ray-cast shadows, and its noise."""
    from cssat.optics.lightcurve import simulate_light_curve

    lc = simulate_light_curve(mesh, geo.scenario, shadows=True, attitude=geo.attitude)
    clean = lc.flux.numpy()[geo.keep] * geo.unit
    sigma = floor * clean + 0.1 * floor * float(np.median(clean))
    y = clean + sigma * np.random.default_rng(seed).normal(size=len(clean))
    return y, sigma, clean


def _family_kw(dishes: int, divisions: int, parts: dict | None = None) -> dict:
    """The family's keywords (two panels, the functions' default): ``dishes`` with the benchmark's
    dish cells, or the finer ``parts``."""
    if parts is not None:
        return dict(divisions=divisions, **parts, **(DISH_CELLS if parts.get("dishes") else {}))
    return dict(divisions=divisions, **(dict(dishes=dishes, **DISH_CELLS) if dishes else {}))


def heldout_chi2(p: np.ndarray, geo: Geometry, y: np.ndarray, sigma: np.ndarray, mask: np.ndarray, dishes: int,
                 divisions: int, parts: dict | None = None) -> float:
    """χ²/n of the family at ``p`` on the samples ``mask`` (its visibility cast at ``p``);
    ``parts``: the finer family's (:func:`fit_fine`), instead of ``dishes``."""
    import torch

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility

    kw = _family_kw(dishes, divisions, parts)
    S, V = geo.sun[mask], geo.observer[mask]
    vis = box_wing_visibility(p, S, V, **kw)
    m = box_wing_light_curve(torch.as_tensor(p), S, V, vis, range_km=1e-3, irradiance=1.0, **kw).numpy()
    return float(np.mean(((y[mask] - m) / sigma[mask]) ** 2))


def turned(mesh: Any, R: np.ndarray) -> Any:
    """``mesh`` with its vertices turned by ``R (3, 3)`` (``v → R v``), its materials and parts kept."""
    from cssat.scene.mesh import Mesh

    return Mesh(mesh.vertices @ np.asarray(R).T, mesh.faces, mesh.cd, mesh.cs, name=mesh.name, part=mesh.part,
                part_names=mesh.part_names)


def closed_volume(mesh: Any) -> float:
    """The volume (m³) of the mesh's watertight components (vertices merged), as the IoU counts it."""
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
    return float(sum(abs(b.volume) for b in tm.split(only_watertight=True)))


def _iou(true_mesh: Any, p: np.ndarray, dishes: int, divisions: int, n_points: int,
         parts: dict | None = None) -> tuple[float, float]:
    """``(IoU, IoU at the true closed volume)`` of the fitted box-wing against ``true_mesh``."""
    from cssat.inversion.parametric import box_wing_mesh
    from cssat.inversion.volume import volume_iou
    from cssat.scene.mesh import Mesh

    fit = box_wing_mesh(p, **_family_kw(dishes, divisions, parts))
    raw = volume_iou(true_mesh, fit, n_points=n_points, seed=0)
    v_true, v_fit = closed_volume(true_mesh), closed_volume(fit)
    s = (v_true / v_fit) ** (1 / 3)
    scaled = volume_iou(true_mesh, Mesh(fit.vertices * s, fit.faces, 0.5, 0.0), n_points=n_points, seed=0)
    return raw, scaled


GEOMETRY_NAMES = ("a", "b", "c", "length", "width", "hinge", "gap") + tuple(
    f"dish_{k}" for k in ("x", "y", "z", "tilt", "azimuth", "radius", "depth"))


def fit_truth(name: str, geo: Geometry, *, seed: int = 0, floor: float = 0.015, surface: str = "materials",
              n_normals: int = 500, fit_settings: dict | None = None, dish_fit: bool = True, oracle: bool = True,
              n_points: int = 100_000, mesh: Truth | None = None) -> dict[str, Any]:
    """The benchmark on one truth (module docstring): a row per fitted family — ``no dishes``
    (the experiment's path, from the EGI), ``dishes`` (from it, the truth's dish count) and, with
    ``oracle`` and a known ``nominal``, two diagnostic rows: ``true geometry`` (the family at the
    nominal sizes, only its albedos fitted: what the family can reach there) and ``from truth``
    (every parameter fitted from the nominal ones: the fit without the start's problem) — each
    with the held-out χ²/n of the fit and of the true mesh, their ratio, the volume IoU, CPU
    seconds and the fitted parameters. ``mesh``: a :class:`Truth` to use instead of
    ``truth(name, surface)`` (e.g. one inside the family)."""
    from cssat.inversion import invert_convex
    from cssat.inversion.parametric import PARAM_NAMES, param_names
    from cssat.inversion.parametric_fit import box_wing_start, fit_box_wing
    from cssat.inversion.parametric_parts import dish_starts

    tr = truth(name, surface) if mesh is None else mesh
    st = dict(FIT, **(fit_settings or {}))
    y, sigma, clean = simulate(tr.mesh, geo, floor, seed)
    fit, held = geo.night < 2, geo.night >= 2
    if not held.any():
        raise ValueError("no held-out night: the geometry needs 3 nights")
    S, V = geo.sun[fit], geo.observer[fit]

    def family_fit(p0, dishes, **over):
        kw = dict(st, **over, **(dict(dishes=dishes, **DISH_CELLS) if dishes else {}))
        return fit_box_wing(y[fit], S, V, p0, sigma=sigma[fit], panels=2, **kw)

    names_d = param_names(tr.dishes)
    albedo_names = ("cd_bus", "cd_panel", "cd_dish")

    def pipeline(tag: str, albedos: Any = None) -> list:
        """The EGI start, the no-dish fit, the dish starts and the dishes fit; ``albedos``
        ``(cd_bus, cd_panel, cd_dish)`` held fixed when given."""
        c0 = time.process_time()
        egi = invert_convex(y[fit], S, V, n_normals=n_normals, sigma=sigma[fit])
        p0 = box_wing_start(egi.normals, egi.areas, panels=2, cd0=CD0)
        fixed: tuple = ()
        if albedos is not None:
            p0[7:9] = albedos[:2]
            fixed = albedo_names
        p_nd, info_nd = family_fit(p0, 0, fixed=[k for k in fixed if k in PARAM_NAMES])
        out = [(f"no dishes{tag}", 0, p_nd, info_nd, time.process_time() - c0, "EGI")]
        if dish_fit and tr.dishes:
            best = None
            for label, ps in dish_starts(p_nd, tr.dishes, cd0=CD0):
                if albedos is not None:
                    ps[-1] = albedos[2]
                p_s, info_s = family_fit(ps, tr.dishes, outer=2, inner=20, fixed=fixed)
                if best is None or info_s["loss"] < best[2]:
                    best = (label, p_s, info_s["loss"])
            p_d, info_d = family_fit(best[1], tr.dishes, fixed=fixed)
            out.append((f"{tr.dishes} dish{'es' if tr.dishes > 1 else ''}{tag}", tr.dishes, p_d, info_d,
                        time.process_time() - c0, f"EGI, then dishes at {best[0]}"))
        return out

    rows = pipeline("")
    if oracle and tr.nominal is not None:
        rows += pipeline(", true albedos given", np.r_[tr.nominal[7:9], tr.nominal[16] if len(tr.nominal) > 16 else CD0])
    if oracle and tr.nominal is not None:
        nom = tr.nominal if tr.dishes else tr.nominal[:9]
        c0 = time.process_time()
        p_a, info_a = family_fit(nom, tr.dishes, outer=3, fixed=[k for k in GEOMETRY_NAMES if k in names_d])
        rows.append(("true geometry, albedos fitted", tr.dishes, p_a, info_a, time.process_time() - c0, "nominal"))
        c0 = time.process_time()
        p_o, info_o = family_fit(nom, tr.dishes)
        rows.append(("all fitted from the true geometry", tr.dishes, p_o, info_o, time.process_time() - c0, "nominal"))

    nominal = None if tr.nominal is None else [float(v) for v in tr.nominal]
    out = [_scored(name, surface, tr, geo, y, sigma, clean, st["divisions"], n_points, label, p, info, cpu, start, nominal,
                   dishes=dishes) for label, dishes, p, info, cpu, start in rows]
    return dict(rows=out, floor=floor, seed=seed)


def _scored(name: str, surface: str, tr: Truth, geo: Geometry, y: np.ndarray, sigma: np.ndarray, clean: np.ndarray,
            divisions: int, n_points: int, label: str, p: np.ndarray, info: dict, cpu: float, start: str, nominal: Any,
            dishes: int = 0, parts: dict | None = None) -> dict[str, Any]:
    """A row of the table: the fit ``p`` (family ``dishes``, or the finer ``parts``) scored on the
    held-out night (its χ²/n and the true mesh's, their ratio) and by its volume IoU."""
    fit, held = geo.night < 2, geo.night >= 2
    chi2_true = float(np.mean(((y[held] - clean[held]) / sigma[held]) ** 2))
    chi2 = heldout_chi2(p, geo, y, sigma, held, dishes, divisions, parts)
    iou, iou_scaled = _iou(tr.mesh, p, dishes, divisions, n_points, parts) if tr.iou else (None, None)
    return dict(mesh=name, surface=surface, family=label, start=start, **({} if parts is None else {"parts": parts}),
                n_fit=int(fit.sum()), n_heldout=int(held.sum()), fit_rms_over_noise=info["rms_over_noise"],
                heldout_chi2=chi2, true_heldout_chi2=chi2_true, ratio=chi2 / chi2_true,
                rms_ratio=math.sqrt(chi2 / chi2_true), iou=iou, iou_at_true_volume=iou_scaled, cpu_s=cpu,
                params=info["params"], nominal=nominal, note=tr.note)


def search_starts(p9: np.ndarray, parts: dict, n: int, seed: int = 0) -> list[tuple[str, np.ndarray]]:
    """``n`` random starts of the finer family (``parts``) about a fitted box-wing ``p9 (9,)``, for a
    global search (:func:`fit_fine`'s ``search``): the bus's half-sizes and the wing's length and
    width each times ``exp(N(0, 0.15²))``, the hinge ``+ N(0, 0.1²)`` rad, the panel albedo times
    ``exp(N(0, 0.3²))``; each dish's vertex uniform on a random ±x or ±z face of the bus (within
    80 % of its half-sizes), its axis uniform over that face's outward hemisphere, its radius
    ``U(0.4, 0.9)`` × the bus's mean half-size, depth 0.3 × radius, ``cd_dish`` ``CD0 × exp(N(0,
    0.3²))`` (a free pair: the second dish drawn the same way, independently); the deck's half-sizes
    ``U(0.2, 0.5)`` of the bus's and height ``U(0.1, 0.5)`` × ``2c``; gaps and booms as
    :func:`~cssat.inversion.parametric_parts.part_starts`. ``cd_bus`` is kept (the albedo prior, if it is held). Reproducible by
    ``seed``: ``(label, p)``."""
    from cssat.inversion.parametric import param_names
    from cssat.inversion.parametric_parts import part_starts

    rng = np.random.default_rng(seed)
    names = param_names(**parts)
    base = dict(zip(names, map(float, part_starts(p9, parts, cd0=CD0)[0][1])))
    out = []

    def ln(s):  # a log-normal factor
        return float(np.exp(rng.normal(0.0, s)))

    for i in range(n):
        q = dict(base)
        for k in ("a", "b", "c", "length", "width"):
            q[k] = base[k] * ln(0.15)
        q["hinge"] = base["hinge"] + rng.normal(0.0, 0.1)
        q["cd_panel"] = min(base["cd_panel"] * ln(0.3), 1.0)
        half = np.array([q["a"], q["b"], q["c"]])
        for pre in ("dish", "dish2"):
            if f"{pre}_x" not in q:
                continue
            axis_k, sign = [(0, 1), (0, -1), (2, 1), (2, -1)][rng.integers(4)]
            vertex = rng.uniform(-0.8, 0.8, 3) * half
            vertex[axis_k] = sign * half[axis_k]
            out_n = np.zeros(3)
            out_n[axis_k] = sign
            v = rng.normal(size=3)
            v /= np.linalg.norm(v)
            v = v if v @ out_n > 0 else -v
            q.update({f"{pre}_x": vertex[0], f"{pre}_y": vertex[1], f"{pre}_z": vertex[2],
                      f"{pre}_tilt": math.acos(float(np.clip(v[2], -1, 1))), f"{pre}_azimuth": math.atan2(v[1], v[0])})
            r = rng.uniform(0.4, 0.9) * float(half.mean())
            q[f"{pre}_radius"], q[f"{pre}_depth"] = r, 0.3 * r
        if "cd_dish" in q:
            q["cd_dish"] = min(CD0 * ln(0.3), 1.0)
        if "deck_a" in q:
            q.update(deck_a=rng.uniform(0.2, 0.5) * q["a"], deck_b=rng.uniform(0.2, 0.5) * q["b"],
                     deck_h=rng.uniform(0.1, 0.5) * 2 * q["c"])
        out.append((f"random start {i}", np.array([q[k] for k in names])))
    return out


def fit_fine(name: str, geo: Geometry, *, seed: int = 0, floor: float = 0.015, surface: str = "materials",
             n_normals: int = 500, fit_settings: dict | None = None, oracle: bool = True, n_points: int = 100_000,
             flip: bool = False, brief_divisions: int | None = None, keep: int = 1, search: int = 0,
             prior: bool = False, brief_iters: tuple[int, int] = (2, 30), pairs: bool = False,
             fit_geo: Geometry | None = None, to_fit: np.ndarray | None = None) -> dict:
    """The finer family (the truth's ``Truth.fine`` parts given: a topology oracle, as the dish
    count is in :func:`fit_truth`) on one truth: **fine, from the EGI** — the EGI start, the
    box-wing without dishes fitted (:func:`fit_truth`'s first stage), then
    :func:`cssat.inversion.parametric_parts.fit_parts`: each of its starts fitted briefly (``outer`` 2, ``inner`` 20; at ``brief_divisions`` cells when
    given; with ``flip`` each dish start also with its axis reversed), the ``keep`` best by their
    fit-night loss fitted in full, the best of those kept. ``search`` > 0: a global search instead —
    :func:`search_starts`' ``search`` random starts and the generic ones, each fitted briefly with the
    cast visibility (cheap: no soft shadows; ``outer, inner = brief_iters``, at ``brief_divisions`` or 2
    cells), the ``keep`` best in full. ``prior``: the bus albedo held at ``CD0`` (the start rescaled
    by :func:`~cssat.inversion.parametric_parts.with_albedo_prior`), fixing the family's flat size–albedo direction. ``pairs``:
    :func:`~cssat.inversion.parametric_parts.part_starts`'. With ``oracle``: **fine: true geometry, albedos fitted** (what this family can
    reach on the truth) and **fine: all fitted from the true geometry**. Rows as :func:`fit_truth`'s.
    ``fit_geo``: the samples in another body frame than the truth's (an estimated spin's, e.g.
    ``benchmarks/bench_shadow_spin.py``), fitted and scored there; ``to_fit (3, 3)`` turns the true
    mesh into it for the IoU. The light curve is the truth's (``geo``) either way."""
    from cssat.inversion import invert_convex
    from cssat.inversion.parametric import param_names
    from cssat.inversion.parametric_fit import box_wing_start, fit_box_wing
    from cssat.inversion.parametric_parts import fit_parts, part_starts, with_albedo_prior

    tr = truth(name, surface)
    if tr.fine is None:
        raise ValueError(f"{name}: no finer-family parts known (Truth.fine)")
    parts, true_params = tr.fine
    st = dict(FIT, **(fit_settings or {}))
    y, sigma, clean = simulate(tr.mesh, geo, floor, seed)
    if fit_geo is not None:  # fitted and scored in another frame: the truth turned into it for the IoU
        geo = fit_geo
        if to_fit is not None:
            tr = Truth(turned(tr.mesh, to_fit), tr.dishes, tr.iou, tr.nominal, tr.note, tr.fine)
    fit = geo.night < 2
    S, V = geo.sun[fit], geo.observer[fit]
    fkw = _family_kw(0, st["divisions"], parts)

    def run(p0, fine=True, **over):
        kw = dict(st, **(fkw if fine else {}))
        kw.update(over)
        return fit_box_wing(y[fit], S, V, p0, sigma=sigma[fit], panels=2, **kw)

    rows = []
    c0 = time.process_time()
    egi = invert_convex(y[fit], S, V, n_normals=n_normals, sigma=sigma[fit])
    p_nd, _ = run(box_wing_start(egi.normals, egi.areas, panels=2, cd0=CD0), fine=False)
    held = ["cd_bus"] if prior else []
    if prior:
        p_nd = with_albedo_prior(p_nd, param_names(), cd_bus=CD0)
    starts = part_starts(p_nd, parts, flip=flip, pairs=pairs, cd0=CD0)
    brief = dict(outer=2, inner=20, **({"divisions": brief_divisions} if brief_divisions else {}))
    if search:
        starts += search_starts(p_nd, parts, search, seed=seed)
        brief = dict(outer=brief_iters[0], inner=brief_iters[1], divisions=brief_divisions or 2, visibility="cast")
    cells = {k: v for k, v in fkw.items() if k not in parts}
    p_f, info_f = fit_parts(y[fit], S, V, p_nd, parts, sigma=sigma[fit], starts=starts, brief=brief, keep=keep,
                            panels=2, fixed=held, **dict(st, **cells))
    print(f"{name} {surface}: {len(starts)} brief fits; the best: "
          + ", ".join(f"{lab} {loss:.3f}" for lab, loss in info_f["briefs"][:4]), file=sys.stderr, flush=True)
    label = info_f["start"]
    rows.append(("fine, from the EGI", p_f, info_f, time.process_time() - c0, f"EGI, then the parts at {label}"))
    if oracle:
        nom = np.array(list(true_params.values()))
        geometry_names = [k for k in true_params if not k.startswith("cd_")]
        c0 = time.process_time()
        p_a, info_a = run(nom, outer=3, fixed=geometry_names)
        rows.append(("fine: true geometry, albedos fitted", p_a, info_a, time.process_time() - c0, "nominal"))
        c0 = time.process_time()
        p_o, info_o = run(nom)
        rows.append(("fine: all fitted from the true geometry", p_o, info_o, time.process_time() - c0, "nominal"))
    out = [_scored(name, surface, tr, geo, y, sigma, clean, st["divisions"], n_points, label, p, info, cpu, start,
                   true_params, parts=parts) for label, p, info, cpu, start in rows]
    return dict(rows=out, floor=floor, seed=seed)


def spin_search_row(name: str, geo: Geometry, *, seed: int = 0, floor: float = 0.015, surface: str = "materials") -> dict:
    """The attitude NOT given: :func:`cssat.inversion.estimate_spin` (the convex EGI's spin search at
    the inversion experiment's default sizes, σ given) on the first two nights, the third held out
    for its verdict — the pole's separation from the truth's, the period, each 1σ (NaN where
    withheld) and the verdict. No shape is fitted here."""
    from cssat.inversion import estimate_spin
    from cssat.inversion.spin_errors import separation_deg
    from cssat.models.egi.config import InversionConfig

    inv = InversionConfig()  # the experiment's defaults (inversion.*)
    tr = truth(name, surface)
    y, sigma, _ = simulate(tr.mesh, geo, floor, seed)
    sc, t = geo.scenario, geo.t
    S, O = sc.sun_dir[geo.keep], sc.obs_dir[geo.keep]
    fit, held = geo.night < 2, geo.night >= 2
    c0 = time.process_time()
    sol = estimate_spin(t[fit], y[fit], S[fit], O[fit], sigma=sigma[fit], frame=geo.attitude.frame,
                        n_normals=inv.search_normals, heldout=(t[held], y[held], S[held], O[held], sigma[held]), **inv.search())
    return dict(mesh=name, surface=surface, seed=seed, floor=floor,
                sep_deg=separation_deg((sol.pole_lon_deg, sol.pole_lat_deg), (SPIN["pole_lon_deg"], SPIN["pole_lat_deg"])),
                period_s=sol.period_s, period_true_s=SPIN["period_s"], pole_err_deg=sol.pole_err_deg,
                period_err_s=sol.period_err_s, verdict=sol["verdict"], why=sol["verdict_why"],
                synodic_verdict=sol.synodic.get("verdict"), reduced_chi2=sol.reduced_chi2, ambiguous=sol.ambiguous,
                cpu_s=time.process_time() - c0)


def markdown(rows: list[dict]) -> str:
    """The table of the rows (targets: held-out rms ratio ≤ 1.5, IoU ≥ 0.7, CPU ≤ 600 s)."""
    head = ("| truth | albedos | family | fit rms/σ | held-out rms/σ: fit | true mesh | ratio (≤ 1.5) | IoU (≥ 0.7) | "
            "IoU at true volume | CPU s (≤ 600) | fitted a, b, c; length × width, hinge; gap; cd bus/panel "
            "[; dish r, depth, tilt, cd] |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
    lines = [head]
    for r in rows:
        q = r["params"]
        par = (f"{q['a']:.2f}, {q['b']:.2f}, {q['c']:.2f}; {q['length']:.2f} × {q['width']:.2f}, "
               f"{math.degrees(q['hinge']):.0f}°; {q['gap']:.2f}; {q['cd_bus']:.2f}/{q['cd_panel']:.2f}")
        if "dish_radius" in q:
            par += (f"; {q['dish_radius']:.2f}, {q['dish_depth']:.2f}, {math.degrees(q['dish_tilt']):.0f}°, "
                    f"{q['cd_dish']:.2f}")
        iou = "n/a" if r["iou"] is None else f"{r['iou']:.2f}"
        ius = "n/a" if r["iou_at_true_volume"] is None else f"{r['iou_at_true_volume']:.2f}"
        lines.append(f"| {r['mesh']} | {r['surface']} | {r['family']} | {r['fit_rms_over_noise']:.2f} | "
                     f"{math.sqrt(r['heldout_chi2']):.2f} | {math.sqrt(r['true_heldout_chi2']):.2f} | {r['rms_ratio']:.2f} | "
                     f"{iou} | {ius} | {r['cpu_s']:.0f} | {par} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--meshes", nargs="+", default=list(MESHES), choices=MESHES)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="JSON file of the rows (a .md table beside it)")
    ap.add_argument("--step", type=float, default=120.0, help="cadence (s)")
    ap.add_argument("--floor", type=float, default=0.015, help="relative noise floor")
    ap.add_argument("--surface", nargs="+", default=["materials", "uniform"], choices=("materials", "uniform"),
                    help="the truths' albedos: their parts' real cd, or cd 0.3 on every facet")
    ap.add_argument("--no-dishes", action="store_true", help="fit the family without dishes only")
    ap.add_argument("--no-oracle", action="store_true", help="leave out the rows started from the true geometry")
    ap.add_argument("--report", default=None, help="print the table of a JSON file written by --out, and stop")
    ap.add_argument("--visibility", choices=("cast", "soft"), default="cast",
                    help="fit_box_wing's shadows: cast and held fixed in each L-BFGS run, or soft (differentiable)")
    ap.add_argument("--family", choices=("box_wing", "fine"), default="box_wing",
                    help="fit the box-wing (with the truth's dishes), or the finer family with the truth's parts "
                         "(wing panels, booms, deck, a free dish pair: Truth.fine)")
    ap.add_argument("--fine-flip", action="store_true", help="--family fine: each dish start also flipped")
    ap.add_argument("--fine-brief-divisions", type=int, default=None, help="--family fine: the brief fits' cells")
    ap.add_argument("--fine-keep", type=int, default=1, help="--family fine: the brief fits fitted in full")
    ap.add_argument("--fine-search", type=int, default=0,
                    help="--family fine: a global search, this many random starts fitted briefly (cast shadows)")
    ap.add_argument("--fine-brief-iters", type=int, nargs=2, default=(2, 30), metavar=("OUTER", "INNER"),
                    help="--fine-search: each brief fit's outer and inner iterations")
    ap.add_argument("--fine-pairs", action="store_true",
                    help="--family fine, a free dish pair: every combination of the two dishes' generic placements")
    ap.add_argument("--albedos", choices=("fit", "profile"), default="fit",
                    help="fit_box_wing's albedos: fitted by gradient, or solved by least squares at each evaluation")
    ap.add_argument("--albedo-prior", action="store_true", help="--family fine: the bus albedo held at CD0 (0.3)")
    ap.add_argument("--spin-search", action="store_true",
                    help="no shape fit: the convex EGI's spin search on each truth (attitude not given), its verdict")
    args = ap.parse_args(argv)
    if args.report:
        print(markdown(json.loads(Path(args.report).read_text())["rows"]))
        return 0
    import torch

    torch.set_num_threads(1)
    geo = geometry(args.step)
    print(f"geometry: {len(geo.night)} samples, nights {np.bincount(geo.night).tolist()}, step {args.step:g} s", flush=True)
    rows = []
    if args.spin_search:
        for name in args.meshes:
            for surface in args.surface:
                r = spin_search_row(name, geo, seed=args.seed, floor=args.floor, surface=surface)
                rows.append(r)
                print(json.dumps(r), flush=True)
        if args.out:
            Path(args.out).write_text(json.dumps(dict(step_s=args.step, argv=sys.argv[1:] if argv is None else argv,
                                                      rows=rows), indent=1))
        return 0
    for name in args.meshes:
        if name == "tess_obj" and not TESS_OBJ.is_file():
            print(f"skip tess_obj: {TESS_OBJ} is not here", flush=True)
            continue
        for surface in args.surface:
            if name == "tess_obj" and surface == "materials" and "uniform" in args.surface:
                continue  # the file has no materials: its "materials" are the uniform cd 0.3
            if args.family == "fine":
                res = fit_fine(name, geo, seed=args.seed, floor=args.floor, surface=surface, oracle=not args.no_oracle,
                               fit_settings=dict(visibility=args.visibility, albedos=args.albedos), flip=args.fine_flip,
                               brief_divisions=args.fine_brief_divisions, keep=args.fine_keep,
                               search=args.fine_search, prior=args.albedo_prior,
                               brief_iters=tuple(args.fine_brief_iters), pairs=args.fine_pairs)
            else:
                res = fit_truth(name, geo, seed=args.seed, floor=args.floor, surface=surface, dish_fit=not args.no_dishes,
                                oracle=not args.no_oracle, fit_settings=dict(visibility=args.visibility, albedos=args.albedos))
            rows += res["rows"]
            for r in res["rows"]:
                print(json.dumps({k: v for k, v in r.items() if k not in ("params", "nominal", "note")}), flush=True)
    table = markdown(rows)
    print(table)
    if args.out:
        out = Path(args.out)
        out.write_text(json.dumps(dict(step_s=args.step, floor=args.floor, seed=args.seed, n_samples=len(geo.night),
                                       visibility=args.visibility,
                                       argv=sys.argv[1:] if argv is None else argv,
                                       rows=rows), indent=1))
        out.with_suffix(".md").write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
