"""Benchmark: loading reference images through a torch DataLoader.

256 items of ``ReferenceImages`` (the TESS-like model at 64², the size of the issue's report),
timed four ways in the same run:

* ``batch``: ``ds.batch(0, 256)``, one vectorised render;
* ``DataLoader`` with ``__getitems__`` (cssat's default): one render per batch of 256, shuffled;
* ``DataLoader`` item by item: the same dataset with ``__getitems__`` hidden, i.e. what a
  ``Dataset`` without it costs (256 single renders);
* pairs ``(x, y)`` under a Gaussian measurement (m = 1024) through the DataLoader.

Run from the repository root::

    python benchmarks/datasets.py --threads 2 --repeats 5
"""

from __future__ import annotations

import argparse

import torch
from _timing import median_time
from torch.utils.data import DataLoader


class ItemByItem(torch.utils.data.Dataset):
    """The same items, without ``__getitems__``: the DataLoader fetches them one at a time."""

    def __init__(self, ds):
        self.ds = ds

    def __len__(self):
        return len(self.ds)

    def __getitem__(self, i):
        return self.ds[i]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--n", type=int, default=256)
    ap.add_argument("--size", type=int, default=64)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)

    from cssat.data import ReferenceImages
    from cssat.physics import GaussianAtmosphere, GaussianNoise, Measurement
    from cssat.scene import tess_like

    mesh, n, size = tess_like(), args.n, args.size
    ds = ReferenceImages(mesh, size, n, seed=0, noise=0.01)
    pairs = ReferenceImages(mesh, size, n, seed=0, noise=0.01, channel_axis=True,
                            measurement=Measurement(GaussianAtmosphere().operator(1024, size * size, seed=1),
                                                    GaussianNoise(relative=0.01)))

    def load(d):
        return list(DataLoader(d, batch_size=n, shuffle=True, generator=torch.Generator().manual_seed(0)))

    ds.batch(0, 8)  # compile the numba kernels outside the timings
    t_batch, _, ref = median_time(lambda: ds.batch(0, n), args.repeats)
    t_loader, _, got = median_time(lambda: load(ds), args.repeats)
    t_items, _, _ = median_time(lambda: load(ItemByItem(ds)), max(1, args.repeats // 2))
    t_pairs, _, _ = median_time(lambda: load(pairs), args.repeats)
    assert sorted(float(v) for v in got[0].sum((1, 2))) == sorted(float(v) for v in ref.sum((1, 2)))
    print(f"{n} items of {size}², threads={args.threads}, median of {args.repeats}")
    print(f"  ds.batch(0, {n})                     {t_batch:7.3f} s")
    print(f"  DataLoader (__getitems__)           {t_loader:7.3f} s   {t_loader / t_batch:5.2f}× batch")
    print(f"  DataLoader item by item             {t_items:7.3f} s   {t_items / t_batch:5.2f}× batch, "
          f"{t_items / t_loader:5.1f}× __getitems__")
    print(f"  DataLoader (x, y) pairs, m = 1024   {t_pairs:7.3f} s   {t_pairs / t_batch:5.2f}× batch")


if __name__ == "__main__":
    main()
