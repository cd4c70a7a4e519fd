"""Benchmark: light curves with shadows and batched renders, against trimesh-based peers.

1. The default scenario's light curve (1437 steps, Astra-like 4,028-facet model, self- and
   observer-shadowing): cssat (one batched Embree query for all steps) against trimesh's
   pure-Python ray engine (``ray_triangle``) on the same rays, timed on a subset of steps and
   scaled to 1437.
2. 16,384 renders at 128² of random Sun/view directions (the size of Simulation 2's reference set),
   facet brightness with shadows included: cssat's batched z-buffer against ray-traced images
   (one Embree ray per pixel through trimesh, first hit, flat shading), timed on a subset and scaled.
3. The same renders for the real TESS mesh (``../shared/models/tess.obj``, 16,161 facets), if present.

Run from the repository root::

    python benchmarks/scene.py --threads 2 --repeats 3
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch
from _timing import median_time


def raytraced_images(mesh, brightness, obs, size, fov):
    """Peer renderer: one ray per pixel (trimesh + Embree), the first facet hit gets
    brightness / (its pixel count): the paper's flat shading without a z-buffer."""
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    from cssat.optics import image_basis

    inter = RayMeshIntersector(mesh.to_trimesh(), scale_to_box=False)
    V = torch.as_tensor(obs, dtype=torch.float64)
    ex, ey = image_basis(V)
    c = (np.arange(size) + 0.5) / size * fov - fov / 2
    gx, gy = np.meshgrid(c, c[::-1])
    imgs = np.zeros((len(obs), size, size))
    for t in range(len(obs)):
        origins = gx.reshape(-1, 1) * ex[t].numpy() + gy.reshape(-1, 1) * ey[t].numpy() + 2 * fov * V[t].numpy()
        dirs = np.tile(-V[t].numpy(), (size * size, 1))
        tri = inter.intersects_first(origins, dirs)
        hit = tri >= 0
        cnt = np.bincount(tri[hit], minlength=len(mesh))
        vals = np.zeros(size * size)
        b = brightness[t].numpy()
        vals[hit] = b[tri[hit]] / cnt[tri[hit]]
        imgs[t] = vals.reshape(size, size)
    return imgs


def bench_light_curve(args):
    from cssat.optics import shadow_mask, simulate_light_curve
    from cssat.scene import astra_like, make_scenario, nadir_pointing_frame, to_body

    mesh, sc = astra_like(), make_scenario()
    simulate_light_curve(mesh, sc)  # warm-up (ephemeris, BVH code paths)
    t_ours, ts, lc = median_time(lambda: simulate_light_curve(mesh, sc), args.repeats)
    frame = nadir_pointing_frame(sc.r_sat, sc.v_sat)
    sun, obs = to_body(frame, sc.sun_dir), to_body(frame, sc.obs_dir)
    sub = np.linspace(0, len(sc) - 1, args.peer_steps).round().astype(int)
    t0 = time.perf_counter()
    vis_peer = shadow_mask(mesh, sun[sub], obs[sub], engine="triangle")
    t_peer = (time.perf_counter() - t0) * len(sc) / len(sub)
    vis_ours = shadow_mask(mesh, sun[sub], obs[sub], engine="embree")
    agree = float((vis_peer == vis_ours).double().mean())
    print("\n1. light curve, 1437 steps, Astra-like (4,028 facets), shadows on")
    print("| method | median s | runs (s) | time / cssat |")
    print("|---|---|---|---|")
    print(f"| cssat `simulate_light_curve` (batched Embree rays) | {t_ours:.2f} | {', '.join(f'{v:.2f}' for v in ts)} | 1.0× |")
    print(f"| trimesh `ray_triangle` on the same rays ({len(sub)} steps, ×{len(sc) / len(sub):.0f}) | {t_peer:.1f} | | {t_peer / t_ours:.0f}× |")
    print(f"visibility agreement between the engines on those steps: {agree:.5f}")


def bench_renders(args, mesh, label):
    from cssat.optics import default_fov, facet_brightness, render
    from cssat.scene import random_unit_vectors

    rng = np.random.default_rng(0)
    n = args.renders
    sun, obs = random_unit_vectors(n, rng), random_unit_vectors(n, rng)
    fov = default_fov(mesh)

    t0 = time.perf_counter()
    b = facet_brightness(mesh, sun, obs, shadows=True)
    t_shadow = time.perf_counter() - t0
    t_ours, ts, img = median_time(lambda: render(mesh, sun, obs, 128, brightness=b, fov_m=fov), args.repeats)
    k = args.peer_renders
    t0 = time.perf_counter()
    peer = raytraced_images(mesh, b[:k].double(), obs[:k], 128, fov)
    t_peer = (time.perf_counter() - t0) * n / k
    flux_err = float(((img.double().sum((1, 2)) - b.double().sum(1)).abs() / b.double().sum(1).clamp_min(1e-30)).max())
    same_px = float(((torch.from_numpy(peer) > 0) == (img[:k] > 0)).double().mean())
    print(f"\n{label}: {n} renders at 128²")
    print(f"facet brightness with shadows (Embree, both methods use it): {t_shadow:.1f} s")
    print("| images from the facet brightness | median s | runs (s) | time / cssat |")
    print("|---|---|---|---|")
    print(f"| cssat `render` (batched z-buffer) | {t_ours:.1f} | {', '.join(f'{v:.1f}' for v in ts)} | 1.0× |")
    print(f"| per-pixel ray tracing (trimesh + Embree), {k} views ×{n / k:.0f} | {t_peer:.1f} | | {t_peer / t_ours:.1f}× |")
    print(f"total for cssat: {t_shadow + t_ours:.1f} s; max |pixel sum − light curve| / light curve = {flux_err:.1e}; "
          f"lit-pixel masks agree on {same_px:.4f} of pixels")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--renders", type=int, default=16384)
    p.add_argument("--peer-steps", type=int, default=15)
    p.add_argument("--peer-renders", type=int, default=64)
    p.add_argument("--parts", default="123")
    args = p.parse_args(argv)
    torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, threads {args.threads}")
    if "1" in args.parts:
        bench_light_curve(args)
    if "2" in args.parts:
        from cssat.scene import astra_like

        bench_renders(args, astra_like(), "2. Astra-like model (4,028 facets)")
    tess = Path(__file__).resolve().parents[2] / "shared" / "models" / "tess.obj"
    if "3" in args.parts and tess.exists():
        from cssat.scene import load_mesh

        bench_renders(args, load_mesh(tess), f"3. TESS mesh {tess.name} (16,161 facets)")


if __name__ == "__main__":
    sys.exit(main())
