"""Figure: the confident-wrong pole, before and after the held-out verdict (docs/pole_verdict.png).

Three panels from the ``metrics.json`` of two runs of ``cssat experiment=inversion`` and the 1σ
the code printed before the verdict existed:

- **before**: the default inversion's pole (a defunct Astra-like satellite with its own
  materials, glints and self-shadowing, inverted by the shadowless convex EGI) against the truth,
  with the 1σ that was printed for that same estimate (``--before-sigma``, 0.42°: BENCHMARKS.md
  "Coverage of the pole and L", the before row) — a circle too small to see, 84° from the truth;
- **after**: the same estimate as the run reports it now — ``spin_verdict: unreliable``, no 1σ,
  with the held-out χ²/n against the level the noise allows;
- **in class**: the oracle row (``brdf=lambert shadows=false inversion.brdf=simulated``): the pole,
  its 68 % and 95 % profile-likelihood regions (drawn as circles of the largest radius over the
  bearings) and the truth.

The runs (BENCHMARKS.md gives their commits and times)::

    cssat experiment=inversion seed=0 threads=1 hydra.run.dir=default_s0
    cssat experiment=inversion brdf=lambert shadows=false inversion.brdf=simulated seed=0 threads=1 hydra.run.dir=inclass_s0
    python benchmarks/fig_pole_verdict.py --mismatch default_s0 --inclass inclass_s0 --out docs/pole_verdict.png

The truth's pole is the ``spin_defunct`` attitude's (``conf/attitude/spin_defunct.yaml``; ecliptic).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np


def _truth() -> tuple[float, float]:
    import yaml

    import cssat.conf

    node = yaml.safe_load((Path(cssat.conf.__file__).parent / "attitude" / "spin_defunct.yaml").read_text())
    return float(node["pole_lon_deg"]), float(node["pole_lat_deg"])


def _wrap(lon_deg: float) -> float:
    return math.radians((lon_deg + 180.0) % 360.0 - 180.0)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mismatch", required=True, help="the default inversion's run directory (its metrics.json)")
    p.add_argument("--inclass", required=True, help="the in-class run's directory")
    p.add_argument("--before-sigma", type=float, default=0.42, help="the 1σ (°) printed for the same estimate before the verdict")
    p.add_argument("--out", default="docs/pole_verdict.png")
    args = p.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cssat.inversion.spin_errors import separation_deg

    mis = json.loads((Path(args.mismatch) / "metrics.json").read_text())
    inc = json.loads((Path(args.inclass) / "metrics.json").read_text())
    truth = _truth()
    est = (mis["spin_pole_lon_deg"], mis["spin_pole_lat_deg"])
    fig = plt.figure(figsize=(13.5, 4.2))
    for k, title in enumerate(("before: a wrong pole with a 1σ", "after: the same pole, called unreliable")):
        ax = fig.add_subplot(1, 3, k + 1, projection="aitoff")
        ax.grid(True, lw=0.4)
        ax.set_xticklabels([])
        ax.plot(_wrap(truth[0]), math.radians(truth[1]), "*", ms=14, color="tab:green", label="truth")
        ax.plot(_wrap(est[0]), math.radians(est[1]), "o" if k == 0 else "x", ms=9, mew=2, color="tab:red",
                label="estimate")
        if k == 0:
            txt = (f"{separation_deg(est, truth):.1f}° from the truth\nprinted 1σ {args.before_sigma:.2f}°\n"
                   "(its circle is smaller than the dot)")
        else:
            n = mis["spin_heldout_n"]
            txt = (f"verdict: {mis['spin_verdict']}\nheld-out χ²/n {mis['spin_heldout_chi2'] / n:.1f} "
                   f"> {mis['spin_heldout_threshold'] / n:.2f} allowed\n1σ: none reported")
        ax.text(0.5, -0.16, txt, transform=ax.transAxes, ha="center", va="top", fontsize=9)
        ax.set_title(title + " (ecliptic)", fontsize=10, pad=12)
        if k == 0:
            ax.legend(loc="upper left", fontsize=8, bbox_to_anchor=(-0.12, 1.18))
    # in class: the local tangent plane about the estimate, degrees east (× cos β) and north
    ax = fig.add_subplot(1, 3, 3)
    e = (inc["spin_pole_lon_deg"], inc["spin_pole_lat_deg"])

    def plane(lon: float, lat: float) -> tuple[float, float]:
        dl = (lon - e[0] + 180.0) % 360.0 - 180.0
        return dl * math.cos(math.radians(e[1])), lat - e[1]

    th = np.linspace(0, 2 * np.pi, 200)
    for r, style, lab in ((inc["spin_pole_radius_68_deg"], "-", "68 % region"), (inc["spin_pole_radius_95_deg"], "--", "95 % region")):
        ax.plot(r * np.cos(th), r * np.sin(th), style, color="tab:blue", label=f"{lab} ({r:.2f}°)")
    ax.plot(0, 0, "o", color="tab:blue", label="estimate (reliable)")
    tx, ty = plane(*truth)
    ax.plot(tx, ty, "*", ms=14, color="tab:green", label=f"truth ({inc['pole_error_deg']:.2f}° off)")
    lim = 1.3 * max(inc["spin_pole_radius_95_deg"], math.hypot(tx, ty))
    ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", xlabel="east (°)", ylabel="north (°)")
    ax.set_title("in class (Lambert, no shadows): the profile region", fontsize=10)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110, metadata={"Software": None})
    print(f"wrote {args.out}: mismatch {mis['pole_error_deg']:.1f}° off ({mis['spin_verdict']}), in class "
          f"{inc['pole_error_deg']:.2f}° off, regions {inc['spin_pole_radius_68_deg']:.2f}° / {inc['spin_pole_radius_95_deg']:.2f}°")


if __name__ == "__main__":
    main()
