"""The Astra-like model's V magnitude at GEO with real materials beside the paper's uniform one.

The inversion experiment's geometry (conf/experiment/inversion.yaml: the synthetic Astra 1KR
element set, the station at 51.17° N 10.45° E, nights from 2020-04-01: Sun below −12°, object above
20°, sunlit), its ``brdf=mesh`` (the paper's Eq. 8–9 with each facet's own cd, cs), no
self-shadowing. For ``astra_defunct`` + ``spin_defunct`` (the inversion's default) and
``astra_like`` + ``nadir`` (a working, Sun-tracking satellite's attitude), each with
``model.material=uniform`` (every facet cd 0.8, cs 0.2) and ``satellite`` (cssat/scene/materials.py),
prints the median V, its 10th percentile, the brightest sample (a glint) and each material's median
share of the flux::

    PYTHONPATH=$PWD python benchmarks/bench_materials.py [--nights 3] [--step-s 60]
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nights", type=int, default=3)
    ap.add_argument("--step-s", type=float, default=60.0)
    args = ap.parse_args()
    import torch  # heavy: torch, the script's work
    from _nights import night_scenario

    from cssat.experiments.build import build, build_model  # heavy: the experiments' builders
    from cssat.optics import apparent_magnitude, simulate_light_curve  # heavy: imports torch

    torch.set_num_threads(1)
    for model, attitude in (("astra_defunct", "spin_defunct"), ("astra_like", "nadir")):
        for material in ("uniform", "satellite"):
            over = ["experiment=inversion", "brdf=mesh", f"model={model}", f"attitude={attitude}",
                    f"model.material={material}"]
            cfg, sc, _ = night_scenario(over, args.nights, args.step_s)
            mesh = build_model(cfg.model)
            facets = simulate_light_curve(mesh, sc, shadows=False, attitude=build(cfg.attitude, "attitude"), brdf=None).facets
            flux = facets.sum(1)
            v = apparent_magnitude(flux[flux > 0]).numpy()
            print(f"{model:14s} {attitude:13s} {material:10s} {len(v):5d} samples: V median {np.median(v):6.2f}, "
                  f"10th pct {np.percentile(v, 10):6.2f}, brightest {v.min():6.2f}, faintest {v.max():6.2f}")
            if mesh.part is not None:  # each material's median share of the flux
                lit = flux > 0
                shares = {n: float(np.median((facets[lit][:, torch.as_tensor(mesh.part == i)].sum(1) / flux[lit]).numpy()))
                          for i, n in enumerate(mesh.part_names)}
                print("    median share of the flux: " + ", ".join(f"{n} {x:.3f}" for n, x in shares.items()))


if __name__ == "__main__":
    main()
