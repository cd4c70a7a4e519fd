"""Benchmark: cssat's GPU path (``device=cuda``) against its CPU path, in one run on one machine.

Each case runs the same call on CPU tensors (numba kernels where cssat has them, ``--threads``
threads) and on CUDA tensors (the torch paths), checks that both give the same answer, and prints
the median seconds of ``--repeats`` runs and the CPU/GPU ratio:

(a) ``batch_omp``: 4,096 signals, a unit-norm Gaussian dictionary 3,277 × 4,096, K = 32 (the shape
    of the paper's Simulation 3), float32 — the supports compared;
(b) ``batch_omp``: one signal over ΦΨ 13,225 × 16,384 (Simulation 1 at 128²), K = 2,000, float32;
(c) ``render``: 4,096 views of the TESS-like model at 64², float32 — the light curves compared;
(d) ``ksvd_denoise``: a 128² image at σ = 0.05, float32 — the PSNRs compared;
(e) the experiments ``sim1`` and ``lightcurve`` at their default (paper) sizes through
    ``run_experiment`` with ``device=cuda`` and ``device=cpu`` — their PSNRs compared.

GPU timings synchronise the device before the clock stops (``torch.cuda.synchronize``) and each
case is run once untimed first (CUDA context, kernels' first launch, numba's JIT). Run from the
repository root on a machine with CUDA::

    python benchmarks/gpu.py --threads 16 --repeats 3
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import numpy as np
import torch


def timed(fn, repeats: int, cuda: bool):
    """``(median seconds, all seconds, last result)``, the device synchronised around each run."""
    fn()  # warm-up
    times, out = [], None
    for _ in range(repeats):
        if cuda:
            torch.cuda.synchronize()
        t = time.perf_counter()
        out = fn()
        if cuda:
            torch.cuda.synchronize()
        times.append(time.perf_counter() - t)
    return statistics.median(times), times, out


def row(name: str, cpu, gpu, agree: str) -> None:
    print(f"| {name} | {cpu[0]:.3f} ({', '.join(f'{t:.3f}' for t in cpu[1])}) | "
          f"{gpu[0]:.3f} ({', '.join(f'{t:.3f}' for t in gpu[1])}) | {cpu[0] / gpu[0]:.1f}× | {agree} |", flush=True)


def case_omp_batch(repeats: int) -> None:
    from cssat.sparse import batch_omp

    rng = np.random.default_rng(0)
    D = rng.standard_normal((3277, 4096)).astype(np.float32)
    D /= np.linalg.norm(D, axis=0)
    X = np.zeros((4096, 4096), np.float32)
    for b in range(4096):
        X[b, rng.choice(4096, 48, replace=False)] = rng.standard_normal(48)
    Y = X @ D.T
    Y += 0.1 * np.linalg.norm(Y, axis=1, keepdims=True) / np.sqrt(3277) * rng.standard_normal(Y.shape).astype(np.float32)
    Dc, Yc = torch.from_numpy(D), torch.from_numpy(Y)
    Dg, Yg = Dc.cuda(), Yc.cuda()
    cpu = timed(lambda: batch_omp(Dc, Yc, n_nonzero_coefs=32), repeats, False)
    gpu = timed(lambda: batch_omp(Dg, Yg, n_nonzero_coefs=32), repeats, True)
    same = float(((cpu[2] != 0) == (gpu[2].cpu() != 0)).all(1).float().mean())
    row("(a) batch_omp 4,096 × (3,277 × 4,096), K 32, float32", cpu, gpu, f"supports equal {same:.1%}")


def case_omp_one(repeats: int) -> None:
    from cssat.sparse import GaussianSensing, batch_omp, sensing_dictionary

    op = GaussianSensing(13225, 16384, seed=0, dtype=torch.float32)
    A = sensing_dictionary(op, (128, 128))
    x = torch.zeros(16384, dtype=torch.float32)
    x[torch.randperm(16384, generator=torch.Generator().manual_seed(1))[:1500]] = torch.randn(1500, dtype=torch.float32)
    y = (A @ x)[None]
    Ag, yg = A.cuda(), y.cuda()
    cpu = timed(lambda: batch_omp(A, y, n_nonzero_coefs=2000), repeats, False)
    gpu = timed(lambda: batch_omp(Ag, yg, n_nonzero_coefs=2000), repeats, True)
    err = float((cpu[2] - gpu[2].cpu()).norm() / cpu[2].norm())
    row("(b) batch_omp 1 × (13,225 × 16,384), K 2,000, float32", cpu, gpu, f"relative difference {err:.1e}")


def case_render(repeats: int) -> None:
    from cssat.optics import render
    from cssat.scene import tess_like

    mesh = tess_like()
    g = torch.Generator().manual_seed(1)
    sun = torch.nn.functional.normalize(torch.randn(4096, 3, generator=g, dtype=torch.float64), dim=1)
    obs = torch.nn.functional.normalize(sun + 0.3 * torch.randn(4096, 3, generator=g, dtype=torch.float64), dim=1)
    cpu = timed(lambda: render(mesh, sun, obs, 64, progress=False), repeats, False)
    gpu = timed(lambda: render(mesh, sun.cuda(), obs.cuda(), 64, progress=False), repeats, True)
    a, b = cpu[2].double().sum((1, 2)), gpu[2].cpu().double().sum((1, 2))
    err = float(((a - b).abs() / a.abs().clamp_min(1e-30)).max())
    row("(c) render 4,096 views of tess_like at 64², float32", cpu, gpu, f"light curves to {err:.1e}")


def case_ksvd(repeats: int) -> None:
    from skimage import data

    from cssat.metrics import psnr
    from cssat.sparse import ksvd_denoise

    clean = torch.from_numpy(data.camera()[::4, ::4].astype(np.float32) / 255.0)
    noisy = clean + torch.from_numpy(np.random.default_rng(0).normal(0, 0.05, clean.shape).astype(np.float32))
    cpu = timed(lambda: ksvd_denoise(noisy, 0.05), repeats, False)
    gpu = timed(lambda: ksvd_denoise(noisy.cuda(), 0.05), repeats, True)
    pc, pg = psnr(clean, cpu[2], data_range=1.0), psnr(clean, gpu[2].cpu(), data_range=1.0)
    row("(d) ksvd_denoise 128², σ 0.05, float32", cpu, gpu, f"PSNR {pc:.2f} / {pg:.2f} dB")


def case_experiments(threads: int) -> None:
    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    for name in ("sim1", "lightcurve"):
        res = {}
        for dev in ("cpu", "cuda"):
            with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
                cfg = compose(config_name="config", overrides=[f"experiment={name}", f"device={dev}", f"threads={threads}"])
            with tempfile.TemporaryDirectory() as d:
                t = time.perf_counter()
                out = run_experiment(cfg, d)
                res[dev] = (time.perf_counter() - t, out)
        (tc, oc), (tg, og) = res["cpu"], res["cuda"]
        agree = f"PSNR {oc.get('psnr', float('nan')):.2f} / {og.get('psnr', float('nan')):.2f} dB" \
            if isinstance(oc.get("psnr"), float) else f"status {oc.get('status')} / {og.get('status')}"
        row(f"(e) `cssat experiment={name}` (one run each)", (tc, [tc]), (tg, [tg]), agree)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--threads", type=int, default=16)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--cases", default="abcde", help="a subset of 'abcde'")
    args = p.parse_args()
    if not torch.cuda.is_available():
        raise SystemExit("benchmarks/gpu.py needs CUDA (torch.cuda.is_available() is False)")
    torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, {torch.cuda.get_device_name()}, CPU threads {args.threads}")
    print("| case | CPU s (runs) | GPU s (runs) | CPU/GPU | agreement |\n|---|---:|---:|---:|---|")
    for c, fn in zip("abcd", (case_omp_batch, case_omp_one, case_render, case_ksvd)):
        if c in args.cases:
            fn(args.repeats)
    if "e" in args.cases:
        case_experiments(args.threads)


if __name__ == "__main__":
    main()
