"""Training pairs for a learned reconstruction: reference images and their light curves.

``ReferenceImages`` renders a satellite under random Sun and view directions; with a
``measurement`` each item is ``(x (1, H, W), y (m,))``, the noise drawn from the item's own
generator, and a DataLoader batch is rendered in one vectorised call. A least-squares
baseline ``Φ⁺y`` is scored on one batch.

    python examples/training_pairs.py --size 32 --n 256
"""

import argparse

import numpy as np
import torch
from torch.utils.data import DataLoader

from cssat.data import ReferenceImages
from cssat.metrics import psnr
from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement
from cssat.scene import tess_like

ap = argparse.ArgumentParser()
ap.add_argument("--size", type=int, default=32)
ap.add_argument("--n", type=int, default=256)
ap.add_argument("--ratio", type=float, default=0.5)
args = ap.parse_args()

n = args.size
phi = GaussianAtmosphere().operator(round(args.ratio * n * n), n * n, seed=0)
pairs = ReferenceImages(tess_like(), n, args.n, seed=0, channel_axis=True,
                        measurement=Measurement(phi, GaussianNoise(relative=0.01)))
loader = DataLoader(pairs, batch_size=64, shuffle=True, generator=torch.Generator().manual_seed(0))
x, y = next(iter(loader))                                  # (64, 1, n, n), (64, m)
x_ls = phi.A_dagger(y).reshape(x.shape).clamp(0, 1)      # the minimum-norm least-squares images
lit = x.flatten(1).amax(1) > 0                            # a view of the unlit side is black
scores = psnr(x[lit], x_ls[lit], data_range=1.0)          # one PSNR per image of the batch
flat = x[lit].mean((1, 2, 3), keepdim=True).expand_as(x[lit])  # what the total flux alone gives
print(f"batch {tuple(x.shape)} -> light curves {tuple(y.shape)}; least squares on the {int(lit.sum())} lit "
      f"views: median PSNR {float(np.median(scores)):.2f} dB "
      f"(flat images: {float(np.median(psnr(x[lit], flat, data_range=1.0))):.2f} dB)")
