"""The occultation's headline over a set of silhouettes (issue 37, point 4): ``cssat
experiment=occultation`` (nothing handed over: offsets, speed, gains and the star's diameter
estimated; polychromatic V; frozen scintillation) on every silhouette of the set, and the
idealised rows beside the default one, each over ``--seeds``.

The set: the Astra-like model with its arrays face-on (the default), at 45° and edge-on
(``astra_like``), the TESS-like procedural model, NASA's TESS mesh (``../shared/models/tess.obj``,
skipped when absent) at two orientations (inertial attitudes), and bar targets of 1.0 and 0.5 m.
The rows (``--rows``, on the default silhouette): ``oracle`` (every nuisance handed over),
``mono`` (a monochromatic pattern at 550 nm, the V band's photons), ``white`` (white
scintillation only), ``giant`` (a red giant of 2 mas instead of the 0.5 mas K giant),
``pixels`` (the pixel TV prior alone, without the held-out choice of superellipses). Prints a table (registered IoU, the IoU where the fit placed the silhouette,
the linear route's, the offsets' errors in units of their 1σ and the 1σ, the star's diameter
where the χ² profile is lowest (a diagnostic: the diameter is fixed at the prior's mean), the
gains within 2σ, the prior used and its number of superellipses, seconds), then per silhouette and
row the registered IoU's **median and 10–90 % range over the seeds** (linear interpolation
between order statistics, numpy's default), and the median and worst over the set; ``--json``
writes every run's metrics.

Run from the repository root (one thread a run; ``--jobs 2`` runs two at once); the headline's
distribution over ten seeds of the default::

    python benchmarks/occultation_set.py --set astra_faceon --rows --seeds 0 1 2 3 4 5 6 7 8 9 --jobs 2 --json outputs/occultation_10seeds.json
"""

from __future__ import annotations

import argparse
import json
import statistics
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

TESS = Path(__file__).resolve().parents[2] / "shared" / "models" / "tess.obj"

SET = {
    "astra_faceon": [],
    "astra_45deg": ["model.array_angle_deg=45"],
    "astra_edgeon": ["model=astra_like"],
    "tess_like": ["model=tess_like"],
    "tess_obj_a": ["model=file", f"model.path={TESS}", "attitude=inertial", "attitude.quaternion=[0.0,0.0,0.0,1.0]"],
    "tess_obj_b": ["model=file", f"model.path={TESS}", "attitude=inertial",
                   "attitude.quaternion=[0.3826834,0.0,0.0,0.9238795]"],
    "bars_1.0m": ["silhouette.target=bars", "silhouette.bar_m=1.0"],
    "bars_0.5m": ["silhouette.target=bars", "silhouette.bar_m=0.5"],
}
ROWS = {"oracle": ["event.oracle=true"], "mono": ["optics.band=null"], "white": ["array.scintillation=white"],
        "giant": ["star.diameter_mas=2.0"], "pixels": ["invert.prior=pixels"]}
KEYS = ("iou", "iou_placed", "iou_linear", "iou_pixels", "time_offset_error_sigmas", "path_offset_error_sigmas", "time_offset_sigma_s",
        "path_offset_sigma_m", "star_diameter_profile_best_mas", "gains_within_2sigma", "prior_used", "n_shapes", "seconds")


def _run(job: tuple[str, list[str], int, str]) -> tuple[str, int, dict]:
    import tempfile

    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    name, overrides, seed, extra = job
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=occultation", *overrides, f"seed={seed}", "threads=1",
                                                       *extra.split()])
    with tempfile.TemporaryDirectory() as d:
        try:
            m = run_experiment(cfg, Path(d) / "run")
        except Exception as e:  # a shadow too faint to find is a result: IoU 0 in the set's statistics
            m = {"status": "failed", "error": str(e), "iou": 0.0}
    return name, seed, m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--set", nargs="*", default=list(SET), help=f"silhouettes (default all: {' '.join(SET)})")
    ap.add_argument("--rows", nargs="*", default=list(ROWS), help="idealised rows on the default silhouette")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--extra", default="", help="overrides added to every run (space-separated)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    jobs = [(n, SET[n], s, args.extra) for n in args.set if not (n.startswith("tess_obj") and not TESS.is_file())
            for s in args.seeds]
    jobs += [(f"row:{r}", ROWS[r], s, args.extra) for r in args.rows for s in args.seeds]
    partial = Path(args.json).with_suffix(".partial.jsonl") if args.json else None
    if partial is not None:
        partial.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text("")
    results = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        for fut in as_completed([ex.submit(_run, j) for j in jobs]):  # each run recorded as it ends (a long set can be read early)
            name, seed, m = fut.result()
            results.append((name, seed, m))
            print(f"done: {name} seed {seed}: IoU {m.get('iou')}, prior {m.get('prior_used')}, n_shapes {m.get('n_shapes')}, "
                  f"{m.get('seconds')} s", flush=True)
            if partial is not None:
                with partial.open("a") as f:
                    f.write(json.dumps({"run": name, "seed": seed, **m}, default=str) + "\n")
    order = {(n, s): i for i, (n, _, s, _) in enumerate(jobs)}
    results.sort(key=lambda r: order[(r[0], r[1])])
    print("| run | seed | " + " | ".join(KEYS) + " |")
    print("|---|---:|" + "---:|" * len(KEYS))
    for name, seed, m in results:
        cells = []
        for k in KEYS:
            v = m.get(k)
            cells.append(f"[{v[0]:.2f}, {v[1]:.2f}]" if isinstance(v, list) else "—" if v is None else
                         v if isinstance(v, str) else f"{v:.3g}")
        print(f"| {name} | {seed} | " + " | ".join(cells) + " |" + (f" {m['error']}" if m.get("status") == "failed" else ""))
    by: dict[str, list[float]] = {}
    for name, _, m in results:
        by.setdefault(name, []).append(float(m.get("iou") or 0.0))
    for name, v in by.items():
        lo, med, hi = np.percentile(v, [10, 50, 90])
        print(f"{name}: registered IoU over {len(v)} seeds: median {med:.3f}, 10-90 % [{lo:.3f}, {hi:.3f}], "
              f"min {min(v):.3f}, max {max(v):.3f}")
    ious = [m["iou"] for n, _, m in results if not n.startswith("row:")]
    if ious:
        print(f"registered IoU over the set ({len(ious)} runs): median {statistics.median(ious):.3f}, worst {min(ious):.3f}")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps([{"run": n, "seed": s, **m} for n, s, m in results], indent=1, default=str))


if __name__ == "__main__":
    main()
