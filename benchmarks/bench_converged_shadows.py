"""Are the shadowed light curves converged? The truths of ``bench_shadow_fit.py`` and the finer
parametric family at each truth's own parameters, against a truth rendered with its shadows
resolved below a facet.

    PYTHONPATH=$PWD python benchmarks/bench_converged_shadows.py                       # the three meshes
    PYTHONPATH=$PWD python benchmarks/bench_converged_shadows.py --meshes b702_like --reference 0.1

A centroid ray makes a facet wholly lit or dark, so a mesh's light curve carries steps of its
facets' size where a shadow edge crosses them. Here each truth (``bench_shadow_fit.truth``, uniform
albedo 0.3, Lambertian; the benchmark's geometry and 1.5 % floor, σ = 1.5 % of the flux + 0.15 %
of its median) is rendered with its shadows from rays ``r`` metres apart on every facet
(:func:`cssat.optics.photometry.shadow_mask`'s ``resolution_m``) for ``r`` = 0.4, 0.2 and the
``--reference`` (default 0.1 m), and compared, on the held-out night in units of σ (rms), with the
reference; then the finer family at the truth's parameters by construction (``Truth.fine``: the
family leaves out the b702's tower dish and engine, the spacebus's omni mast, the Astra-like's
plate) is compared with the same reference: its centroid ray cast at 4, 8, 16 cells a face, its
soft shadows at τ = 1 cm, and its cast at 4 cells resolved to 0.4 and 0.2 m. Prints one markdown
table; one thread; ~5 CPU-min.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

MESHES = ("astra_defunct", "b702_like", "spacebus_like")


def rms_sigma(a: np.ndarray, b: np.ndarray, sigma: np.ndarray) -> float:
    """The rms of ``(a − b) / sigma``."""
    return float(np.sqrt(np.mean(((a - b) / sigma) ** 2)))


def rows(name: str, reference: float) -> list[tuple[str, float, float]]:
    """``(what, rms in σ against the reference truth, CPU s)`` for one truth (module docstring)."""
    import torch

    import bench_shadow_fit as B
    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility
    from cssat.inversion.soft_shadow import soft_visibility
    from cssat.optics.lightcurve import simulate_light_curve

    geo = B.geometry()
    held = geo.night == 2
    tr = B.truth(name, "uniform")

    def truth_curve(res):
        c0 = time.process_time()
        kw = {} if res is None else {"shadow_resolution_m": res}
        lc = simulate_light_curve(tr.mesh, geo.scenario, shadows=True, attitude=geo.attitude, **kw)
        return (lc.flux.numpy()[geo.keep] * geo.unit)[held], time.process_time() - c0

    ref, cpu_ref = truth_curve(reference)
    sigma = 0.015 * ref + 0.0015 * float(np.median(ref))
    out = []
    for res in (None, 0.4, 0.2):
        c, cpu = truth_curve(res)
        out.append((f"truth, {'one ray a facet' if res is None else f'rays {res} m apart'} ({len(tr.mesh.faces)} facets)",
                    rms_sigma(c, ref, sigma), cpu))
    out.append((f"truth, rays {reference} m apart (the reference)", 0.0, cpu_ref))
    parts, params = tr.fine
    p = np.array(list(params.values()))
    S, V = geo.sun[held], geo.observer[held]
    for div, how, res in ((4, "cast", None), (8, "cast", None), (16, "cast", None), (4, "soft", None),
                          (16, "soft", None), (4, "cast", 0.4), (4, "cast", 0.2)):
        kw = B._family_kw(0, div, parts)
        c0 = time.process_time()
        with torch.no_grad():
            vis = soft_visibility(p, S, V, tau=0.01, **kw) if how == "soft" else \
                box_wing_visibility(p, S, V, resolution_m=res, **kw)
            m = box_wing_light_curve(torch.as_tensor(p), S, V, vis, range_km=1e-3, irradiance=1.0, **kw).numpy()
        label = f"family, {div} cells a face, " + ("soft shadows τ 1 cm" if how == "soft" else
                                                    "one ray a cell" if res is None else f"rays {res} m apart")
        out.append((label, rms_sigma(m, ref, sigma), time.process_time() - c0))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--meshes", nargs="+", default=list(MESHES), choices=MESHES)
    ap.add_argument("--reference", type=float, default=0.1, help="the reference truth's ray spacing (m)")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    print("| truth | light curve | held-out rms from the reference truth (σ) | CPU s |")
    print("|---|---|---:|---:|")
    for name in args.meshes:
        for what, r, cpu in rows(name, args.reference):
            print(f"| {name} | {what} | {r:.3f} | {cpu:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
