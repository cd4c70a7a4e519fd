"""The size of earthshine beside direct sunlight at GEO, on the inversion experiment's default geometry.

The inversion's defaults (conf/experiment/inversion.yaml): the synthetic Astra 1KR element set,
the station at 51.17° N 10.45° E, model ``astra_defunct``, attitude ``spin_defunct``, BRDF
``lambert`` (given: the experiment's default is now ``mesh``), nights from 2020-04-01 (Sun below −12°, object above 20°). This script simulates the
first ``--nights`` nights at ``--step-s`` with and without earthshine (Earth: Lambertian, albedo
0.3; cssat.optics.earthshine) and prints the earthshine fraction of the total and its effect in
magnitudes::

    PYTHONPATH=$PWD python benchmarks/bench_earthshine.py [--nights 1] [--step-s 600]
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nights", type=int, default=1)
    ap.add_argument("--step-s", type=float, default=600.0)
    args = ap.parse_args()
    import torch  # heavy: torch, the script's work
    from _nights import night_scenario

    from cssat.experiments.build import build, build_model  # heavy: the experiments' builders
    from cssat.optics import simulate_light_curve  # heavy: imports torch

    torch.set_num_threads(1)
    # the inversion's geometry with a Lambert surface (albedo 0.5), as measured in BENCHMARKS.md
    cfg, sc, n = night_scenario(["experiment=inversion", "brdf=lambert"], args.nights, args.step_s)
    mesh = build_model(cfg.model)
    attitude = build(cfg.attitude, "attitude")
    brdf = build(cfg.brdf, "brdf")
    sun = simulate_light_curve(mesh, sc, shadows=False, attitude=attitude, brdf=brdf).flux.numpy()
    both = simulate_light_curve(mesh, sc, shadows=False, attitude=attitude, brdf=brdf, earthshine=True).flux.numpy()
    lit = sun > 0
    frac = (both - sun)[lit] / both[lit]
    dm = 2.5 * np.log10(both[lit] / sun[lit])
    print(f"{lit.sum()} night samples of {n} ({args.nights} night(s) at {args.step_s:.0f} s); phase angle "
          f"{np.degrees(np.arccos(np.clip((sc.sun_dir * sc.obs_dir).sum(1), -1, 1)))[lit].min():.0f}-"
          f"{np.degrees(np.arccos(np.clip((sc.sun_dir * sc.obs_dir).sum(1), -1, 1)))[lit].max():.0f}°")
    print(f"earthshine / total: median {np.median(frac):.2e}, max {frac.max():.2e}; brighter by median "
          f"{np.median(dm):.4f} mag, max {dm.max():.4f} mag")


if __name__ == "__main__":
    main()
