"""cssat beside lumos-sat (PyPI ``lumos-sat`` 1.0.9) on plate and box-wing satellites.

lumos-sat pins old numpy/astropy, so it lives in its own virtual environment and never becomes a
cssat dependency; this script runs its lumos half there (``--lumos-part``, a JSON on stdout) and its
cssat half here::

    python3 -m venv /work/lumos-venv && /work/lumos-venv/bin/pip install lumos-sat
    PYTHONPATH=$PWD python benchmarks/bench_lumos.py [--lumos-python /work/lumos-venv/bin/python]

Geometry (lumos's "brightness frame", metres): the Earth's centre at the origin, the satellite at
``(0, 0, R⊕ + h)``, the Sun along ``(0, cos β, −sin β)`` (β the angle past the terminator), the
observer where lumos's ``get_brightness_coords`` puts it for the satellite's altitude/azimuth and
the Sun's altitude. Surfaces: Lambertian (``LAMBERTIAN(albedo)`` in lumos, ``cd = albedo, cs = 0``
in cssat), one-sided, no shadowing (lumos casts none). The Earth: Lambertian, albedo 0.3, R⊕ = 6378
km (lumos's constants). Compared: the AB magnitude at 532 nm of the total flux (lumos's
``intensity_to_ab_mag``; cssat's ``ab_magnitude_at(..., convention="bolometric")``) and the
earthshine term alone (lumos ``include_sun=False``; cssat :func:`earthshine_brightness`).
cssat keeps its own I₀ = 1361 W/m² (lumos: 1360) and c = 299 792 458 m/s (lumos: 3·10⁸).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys

R_EARTH_M = 6378e3  # lumos.constants.EARTH_RADIUS


def geometries() -> list[dict]:
    """36 cases: 3 heights × 2 shapes × 6 (satellite alt/az, Sun alt/az) pairs."""
    views = [(70, 10, -20, 100), (45, 200, -15, 270), (30, 90, -12, 60), (60, 300, -8, 180), (80, 45, -10, 200),
             (35, 150, -18, 330)]
    return [dict(h_km=h, shape=s, sat_alt=a, sat_az=az, sun_alt=sa, sun_az=saz)
            for h in (550.0, 1200.0, 2000.0) for s in ("plate", "boxwing") for a, az, sa, saz in views]


def surfaces(shape: str, beta: float) -> list[tuple[float, tuple[float, float, float], float]]:
    """``[(area m², unit normal in the brightness frame, albedo)]``; a box-wing's wings face the Sun."""
    if shape == "plate":
        return [(10.0, (0.0, 0.0, -1.0), 0.5)]
    sun = (0.0, math.cos(beta), -math.sin(beta))
    box = [(2.0, n, 0.4) for n in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1))] + [(4.0, (0, 0, -1), 0.4)]
    return box + [(20.0, sun, 0.2), (20.0, tuple(-c for c in sun), 0.6)]


def lumos_part() -> list[dict]:
    import numpy as np  # heavy: lumos's own numpy, in lumos's venv
    import lumos.brdf.library as lib  # heavy: lumos-sat, only in its venv
    import lumos.calculator as calc  # heavy: lumos-sat, only in its venv
    import lumos.conversions as conv  # heavy: lumos-sat, only in its venv
    import lumos.geometry as geo  # heavy: lumos-sat, only in its venv

    out = []
    for g in geometries():
        h = g["h_km"] * 1e3
        ox, oy, oz, beta = calc.get_brightness_coords(g["sat_alt"], g["sat_az"], h, g["sun_alt"], g["sun_az"])
        ox, oy, oz, beta = float(ox), float(oy), float(oz), float(beta)
        surf = [geo.Surface(a, np.array(n, dtype=float), lib.LAMBERTIAN(alb)) for a, n, alb in surfaces(g["shape"], beta)]
        earth = lib.LAMBERTIAN(0.3)
        kw = dict(earth_panel_density=150, earth_brdf=earth)
        total = calc.get_intensity_satellite_frame(surf, h, beta, (ox, oy, oz), True, True, **kw)
        es = calc.get_intensity_satellite_frame(surf, h, beta, (ox, oy, oz), False, True, **kw)
        out.append(dict(g, beta=beta, observer_m=[ox, oy, oz], total=float(total), earthshine=float(es),
                        ab532=float(conv.intensity_to_ab_mag(total, clip=False))))
    return out


