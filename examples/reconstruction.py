"""An image from its light curve: the paper's Simulation 1 in a dozen lines.

A target image, the paper's Gaussian atmosphere Φ (Eq. 15, N(0, 1/N) weights), 1 % sensor
noise, batch-OMP over the DCT (Eq. 5), sparse K-SVD denoising (Eq. 16–21), PSNR and SSIM, and
the figure with error maps.

    python examples/reconstruction.py --size 64 --ratio 0.5 --out reconstruction.png
"""

import argparse

import torch

from cssat.data import load_target
from cssat.metrics import psnr, ssim
from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement
from cssat.plots import error_panels, image_panels, save_figure
from cssat.recon import OMP, SparseKSVD

ap = argparse.ArgumentParser()
ap.add_argument("--size", type=int, default=64, help="pixels per side")
ap.add_argument("--ratio", type=float, default=0.5, help="m / N, light-curve samples per pixel")
ap.add_argument("--out", default="reconstruction.png")
args = ap.parse_args()

n = args.size
x = torch.tensor(load_target("tess", n), dtype=torch.float32)       # (n, n) in [0, 1]
m = round(args.ratio * n * n)
phi = GaussianAtmosphere().operator(m, n * n, seed=0)                # Φ (m, N), row i from (seed, i)
meas = Measurement(phi, GaussianNoise(relative=0.01), seed=1)        # y = Φx + noise
y = meas(x)

x_hat, info = OMP()(meas.operator, y, (n, n))                        # K from m/N (README)
x_hat = x_hat.clamp(0, 1)
den, dinfo = SparseKSVD(n_iter=5, seed=0)(x_hat)
print(f"m = {m} ({args.ratio:.0%} of N = {n * n}), K = {info['solver_n_nonzero_coefs']}: "
      f"PSNR {psnr(x, x_hat, data_range=1.0):.2f} dB, SSIM {ssim(x, x_hat, data_range=1.0):.3f}; "
      f"denoised {psnr(x, den, data_range=1.0):.2f} dB")

fig = image_panels([(x, "truth"), (x_hat, "OMP"), (den, "denoised"),
                    (None, ""), *error_panels(x, [(x_hat, "OMP"), (den, "denoised")])], ncols=3)
save_figure(fig, args.out)
print("figure:", args.out)
