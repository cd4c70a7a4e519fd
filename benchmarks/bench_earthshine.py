"""The size of earthshine beside direct sunlight at GEO, on the inversion experiment's default geometry.

The inversion's defaults (conf/experiment/inversion.yaml): the synthetic Astra 1KR element set,
the station at 51.17° N 10.45° E, model ``astra_defunct``, attitude ``spin_defunct``, BRDF
``lambert``, nights from 2020-04-01 (Sun below −12°, object above 20°). This script simulates the
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
    from hydra import compose, initialize_config_module  # heavy: hydra, to read the shipped configs

    from cssat.experiments.build import build, build_model  # heavy: the experiments' builders
    from cssat.experiments.forward.nights import night_mask  # heavy: the inversion's nights
    from cssat.experiments.scene import build_scenario  # heavy: skyfield scenarios
    from cssat.optics import simulate_light_curve  # heavy: imports torch

    torch.set_num_threads(1)
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose("config", overrides=["experiment=inversion"])
    start = np.datetime64(str(cfg.scenario.start_utc))
    n = int(args.nights * 86400 / args.step_s)
    times = start + (np.arange(n) * args.step_s * 1e6).astype("timedelta64[us]")
    sc = build_scenario(cfg, times)
    keep = night_mask(sc, float(cfg.nights.sun_alt_max_deg), float(cfg.nights.min_elevation_deg))
    sc = type(sc)(**{k: (getattr(sc, k)[keep] if k != "name" else sc.name) for k in sc.__dataclass_fields__})
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
