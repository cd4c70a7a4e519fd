"""An oracle start for the finer family: what its fit reaches from the platform's own parameters.

A probe, not a result: the start is the truth's (``benchmarks/_platforms.py``'s ``FINE``, every
albedo at the run's ``cd0``), which no user has. It tells a search failure (the family and its fit
reach the noise from there, the experiment's search did not find that basin) from a family or
rendering that cannot (they do not, even from there).

Input: the directory of an inversion run of one of the platforms with the attitude known
(``inversion.spin=known``, ``inversion.shape=parametric``, ``shadow_resolution_m`` and
``inversion.parametric.shadow_resolution_m``, ``brdf=lambert``; BENCHMARKS.md "Each night's χ²"
and "An oracle start"): its ``arrays.npz`` (flux, σ, body-frame Sun and observer, nights) and
``metrics.json`` (the fitted family). The flux's scale to the family's unit (m², flux per unit
irradiance at 1 m) is read off the run's own final model against the family rendered at its
fitted parameters (the same for every sample to rounding: printed).

Prints χ²/n night by night (the held-out night starred) for: the run's fitted family; the
platform's own parameters; the fit from them (soft shadows, then a polish with the shadows resolved,
the experiment's path); with ``--spin LON LAT PERIOD PHASE`` (the truth's spin, the run's config),
:func:`~cssat.inversion.parametric_spin.refine_spin` from the truth's spin and parameters with
shape and spin free, its pole's error against its 1σ and its verdict. One thread::

    PYTHONPATH=$PWD python benchmarks/probe_oracle_start.py RUN_DIR spacebus_like --resolution 0.2 --spin 60 35 437 17
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path, help="an inversion run's directory (attitude known)")
    ap.add_argument("platform", choices=("b702_like", "spacebus_like"))
    ap.add_argument("--resolution", type=float, default=0.2, help="the family's resolved shadows (m), as the run's")
    ap.add_argument("--cd0", type=float, default=0.5, help="every albedo of the start (the run's cd0)")
    ap.add_argument("--spin", type=float, nargs=4, metavar=("LON", "LAT", "PERIOD", "PHASE"), default=None)
    ap.add_argument("--no-fit", action="store_true", help="skip the attitude-known fit (only the spin's refinement)")
    args = ap.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _platforms

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility, param_names
    from cssat.inversion.parametric_fit import fit_box_wing

    a = np.load(args.run / "arrays.npz")
    m = json.loads((args.run / "metrics.json").read_text())
    parts, fine = _platforms.FINE[args.platform]
    geo = dict(panels=2, divisions=4, dish_rings=4, dish_segments=16, **parts)
    names = param_names(**parts)
    S, V, night, fit = a["sun_body"], a["obs_body"], a["night"], a["fit"].astype(bool)
    res = args.resolution

    def curve(p):
        vis = box_wing_visibility(p, S, V, resolution_m=res, **geo)
        return box_wing_light_curve(torch.as_tensor(p), S, V, vis, range_km=1e-3, irradiance=1.0, **geo).numpy()

    p_run = np.array([m[f"parametric_{k}"] for k in names])
    u = curve(p_run)
    lit = u > 0.2 * u.max()
    k = a["model"][lit] / u[lit]
    print(f"the flux's scale from the run's model: spread {k.max() / k.min() - 1:.1e} (relative)")
    k = float(np.median(k))
    y, sig = a["flux"] / k, a["sigma"] / k

    def report(label, p):
        z2 = ((y - curve(p)) / sig) ** 2
        nights = ", ".join(f"{z2[night == n].mean():.2f}{'' if fit[night == n][0] else '*'}" for n in np.unique(night))
        print(f"{label:46s} χ²/n by night {nights}; fitted {z2[fit].mean():.2f}, held out {z2[~fit].mean():.2f}", flush=True)

    z2t = ((a["flux"] - a["clean"]) / a["sigma"]) ** 2
    print(f"{'the true mesh':46s} χ²/n by night " + ", ".join(f"{z2t[night == n].mean():.2f}" for n in np.unique(night)))
    report("the run's fitted family", p_run)
    p0 = np.array([args.cd0 if q.startswith("cd_") else fine[q] for q in names])
    report("the platform's own parameters", p0)
    kw = dict(sigma=sig[fit], outer=6, inner=40, huber=3.0, visibility="soft", softness=0.1, albedos="profile",
              fixed=("cd_bus",))
    if not args.no_fit:
        clock = time.process_time()
        p1, _ = fit_box_wing(y[fit], S[fit], V[fit], p0, **kw, **geo)
        report("fitted from them, soft shadows", p1)
        p2, _ = fit_box_wing(y[fit], S[fit], V[fit], p1, **dict(kw, outer=3, resolution_m=res), **geo)
        report("then polished, shadows resolved", p2)
        print(f"  {time.process_time() - clock:.0f} CPU-s")
    if args.spin is None:
        return
    from cssat.inversion.parametric_spin import refine_spin
    from cssat.inversion.spin_errors import separation_deg
    from cssat.scene.attitude import spin_frame

    lon, lat, period, phase = args.spin
    t = a["times"]
    R = spin_frame(t, lon, lat, period, phase, "ecliptic")  # the truth's frames: body = R inertial
    s_in, o_in = np.einsum("tji,tj->ti", R, S), np.einsum("tji,tj->ti", R, V)
    h = ~fit
    clock = time.process_time()
    r = refine_spin(t[fit], y[fit], s_in[fit], o_in[fit], p0, lon, lat, period, phase, sigma=sig[fit], frame="ecliptic",
                    fixed=("cd_bus",), shape=True, heldout=(t[h], y[h], s_in[h], o_in[h], sig[h]), huber=3.0,
                    resolution_m=res, **geo)
    off = separation_deg((r["pole_lon_deg"], r["pole_lat_deg"]), (lon, lat))
    one = r["formal_pole_err_deg"]
    print(f"refine_spin from the truth's spin and parameters: pole {off:.3f}° off (formal 1σ {one:.3f}°: {off / one:.1f}σ), "
          f"period {r['period_s']:.5f} s, held-out χ²/n {r['heldout_chi2'] / r['heldout_n']:.3f} "
          f"(limit {r['heldout_threshold'] / r['heldout_n']:.3f}), verdict {r['verdict']}, stated 1σ {r['pole_err_deg']:.3f}°; "
          f"loss {r['refined_loss']:.4f} refined, {r['start_loss']:.4f} at the start, the start kept: {r['kept_start']}; "
          f"{time.process_time() - clock:.0f} CPU-s")


if __name__ == "__main__":
    main()
