"""A light curve of a real satellite mesh, as a notebook would compute it.

The NASA TESS model (``../shared/models/tess.obj`` when present, else cssat's TESS-like model),
three-axis stabilised on the paper's geostationary orbit, seen from 51.17°N 10.45°E for a day:
SGP4 orbit, Sun, Earth shadow, per-facet BRDF (Eq. 8–9) with self- and observer-shadowing, and
the light curve in W/m² and magnitudes (Eq. 10); then the paper's Fig. 4.

    python examples/light_curve_of_a_mesh.py --steps 1437 --size 128 --out fig4.png
"""

import argparse
from pathlib import Path

import numpy as np

from cssat.optics import apparent_magnitude, default_fov, render, simulate_light_curve
from cssat.plots import lightcurve_figure, save_figure
from cssat.scene import load_mesh, make_scenario, tess_like

ap = argparse.ArgumentParser()
ap.add_argument("--steps", type=int, default=1437, help="one-minute steps from 2020-04-01 00:00 UTC")
ap.add_argument("--size", type=int, default=128, help="pixels per side of the rendered views")
ap.add_argument("--out", default="fig4_lightcurve.png")
args = ap.parse_args()

obj = Path(__file__).resolve().parents[2] / "shared" / "models" / "tess.obj"
mesh = load_mesh(obj, scale=1.0) if obj.exists() else tess_like()   # metres, per-facet Cd/Cs
scenario = make_scenario(n_steps=args.steps, step_s=60.0)           # the paper's Astra 1KR geometry
lc = simulate_light_curve(mesh, scenario)                           # Eq. 8–10, shadows included
mag = apparent_magnitude(lc.flux).numpy()
lit = np.isfinite(mag)
print(f"{mesh.name}: {len(mesh)} facets, {len(scenario)} steps, V = {mag[lit].min():.2f} .. {mag[lit].max():.2f}")

marks = np.linspace(0, len(scenario) - 1, 5).round().astype(int)    # five views along the day
fov = default_fov(mesh)
views = render(mesh, lc.sun[marks], lc.observer[marks], args.size, fov_m=fov, brightness=lc.facets[marks])
minutes = (scenario.times - scenario.times[0]) / np.timedelta64(1, "m")
save_figure(lightcurve_figure(minutes, mag, views.numpy(), marks, scenario.times, scenario.sunlit, fov_m=fov), args.out)
print("figure:", args.out)
