"""Benchmark: light-curve inversion (issue 24).

1. **Shape from an ideal light curve**: 1,000 random Sun/observer directions (uniform on the
   sphere, independent), Lambert, no noise, no shadows, on the convex hulls of the shipped
   meshes (``astra_like``, ``tess_like``, ``../shared/models/tess.obj`` when present) and of
   procedural box-wing models of varied proportions; the EGI by NNLS on a Fibonacci grid of
   ``K`` normals with the closure constraint, the convex shape by Little's program, scored by
   the volume IoU with the true hull (scaled to the same volume, centroids aligned — both in the
   body frame, which is known here). For reference: the hull's own facets snapped to the
   grid's nearest normals (the grid's floor) through the same Minkowski step.
2. **Speed**: one EGI solve, T = 2,000 samples × K = 1,000 normals, cssat's ``recover_egi``
   (nnls, nnomp, l1, tv) beside scipy's ``nnls`` called directly on the same problem.
3. **Minkowski** (``minkowski``: Newton on Little's program) on the EGIs of convex hulls of
   points on an ellipsoid, 50 to 6,000 facets: time, steps, the facets' area error.
4. **A smooth EGI** (a 2 × 1 × 0.6 ellipsoid's: area per normal = 1/Gaussian curvature,
   analytic), T = 2,000 noisy samples (0.3 % of the mean flux) on K = 1,000 normals: NNLS against
   ℓ1 and TV with λ by the discrepancy principle — the EGI's relative error, χ²/T, time.

Times are medians of ``--repeats`` runs. Run from the repository root::

    python benchmarks/inversion.py --threads 2 --repeats 3
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from _timing import median_time


def _hulls():
    import trimesh

    from cssat.scene import box, get_model, load_mesh, merge, panel

    out = {name: get_model(name).vertices for name in ("astra_like", "tess_like")}
    shared = Path(__file__).resolve().parents[1].parent / "shared" / "models" / "tess.obj"
    if shared.is_file():
        out["tess.obj"] = load_mesh(str(shared), scale=1.0).vertices
    # box-wings: a bus (a × b × c) and two wings of span s, chord w (panels in the y–z plane)
    for a, b, c, s, w in ((2.6, 2.4, 3.6, 10.0, 2.4), (1.0, 1.0, 1.0, 3.0, 1.0), (2.0, 1.0, 4.0, 6.0, 3.0),
                          (3.0, 3.0, 1.5, 2.0, 1.0), (1.5, 2.5, 2.0, 12.0, 0.8)):
        parts = [box((a, b, c))]
        for side in (1, -1):
            y0 = b / 2 if side > 0 else -(b / 2 + s)
            parts.append(panel((0, s, 0), (0, 0, w), (0, y0, -w / 2)))
        out[f"box_wing {a}x{b}x{c} s{s} w{w}"] = merge(parts).vertices
    return {k: trimesh.convex.convex_hull(v) for k, v in out.items()}


def _views(n, rng):
    from cssat.scene.attitude import random_unit_vectors

    return random_unit_vectors(n, rng), random_unit_vectors(n, rng)


def shape_table(K_list, n_views=1000, seed=0):
    from cssat.inversion import convex_iou, fibonacci_sphere, invert_convex, minkowski

    rng = np.random.default_rng(seed)
    rows = []
    for name, hull in _hulls().items():
        S, O = _views(n_views, rng)
        N, A = np.asarray(hull.face_normals), np.asarray(hull.area_faces)
        y = (A / np.pi * np.clip(S @ N.T, 0, None) * np.clip(O @ N.T, 0, None)).sum(1)  # brute force, independent of G
        row = {"model": name, "facets": len(A)}
        for K in K_list:
            res = invert_convex(y, S, O, n_normals=K, closure=1.0)
            row[f"iou_{K}"] = convex_iou(hull, res.mesh)
            grid = fibonacci_sphere(K).numpy()  # the floor: the hull's own facets snapped to the grid
            snap = np.bincount(np.argmax(N @ grid.T, 1), weights=A, minlength=K)
            row[f"snap_{K}"] = convex_iou(hull, minkowski(grid[snap > 0], snap[snap > 0])[0])
        rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--skip-shapes", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from scipy.optimize import nnls

    from cssat.inversion import egi_operator, fibonacci_sphere, recover_egi

    if not args.skip_shapes:
        Ks = (1000, 4000)
        print("1. shape from 1,000 ideal random views (Lambert, no noise): volume IoU with the true hull")
        print(f"{'model':38s} {'facets':>6s} " + " ".join(f"{'IoU K=' + str(k):>11s} {'grid floor':>10s}" for k in Ks))
        for r in shape_table(Ks):
            print(f"{r['model']:38s} {r['facets']:6d} " + " ".join(f"{r[f'iou_{k}']:11.3f} {r[f'snap_{k}']:10.3f}" for k in Ks))

    rng = np.random.default_rng(1)
    S, O = _views(2000, rng)
    N = fibonacci_sphere(1000)
    G = egi_operator(S, O, N)
    a = np.zeros(1000)
    a[rng.choice(1000, 12, replace=False)] = rng.uniform(1, 5, 12)
    Gm = G.matrix().numpy()
    y = Gm @ a + 1e-3 * rng.standard_normal(2000)
    print("\n2. one EGI solve, T = 2,000 x K = 1,000 (12-sparse EGI, noise 1e-3)")
    t_peer = median_time(lambda: nnls(Gm, y, maxiter=50000), args.repeats)[0]
    print(f"   scipy.optimize.nnls (the peer)          {t_peer:7.3f} s")
    for method in ("nnls", "nnomp", "l1", "tv"):
        t, _, (got, info) = median_time(lambda: recover_egi(G, y, method=method, sigma=1e-3), args.repeats)
        err = np.linalg.norm(got - a) / np.linalg.norm(a)
        print(f"   cssat recover_egi(method={method!r:7s})     {t:7.3f} s  ratio {t / t_peer:5.2f}  "
              f"relative error {err:.2e}, {info['n_nonzero']} non-zero")

    import trimesh

    from cssat.inversion import minkowski

    print("\n3. Minkowski: convex hulls of points on a 2 x 1 x 0.6 ellipsoid, from their own EGIs")
    for n in (30, 300, 1000, 3000):
        p = np.random.default_rng(9).normal(size=(n, 3))
        hull = trimesh.convex.convex_hull(p / np.linalg.norm(p, axis=1, keepdims=True) * [2.0, 1.0, 0.6])
        Nh, Ah = np.asarray(hull.face_normals), np.asarray(hull.area_faces)
        t, _, (mesh, info) = median_time(lambda: minkowski(Nh, Ah), args.repeats)
        print(f"   {len(Ah):5d} facets  {t:7.3f} s  {info['iterations']:3d} steps  area error {info['area_error']:.1e}  "
              f"volume {mesh.volume / hull.volume:.9f} of the truth's")

    print("\n4. a smooth EGI (ellipsoid 2 x 1 x 0.6), T = 2,000 (noise 0.3 % of the mean), K = 1,000")
    rng = np.random.default_rng(3)
    S, O = _views(2000, rng)
    Ne = fibonacci_sphere(1000)
    ax = np.array([2.0, 1.0, 0.6])
    truth = ax.prod() ** 2 * ((Ne.numpy() ** 2 / ax ** 2).sum(1)) ** 2 * 4 * np.pi / 1000
    Ge = egi_operator(S, O, Ne)
    y0 = Ge.matrix().numpy() @ truth
    sig = 0.003 * np.abs(y0).mean()
    ye = y0 + sig * rng.standard_normal(len(y0))
    for method, lam in (("nnls", None), ("l1", "discrepancy"), ("tv", "discrepancy")):
        kw = {} if lam is None else {"lam": lam}
        t, _, (got, info) = median_time(lambda: recover_egi(Ge, ye, method=method, sigma=sig, **kw), args.repeats)
        print(f"   {method:5s} {str(lam or ''):12s} {t:7.3f} s  EGI error {np.linalg.norm(got - truth) / np.linalg.norm(truth):.3f}  "
              f"chi2/T {info['chi2'] / len(ye):.3f}" + (f"  lam {info['solver_lam']:.2e}" if lam else ""))


if __name__ == "__main__":
    main()