def cssat_part(rows: list[dict]) -> list[dict]:
    import numpy as np  # heavy: numpy, the cssat half only
    import torch  # heavy: torch, the cssat half only

    from cssat.optics.earthshine import earthshine_brightness  # heavy: imports torch
    from cssat.optics.passbands import ab_magnitude_at, magnitude  # heavy: imports torch
    from cssat.optics.photometry import facet_brightness  # heavy: imports torch
    from cssat.scene.mesh import Mesh  # heavy: imports numpy

    torch.set_num_threads(1)
    for r in rows:
        surf = surfaces(r["shape"], r["beta"])
        verts, faces, cd = [], [], []
        for k, (area, n, alb) in enumerate(surf):
            n = np.array(n, dtype=float)
            e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(n, e1)
            a = math.sqrt(area) / 2
            verts += [-a * e1 - a * e2, a * e1 - a * e2, a * e1 + a * e2, -a * e1 + a * e2]
            faces += [[4 * k, 4 * k + 1, 4 * k + 2], [4 * k, 4 * k + 2, 4 * k + 3]]
            cd += [alb, alb]
        mesh = Mesh(np.array(verts), np.array(faces), np.array(cd), np.zeros(len(cd)))
        sat = np.array([0.0, 0.0, (R_EARTH_M + r["h_km"] * 1e3) / 1e3])
        obs = np.array(r["observer_m"]) / 1e3
        sun_dir = np.array([0.0, math.cos(r["beta"]), -math.sin(r["beta"])])
        v = obs - sat
        rng = np.linalg.norm(v)
        sun = facet_brightness(mesh, sun_dir[None], (v / rng)[None], range_km=rng, sun_range_km=1.496e8).sum()
        es = earthshine_brightness(mesh, sat, sat + 1e12 * sun_dir, obs, earth_radius_km=R_EARTH_M / 1e3,
                                   n_theta=48, n_phi=96).sum()
        tot = float(sun + es)
        r.update(c_total=tot, c_earthshine=float(es), c_ab532=float(ab_magnitude_at(tot, 532.0, "bolometric")),
                 c_V=float(magnitude(tot, "V", "Vega")), c_g=float(magnitude(tot, "g", "AB")))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lumos-part", action="store_true", help="run lumos's half (in lumos's venv), JSON to stdout")
    ap.add_argument("--lumos-python", default="/work/lumos-venv/bin/python")
    args = ap.parse_args()
    if args.lumos_part:
        json.dump(lumos_part(), sys.stdout)
        return
    res = subprocess.run([args.lumos_python, __file__, "--lumos-part"], capture_output=True, text=True, check=True)
    rows = cssat_part(json.loads(res.stdout))
    print(f"{'h km':>6} {'shape':>8} {'alt':>4} {'az':>4} {'sun':>4} {'beta°':>6} {'lumos AB532':>11} {'cssat AB532':>11} "
          f"{'Δ mag':>7} {'ES/total':>8} {'ES cssat/lumos':>14} {'cssat V':>8}")
    dm, ratio = [], []
    for r in rows:
        if r["total"] <= 0:  # lumos: the satellite in the Earth's shadow or below the observer's horizon
            print(f"{r['h_km']:6.0f} {r['shape']:>8} {r['sat_alt']:4.0f} {r['sat_az']:4.0f} {r['sun_alt']:4.0f} "
                  f"{math.degrees(r['beta']):6.1f}  (lumos: 0, in the Earth's shadow; cssat sunlight "
                  f"{r['c_total'] - r['c_earthshine']:.3g}, earthshine {r['c_earthshine']:.3g} W/m²)")
            continue
        d = r["c_ab532"] - r["ab532"]
        q = r["c_earthshine"] / r["earthshine"] if r["earthshine"] > 0 else float("nan")
        dm.append(abs(d))
        if r["earthshine"] > 0:
            ratio.append(q)
        print(f"{r['h_km']:6.0f} {r['shape']:>8} {r['sat_alt']:4.0f} {r['sat_az']:4.0f} {r['sun_alt']:4.0f} "
              f"{math.degrees(r['beta']):6.1f} {r['ab532']:11.4f} {r['c_ab532']:11.4f} {d:+7.4f} "
              f"{r['earthshine'] / r['total']:8.4f} {q:14.4f} {r['c_V']:8.3f}")
    print(f"cases {len(dm)} lit of {len(rows)}: max |Δ AB532| = {max(dm):.4f} mag; earthshine cssat/lumos in "
          f"[{min(ratio):.4f}, {max(ratio):.4f}], median {sorted(ratio)[len(ratio) // 2]:.4f}")


if __name__ == "__main__":
    main()
