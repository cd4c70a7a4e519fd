"""Benchmark: does the pole's profile-likelihood region cover the truth, and is a model that does
not fit called unreliable?

``--part class`` (in the model class): a convex body the EGI represents exactly — non-negative
areas on 24 of the fit's own grid normals (:func:`cssat.inversion.fibonacci_sphere` of
``n_normals``), closed (``Σ aₖ nₖ ≈ 0``: a convex polyhedron, Minkowski) — turning about a random
pole (uniform on the sphere) with a period uniform in 300–900 s, phase 0 at t = 0 in cssat's
spin frame (the areas sit on the grid in the fit's own body frame), Lambert, no shadows: the model
:func:`cssat.inversion.estimate_spin` fits. Four GEO-like nights of 100 samples (the observer
turning with the Earth, the Sun nearly fixed), the fourth held out; white noise of 0.5–2 % of the
mean flux, its σ given. The search is the real one over the whole sphere (``n_poles 60, n_starts
4, n_refine 2, coarse_normals 150, coarse_samples 250, n_normals 400, max_samples 300``), from the
synodic period of :func:`~cssat.inversion.estimate_period` (without σ: see BENCHMARKS.md).

Counted per seed: the verdict; the truth's profile ``Δχ²`` (the χ² at the true pole minimised
over the period and the areas, less the solution's, over the reduced χ² where above 1) against
2.30 and 6.18 — the 68.27 % / 95.45 % regions of the pole's two numbers; the separation against
the reported radial 1σ ``pole_err_deg`` (63.2 % / 98.2 % for a circular Gaussian).

``--part mismatch`` (outside the class): the same geometry and search on the 14-facet polyhedron
of ``tests/test_inversion_spin.py`` with a specular lobe (Blinn–Phong 200, weight ``--glint``) and
an off-grid EGI: the rate of "unreliable" verdicts and of wrong poles.

``--part tumble`` (the tumbler's ``L``, in the model class): a torque-free tumbler whose moments
(``i₂`` 0.6–0.95, ``i₁`` up to ``i₂``), mode angle (10–60°), direction of ``L`` (uniform on the
sphere), phases and ``P_φ`` (150–400 s) are drawn, its EGI 24 of the final fit's own ``n_normals``
grid normals in the body frame, closed, Lambert, no shadows; two 4-h arcs a day apart fitted, an
hour of the third day held out, 10 s cadence, GEO-like geometry, 0.5–2 % noise with σ given. The
search is :func:`cssat.inversion.estimate_tumbling`'s, blind (the frequency lattice from the light
curve, the default inertia grid), at :data:`TUMBLE` (``--search`` changes them). Counted: the
verdict; the separation of ``L`` against its reported 1σ ``L_err_deg`` (the radial 1σ,
the bootstrap's, or ``√(σ_β² + cos²β σ_λ²)`` with ``bootstrap=0``, ⊕ the grid's shift): inside ``1.0714 × L_err_deg`` for the
68.27 % region and ``1.7579 ×`` for the 95.45 % one of a circular Gaussian.

``--egi off`` draws the in-class truths' normals off any grid (uniform on the sphere) instead of
on the fit's own grid. ``--search bootstrap=B`` (and ``error_grids=G``, ``local_starts=K``) sets the estimators' 1σ
options; the rows keep each part of the 1σ (bootstrap, grid, formal / profile) so that
``--report`` prints each alone.

Each seed is independent; ``--workers N`` spreads them over N one-thread processes; one line a
seed goes to ``--out`` (JSON lines, appended: an interrupted run resumes)::

    python benchmarks/bench_pole_coverage.py --part class --seeds 100 --workers 1 --out class.jsonl
    python benchmarks/bench_pole_coverage.py --part mismatch --seeds 20 --workers 1 --out mis.jsonl
    python benchmarks/bench_pole_coverage.py --part tumble --seeds 100 --workers 2 --out tumble.jsonl
    python benchmarks/bench_pole_coverage.py --report class.jsonl
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing as mp  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

SIDEREAL_DAY = 86164.0905
SEARCH = dict(n_poles=60, n_starts=4, n_refine=2, coarse_normals=150, coarse_samples=250, n_normals=400, max_samples=300,
              error_grids=1, bootstrap=0, local_starts=0)
#: the tumbling search's settings for ``--part tumble`` (those of tests/test_inversion_tumble.py's blind tumbler)
TUMBLE = dict(n_poles=40, coarse_samples=80, coarse_normals=32, n_pairs=2, screen_moments=4, screen_poles=12, n_screen=12,
              n_starts=6, n_refine=3, mid_samples=150, mid_normals=64, n_normals=200, max_samples=400, error_grids=1,
              bootstrap=20)
#: a circular Gaussian's radius, in units of its radial 1σ √(2)σ, that holds 68.27 % / 95.45 %
R68, R95 = math.sqrt(-math.log(1 - 0.6827)), math.sqrt(-math.log(1 - 0.9545))


def _geometry(t):
    w = 2 * np.pi / SIDEREAL_DAY
    obs = np.stack([np.cos(w * t + 0.3), np.sin(w * t + 0.3), np.full_like(t, 0.12)], 1)
    obs /= np.linalg.norm(obs, axis=1, keepdims=True)
    sun = np.tile(np.array([0.95, -0.1, 0.3]) / np.linalg.norm([0.95, -0.1, 0.3]), (len(t), 1))
    return sun, obs


def in_class_egi(rng, n_normals=400, k=24, on_grid=True):
    """``k`` normals with non-negative areas closed to ``|Σ a n| ≤ 1e-3 Σ a`` (NNLS of the
    closure, weight 100, beside areas near random targets): ``k`` of the ``n_normals`` grid
    normals (``on_grid``: the EGI represents it exactly on the fit's own grid) or ``k`` directions
    uniform on the sphere (a convex body off any grid: the grid's bias is then real)."""
    from scipy.optimize import nnls

    from cssat.inversion import fibonacci_sphere

    if on_grid:
        grid = fibonacci_sphere(n_normals).numpy()
        N = grid[rng.choice(n_normals, k, replace=False)]
    else:
        N = rng.normal(size=(k, 3))
        N /= np.linalg.norm(N, axis=1, keepdims=True)
    b = rng.uniform(0.2, 1.0, k)
    a, _ = nnls(np.vstack([100.0 * N.T, np.eye(k)]), np.concatenate([np.zeros(3), b]))
    return N, a


def off_grid_body():
    """The 14-facet polyhedron of tests/test_inversion_spin.py: normals (F, 3), areas (F,)."""
    import trimesh

    pts = np.random.default_rng(7).normal(size=(14, 3)) * np.array([2.0, 1.2, 0.7])
    hull = trimesh.convex.convex_hull(pts)
    return np.array(hull.face_normals), np.array(hull.area_faces)


def render(t, sun, obs, normals, areas, pole, period, glint=0.0):
    """Lambert light curve (plus a Blinn–Phong-200 lobe of weight ``glint``) of facets turning
    counter-clockwise about ``pole`` (scipy rotations, independent of cssat's spin frame)."""
    from scipy.spatial.transform import Rotation

    B0, _ = Rotation.align_vectors([pole], [[0.0, 0.0, 1.0]])
    out = np.empty(len(t))
    for i, ti in enumerate(t):
        n = (Rotation.from_rotvec(2 * np.pi * ti / period * pole) * B0).apply(normals)
        mu0, mu = np.clip(n @ sun[i], 0, None), np.clip(n @ obs[i], 0, None)
        h = (sun[i] + obs[i]) / np.linalg.norm(sun[i] + obs[i])
        out[i] = (areas / np.pi * mu0 * mu).sum()
        if glint:
            out[i] += glint * (areas * np.clip(n @ h, 0, None) ** 200 * (mu0 > 0) * (mu > 0)).sum()
    return out


def case(seed: int, part: str = "class", glint: float = 1.0, search: dict | None = None, egi: str = "grid") -> dict:
    """One seed: draw, search (``search``: :data:`SEARCH` with these keys replaced), verdict, the
    truth's profile Δχ²."""
    SEARCH = {**globals()["SEARCH"], **(search or {})}
    from cssat.inversion import estimate_period, estimate_spin
    from cssat.inversion.spin import _Fit
    from cssat.inversion.spin_errors import profile_chi2, separation_deg

    rng = np.random.default_rng(5000 + seed)
    t = np.sort(np.concatenate([d * 86400.0 + rng.uniform(0, 7 * 3600.0, 100) for d in range(4)]))
    sun, obs = _geometry(t)
    pole = rng.normal(size=3)
    pole /= np.linalg.norm(pole)
    period = rng.uniform(300, 900)
    ra, dec = math.degrees(math.atan2(pole[1], pole[0])), math.degrees(math.asin(pole[2]))
    if part == "class":  # the fit's own body frame (cssat's spin frame: phase 0 at t = 0), the areas on its grid
        from cssat.scene.attitude import spin_frame, to_body

        N, a = in_class_egi(rng, SEARCH["n_normals"], on_grid=egi == "grid")
        R = spin_frame(t, ra, dec, period, 0.0, "equatorial")
        sb, ob = to_body(R, sun), to_body(R, obs)
        y = (a / np.pi * np.clip(sb @ N.T, 0, None) * np.clip(ob @ N.T, 0, None)).sum(1)
    else:
        y = render(t, sun, obs, *off_grid_body(), pole, period, glint=glint)
    s = rng.uniform(0.005, 0.02) * float(np.mean(y))
    y = y + rng.normal(size=t.size) * s
    fit = t < 3 * 86400.0
    clock = time.process_time()
    P0 = estimate_period(t[fit], y[fit], min_period_s=150, max_period_s=3000)["best_period_s"]
    sol = estimate_spin(t[fit], y[fit], sun[fit], obs[fit], sigma=s, frame="equatorial", period_s=P0,
                        heldout=(t[~fit], y[~fit], sun[~fit], obs[~fit], s), **SEARCH)
    row = {"seed": seed, "part": part, "egi": egi, "sep_deg": separation_deg((sol.pole_lon_deg, sol.pole_lat_deg), (ra, dec)),
           "period_rel": abs(sol.period_s / period - 1), "verdict": sol.verdict, "reduced_chi2": sol.reduced_chi2,
           "heldout_chi2_n": sol.heldout_chi2 / sol.heldout_n, "heldout_limit_n": sol.heldout_threshold / sol.heldout_n,
           "heldout_leverage_n": sol.get("heldout_leverage", float("nan")) / sol.heldout_n,
           "pole_err_deg": sol.pole_err_deg, "laplace_pole_err_deg": sol.laplace_pole_err_deg, "noise": s,
           "ambiguous": sol.ambiguous, "grid_pole_shift_deg": sol.grid_pole_shift_deg,
           "search": {k: SEARCH[k] for k in ("n_poles", "n_starts", "n_refine", "error_grids", "bootstrap", "local_starts")},
           "bootstrap_pole_err_deg": sol.get("bootstrap_pole_err_deg"), "period_s_true": period, "period_err_s": sol.period_err_s,
           "bootstrap_period_err_s": sol.get("bootstrap_period_err_s"), "grid_period_shift_s": sol["grid_period_shift_s"],
           "bootstrap_lr_factor": sol.get("bootstrap_lr_factor")}
    prof = sol.pole_interval
    if prof:
        # the truth's profile Δχ² on the same samples and normals as the fit's (estimate_spin's subset)
        Tf = int(fit.sum())
        idx = np.unique(np.linspace(0, Tf - 1, min(SEARCH["max_samples"], Tf)).round().astype(int))
        from cssat.inversion import fibonacci_sphere

        w = np.full(Tf, 1.0 / s)
        q = _Fit(t[fit][idx], y[fit][idx], w[idx], sun[fit][idx], obs[fit][idx],
                 fibonacci_sphere(SEARCH["n_normals"]).numpy(), None, "equatorial")
        c_true, _ = profile_chi2(q.chi2, ra, dec, 1.0 / period, float(t[fit][-1] - t[fit][0]))
        row.update(delta_chi2_true=(c_true - prof["chi2"]) / prof["scale"], radius_68_deg=prof["radius_68_deg"],
                   radius_95_deg=prof["radius_95_deg"], profile_evals=prof["evaluations"], moved_deg=prof["moved_deg"],
                   quadratic_pole_err_deg=prof.get("quadratic_pole_err_deg"), profile_pole_err_deg=prof["pole_err_deg"])
    row["cpu_s"] = time.process_time() - clock
    return row


def tumble_case(seed: int, search: dict | None = None, egi: str = "grid") -> dict:
    """One tumbler (``--part tumble``): draw, search blind, verdict, ``L``'s error against its 1σ."""
    from cssat.inversion.spin_errors import separation_deg
    from cssat.inversion.tumble import TumblingState, estimate_tumbling, tumbling_rates

    opts = {**TUMBLE, **(search or {})}
    rng = np.random.default_rng(9000 + seed)
    while True:  # a motion with both rates (not on the separatrix)
        i2 = rng.uniform(0.6, 0.95)
        i1 = rng.uniform(max(1.0 - i2, 0.35), i2 - 0.02)
        alpha = math.radians(rng.uniform(10.0, 60.0))
        fw, fp = tumbling_rates(i1, i2, alpha)
        if fw == fw and fp > 0:
            break
    scale = 1.0 / (rng.uniform(150.0, 400.0) * fp)  # P_φ drawn
    L = rng.normal(size=3)
    L /= np.linalg.norm(L)
    lon, lat = math.degrees(math.atan2(L[1], L[0])), math.degrees(math.asin(L[2]))
    truth = TumblingState(i1, i2, alpha, fw * scale, fp * scale, rng.uniform(0, 1 / (fw * scale)), lon, lat,
                          rng.uniform(0, 360.0), 0.0, "equatorial")
    t = np.concatenate([np.arange(0, 14400, 10.0), 86400 + np.arange(0, 14400, 10.0), 2 * 86400 + np.arange(0, 3600, 10.0)])
    sun, obs = _geometry(t)
    N, a = in_class_egi(rng, opts["n_normals"], on_grid=egi == "grid")  # in the body (principal) frame
    R = truth.frames(t)
    sb, ob = np.einsum("tij,tj->ti", R, sun), np.einsum("tij,tj->ti", R, obs)
    clean = (a / np.pi * np.clip(sb @ N.T, 0, None) * np.clip(ob @ N.T, 0, None)).sum(1)
    s = rng.uniform(0.005, 0.02) * float(clean.mean())
    y = clean + s * rng.normal(size=t.size)
    fit = t < 2 * 86400
    clock = time.process_time()
    sol = estimate_tumbling(t[fit], y[fit], sun[fit], obs[fit], sigma=s, frame="equatorial", arc_s=7200.0,
                            heldout=(t[~fit], y[~fit], sun[~fit], obs[~fit], s), **opts)
    st = sol.state
    return {"seed": seed, "part": "tumble", "egi": egi, "sep_deg": separation_deg((st.lon_deg, st.lat_deg), (lon, lat)),
            "period_rel": max(abs(st.f_omega_hz / truth.f_omega_hz - 1), abs(st.f_phi_hz / truth.f_phi_hz - 1)),
            "i_err": max(abs(st.i1 - i1), abs(st.i2 - i2)), "mode_right": bool(st.short_axis == truth.short_axis),
            "verdict": sol.verdict, "verdict_why": sol.verdict_why, "reduced_chi2": sol.reduced_chi2, "noise": s,
            "heldout_chi2_n": sol.heldout_chi2 / sol.heldout_n, "heldout_limit_n": sol.heldout_threshold / sol.heldout_n,
            "heldout_leverage_n": sol.get("heldout_leverage", float("nan")) / sol.heldout_n,
            "L_err_deg": sol.errors["L_err_deg"], "formal_L_err_deg": sol.errors["formal_L_err_deg"],
            "grid_L_shift_deg": sol.errors["grid_L_shift_deg"],
            "bootstrap_L_err_deg": sol.errors.get("bootstrap_L_err_deg"), **_ellipse(sol, lon, lat),
            "fitted": [st.i1, st.i2, 1 / st.f_omega_hz, 1 / st.f_phi_hz], "ambiguous": sol.ambiguous,
            "errors": {k: sol.errors.get(k) for k in ("i1", "i2", "P_omega_s", "P_phi_s")}, "truth": [i1, i2, math.degrees(alpha), 1 / truth.f_omega_hz,
                                                                          1 / truth.f_phi_hz, lon, lat],
            "search": opts, "cpu_s": time.process_time() - clock}


def _ellipse(sol, lon: float, lat: float) -> dict:
    """The row's ``L`` ellipse keys and the truth's region levels: Hotelling's (``L_level``, what
    ``TumblingSolution.L_level`` reports) and the Gaussian's with the covariance taken as known."""
    from cssat.inversion.ellipse import ellipse_level

    e = {k: sol.errors.get(k) for k in ("L_major_deg", "L_minor_deg", "L_pa_deg", "L_dof")}
    if e["L_major_deg"] is None or e["L_major_deg"] != e["L_major_deg"]:
        return e
    known = ellipse_level((sol.state.lon_deg, sol.state.lat_deg), (lon, lat), e["L_major_deg"], e["L_minor_deg"], e["L_pa_deg"])
    return dict(e, L_level=sol.L_level(lon, lat), L_level_known=known)


def _verdicts(part: str, rs: list[dict], found_if, found_label: str, usable) -> list[tuple[str, list[dict]]]:
    """Print the part's line (found by ``found_if``, unreliable, of which wrong, wrong and reliable)
    and return the reliable seeds that ``usable`` keeps, all and found, each with its label."""
    found = [r for r in rs if found_if(r)]
    unrel = [r for r in rs if r["verdict"] == "unreliable"]
    print(f"{part}: {len(rs)} seeds; found ({found_label}) {len(found)}; unreliable {len(unrel)} "
          f"({100 * len(unrel) / max(len(rs), 1):.0f} %), of which wrong {sum(r not in found for r in unrel)}; "
          f"wrong and reliable {sum(r not in found and r['verdict'] == 'reliable' for r in rs)}")
    rel = [r for r in rs if r["verdict"] == "reliable" and usable(r)]
    return [(label, sub) for label, sub in (("reliable", rel), ("reliable and found", [r for r in rel if r in found])) if sub]


def tumble_found(r: dict) -> bool:
    """A tumbler row found: L within 5°, both periods within 1e-3."""
    return r["sep_deg"] < 5 and r["period_rel"] < 1e-3


def report_tumble(rs: list[dict]) -> None:
    for label, sub in _verdicts("tumble", rs, tumble_found,
                                "L < 5°, periods < 1e-3", lambda r: r["L_err_deg"] == r["L_err_deg"]):
        m = len(sub)
        z = np.array([r["sep_deg"] / r["L_err_deg"] for r in sub])
        zf = np.array([r["sep_deg"] / r["formal_L_err_deg"] for r in sub])
        k68, k95 = int((z <= R68).sum()), int((z <= R95).sum())
        lo68, hi68 = _wilson(k68, m)
        lo95, hi95 = _wilson(k95, m)
        print(f"  {label}: n {m}; L within the 68 % region: {100 * k68 / m:.1f} % (1σ binomial {100 * lo68:.1f}–"
              f"{100 * hi68:.1f}, {_p(k68, m, 0.6827)}); 95 %: {100 * k95 / m:.1f} % ({100 * lo95:.1f}–{100 * hi95:.1f}, "
              f"{_p(k95, m, 0.9545)}); the formal part alone "
              f"{100 * np.mean(zf <= R68):.1f} / {100 * np.mean(zf <= R95):.1f} %; median sep {np.median([r['sep_deg'] for r in sub]):.3f}°, "
              f"median L_err_deg {np.median([r['L_err_deg'] for r in sub]):.3f}°, cpu {np.median([r['cpu_s'] for r in sub]):.0f} s")
        if all(r.get("bootstrap_L_err_deg") is not None for r in sub):  # the parts of the 1σ, each alone
            zb = np.array([r["sep_deg"] / r["bootstrap_L_err_deg"] for r in sub])
            zg = np.array([r["sep_deg"] / r["grid_L_shift_deg"] if r["grid_L_shift_deg"] > 0 else math.inf for r in sub])
            print(f"    the bootstrap's part alone {100 * np.mean(zb <= R68):.1f} / {100 * np.mean(zb <= R95):.1f} %; the grid's "
                  f"alone {100 * np.mean(zg <= R68):.1f} / {100 * np.mean(zg <= R95):.1f} %")
        if all(r.get("L_level") is not None for r in sub):  # the 1σ ellipse's regions (what L_level reports)
            for key, what in (("L_level", "Hotelling's (L_dof replicates)"), ("L_level_known", "the covariance as known")):
                lv = np.array([r[key] for r in sub])
                k68, k95 = int((lv <= 0.6827).sum()), int((lv <= 0.9545).sum())
                print(f"    L inside its 1σ ellipse's regions, {what}: 68.27 % {100 * k68 / m:.1f} % ({_p(k68, m, 0.6827)}); "
                      f"95.45 % {100 * k95 / m:.1f} % ({_p(k95, m, 0.9545)})")
            print(f"    the ellipse's axis ratio: median {np.median([r['L_major_deg'] / max(r['L_minor_deg'], 1e-12) for r in sub]):.2f}")
        if all("errors" in r for r in sub):  # the moments' and periods' 1σ: |error| within 1 and 2 of it (68.27 / 95.45 %)
            for j, k in enumerate(("i1", "i2", "P_omega_s", "P_phi_s")):
                z1 = np.array([abs(r["fitted"][j] - r["truth"][[0, 1, 3, 4][j]]) / r["errors"][k] for r in sub])
                print(f"    {k}: within its 1σ {100 * np.mean(z1 <= 1):.1f} %, within 2σ {100 * np.mean(z1 <= 2):.1f} %")


def _wilson(k: int, n: int, z: float = 1.0) -> tuple[float, float]:
    """The Wilson score interval of ``k`` of ``n`` at ``z`` σ."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return c - h, c + h


def _p(k: int, n: int, level: float) -> str:
    """The two-sided binomial p-value of ``k`` of ``n`` inside a region of probability ``level``
    (scipy's exact test): how often a calibrated 1σ gives a count this far from ``n × level``."""
    from scipy.stats import binomtest

    return f"p {binomtest(k, n, level).pvalue:.2g}" if n else "p nan"


def powerless(rows: list[dict]) -> list[dict]:
    """The rows with the held-out test's power rule applied (``HELDOUT_MAX_LEVERAGE``, since the
    ellipse study) where they carry the leverage: a reliable row whose fitted parameters predict
    the held-out samples more loosely than that reread as unreliable, and said. Rows written
    before it carry no leverage and keep their verdict (``heldout_limit_n`` above 2 flags the few
    that could move: a limit is at least ``1 + leverage``)."""
    from cssat.inversion.spin_errors import HELDOUT_MAX_LEVERAGE

    weak = [r for r in rows if r.get("verdict") == "reliable" and (r.get("heldout_leverage_n") or 0) > HELDOUT_MAX_LEVERAGE]
    if weak:
        print(f"{len(weak)} reliable rows whose fitted parameters predict the held-out samples with more than "
              f"{HELDOUT_MAX_LEVERAGE:g}× the noise's variance counted unreliable (seeds {', '.join(str(r['seed']) for r in weak)})")
    return [{**r, "verdict": "unreliable"} if r in weak else r for r in rows]


def report(rows: list[dict]) -> None:
    from cssat.inversion.spin_errors import POLE_DELTA_CHI2  # the region's levels: 2.30, 6.18

    rows = powerless(rows)
    for part in sorted({r["part"] for r in rows}):
        rs = [r for r in rows if r["part"] == part]
        if part == "tumble":
            report_tumble(rs)
            continue
        # estimate_spin calls an ambiguous pole unreliable (since the ambiguity rule): rows written before it, reread so
        n_amb = sum(r["verdict"] == "reliable" and bool(r.get("ambiguous")) for r in rs)
        rs = [{**r, "verdict": "unreliable"} if r["verdict"] == "reliable" and r.get("ambiguous") else r for r in rs]
        if n_amb:
            print(f"{part}: {n_amb} reliable but ambiguous seeds counted unreliable (another minimum > 10° away within Δχ² < 9)")
        for label, sub in _verdicts(part, rs, lambda r: r["sep_deg"] < 10 and r["period_rel"] < 1e-3,
                                    "pole < 10°, period < 1e-3", lambda r: "delta_chi2_true" in r):
            m = len(sub)
            # inside the reported region: the truth's profile Δχ² under the level AND within the region's
            # widest radius (a truth of lower χ² elsewhere — a search that stopped in another minimum — is a miss)
            d = np.array([r["delta_chi2_true"] for r in sub])
            sep = np.array([r["sep_deg"] for r in sub])
            k68 = int(((d <= POLE_DELTA_CHI2["68"]) & (sep <= np.array([r["radius_68_deg"] for r in sub]))).sum())
            k95 = int(((d <= POLE_DELTA_CHI2["95"]) & (sep <= np.array([r["radius_95_deg"] for r in sub]))).sum())
            z = np.array([r["sep_deg"] / r["pole_err_deg"] for r in sub])
            zl = np.array([r["sep_deg"] / r["laplace_pole_err_deg"] for r in sub])
            lo68, hi68 = _wilson(k68, m)
            lo95, hi95 = _wilson(k95, m)
            if all("profile_pole_err_deg" in r for r in sub):  # the 1σ reported since the grid term joined the profile's
                c68, c95 = int((z <= R68).sum()), int((z <= R95).sum())
                (a68, b68), (a95, b95) = _wilson(c68, m), _wilson(c95, m)
                zp = np.array([r["sep_deg"] / r["profile_pole_err_deg"] for r in sub])
                print(f"  {label}: n {m}; the pole inside the 68.27 % circle of pole_err_deg (profile or bootstrap ⊕ grid, "
                      f"{R68:.4f}×): {100 * c68 / m:.1f} % ({100 * a68:.1f}–{100 * b68:.1f}, {_p(c68, m, 0.6827)}); 95.45 % "
                      f"({R95:.4f}×): {100 * c95 / m:.1f} % ({100 * a95:.1f}–{100 * b95:.1f}, {_p(c95, m, 0.9545)}); the profile's 1σ alone "
                      f"{100 * np.mean(zp <= R68):.1f} / {100 * np.mean(zp <= R95):.1f} %")
            if all(r.get("bootstrap_pole_err_deg") is not None for r in sub):  # step 8: the 1σ is bootstrap ⊕ grid
                zb = np.array([r["sep_deg"] / r["bootstrap_pole_err_deg"] for r in sub])
                zg = np.array([r["sep_deg"] / r["grid_pole_shift_deg"] for r in sub])
                print(f"    (pole_err_deg is bootstrap ⊕ grid here) the bootstrap's part alone {100 * np.mean(zb <= R68):.1f} / "
                      f"{100 * np.mean(zb <= R95):.1f} %; the grid's alone {100 * np.mean(zg <= R68):.1f} / "
                      f"{100 * np.mean(zg <= R95):.1f} %")
                if all(r.get("bootstrap_lr_factor") is not None for r in sub):  # the profile calibrated by the bootstrap
                    zc = np.array([r["sep_deg"] / math.hypot(math.sqrt(max(1.0, r["bootstrap_lr_factor"])) * r["profile_pole_err_deg"],
                                                             r["grid_pole_shift_deg"]) for r in sub])
                    print(f"    the profile's 1σ × √max(1, bootstrap_lr_factor) ⊕ grid: {100 * np.mean(zc <= R68):.1f} / "
                          f"{100 * np.mean(zc <= R95):.1f} % (median factor "
                          f"{np.median([r['bootstrap_lr_factor'] for r in sub]):.2f})")
            if all(r.get("period_err_s") is not None for r in sub):  # the period's 1σ (one number: 1σ and 2σ)
                zp1 = np.array([r["period_rel"] * r["period_s_true"] / r["period_err_s"] for r in sub])
                print(f"    the period inside period_err_s / 2×: {100 * np.mean(zp1 <= 1):.1f} / {100 * np.mean(zp1 <= 2):.1f} % "
                      f"(68.27 / 95.45)")
            print(f"  {label}: n {m}; profile region 68 %: {100 * k68 / m:.1f} % (1σ binomial {100 * lo68:.1f}–{100 * hi68:.1f}); "
                  f"95 %: {100 * k95 / m:.1f} % ({100 * lo95:.1f}–{100 * hi95:.1f}); sep ≤ pole_err_deg {100 * np.mean(z <= 1):.1f} % "
                  f"/ ≤ 2× {100 * np.mean(z <= 2):.1f} % (63.2 / 98.2); Laplace 1σ {100 * np.mean(zl <= 1):.1f} / "
                  f"{100 * np.mean(zl <= 2):.1f} %; median sep {np.median([r['sep_deg'] for r in sub]):.3f}°, "
                  f"median radius_68 {np.median([r['radius_68_deg'] for r in sub]):.3f}°, cpu {np.median([r['cpu_s'] for r in sub]):.0f} s")


def _run(args_tuple):
    seed, part, glint, search, egi = args_tuple
    try:
        return tumble_case(seed, search, egi) if part == "tumble" else case(seed, part, glint, search, egi)
    except Exception as e:  # noqa: BLE001 - a failed seed is reported, not fatal
        return {"seed": seed, "part": part, "error": repr(e)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--part", choices=("class", "mismatch", "tumble"), default="class")
    p.add_argument("--seeds", type=int, default=100)
    p.add_argument("--first", type=int, default=0)
    p.add_argument("--glint", type=float, default=1.0)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--egi", choices=("grid", "off"), default="grid",
                   help="in class: the truth's EGI on the fit's own grid of normals, or off any grid")
    p.add_argument("--out", default=None, help="JSON lines, appended; seeds already there are skipped")
    p.add_argument("--report", nargs="+", default=None, help="only tabulate these JSON-lines files, pooled")
    p.add_argument("--search", nargs="*", default=[], metavar="KEY=INT",
                   help="the search's settings changed, e.g. n_poles=200 n_starts=12 n_refine=4 (default: SEARCH)")
    args = p.parse_args()
    search = {}
    for kv in args.search:
        key, _, value = kv.partition("=")
        known = TUMBLE if args.part == "tumble" else SEARCH
        if key not in known or not value.isdigit():
            p.error(f"--search {kv!r}: expected KEY=INT with KEY one of {', '.join(known)}")
        search[key] = int(value)
    if args.report:
        rows = []
        for name in args.report:
            with open(name) as fh:
                rows += [json.loads(x) for x in fh if x.strip()]
        return report([r for r in rows if "error" not in r])
    done = set()
    if args.out and os.path.exists(args.out):
        with open(args.out) as fh:
            done = {(r["part"], r["seed"]) for r in map(json.loads, filter(str.strip, fh))}
    todo = [(s, args.part, args.glint, search, args.egi) for s in range(args.first, args.first + args.seeds) if (args.part, s) not in done]
    rows = []
    with mp.get_context("spawn").Pool(max(args.workers, 1)) as pool:
        for r in pool.imap_unordered(_run, todo):
            rows.append(r)
            print(json.dumps(r), file=sys.stderr, flush=True)
            if args.out:
                with open(args.out, "a") as fh:
                    fh.write(json.dumps(r) + "\n")
    report([r for r in rows if "error" not in r])


if __name__ == "__main__":
    main()
