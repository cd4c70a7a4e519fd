"""torch ``Dataset``s of rendered reference images and simulated light curves.

Every item is a pure function of ``(seed, index)``: its random numbers come from generators seeded
by that pair alone, so an item is the same whatever the order, the batch or the number of
DataLoader workers.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.utils.data import Dataset

from cssat.scene.mesh import Mesh

__all__ = ["ReferenceImages", "LightCurves", "item_rng"]


def item_rng(seed: int, index: int, stream: int = 0) -> np.random.Generator:
    """The generator of item ``index`` of a dataset with ``seed`` (``stream`` separates uses)."""
    return np.random.default_rng([int(seed), int(index), int(stream)])


class ReferenceImages(Dataset):
    """Reference images of a satellite (the paper's ``X_ref``): ``length`` renders of ``mesh`` at
    ``size × size`` under random Sun and view directions (uniform on the sphere), with optional
    white Gaussian noise of standard deviation ``noise`` (as a fraction of the image's maximum).

    Item ``i`` is a ``(size, size)`` float tensor; :meth:`batch` renders a range of items in one
    vectorised call and gives the same values. All images share the field of view ``fov_m``
    (default: the mesh's bounding sphere), hence the same scale. ``normalize`` divides each image
    by its maximum (before noise), so images lie in [0, 1].
    """

    def __init__(
        self,
        mesh: Mesh,
        size: int,
        length: int,
        seed: int = 0,
        noise: float = 0.0,
        fov_m: float | None = None,
        shadows: bool = True,
        normalize: bool = True,
        dtype: torch.dtype = torch.float32,
    ):
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"reference.size: must be a positive integer, got {size!r}")
        if isinstance(length, bool) or not isinstance(length, int) or length < 0:
            raise ValueError(f"reference.n: must be a non-negative integer, got {length!r}")
        if not noise >= 0:
            raise ValueError(f"reference.noise: must be >= 0, got {noise!r}")
        self.mesh, self.size, self.length, self.seed = mesh, size, length, int(seed)
        self.noise, self.fov_m, self.shadows, self.normalize, self.dtype = float(noise), fov_m, shadows, normalize, dtype

    def __len__(self) -> int:
        return self.length

    def directions(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """The Sun and view directions (body frame, unit) of item ``index``."""
        from cssat.scene.attitude import random_unit_vectors

        d = random_unit_vectors(2, item_rng(self.seed, index, 0))
        return d[0], d[1]

    def batch(self, start: int, stop: int) -> torch.Tensor:
        """Items ``start .. stop-1`` as one ``(stop - start, size, size)`` tensor."""
        from cssat.optics import render

        idx = range(start, stop)
        if not idx:
            return torch.zeros(0, self.size, self.size, dtype=self.dtype)
        if start < 0 or stop > self.length:
            raise IndexError(f"index range [{start}, {stop}) outside [0, {self.length})")
        dirs = [self.directions(i) for i in idx]
        sun = np.stack([d[0] for d in dirs])
        obs = np.stack([d[1] for d in dirs])
        img = render(self.mesh, sun, obs, self.size, fov_m=self.fov_m, shadows=self.shadows, dtype=torch.float64,
                     progress=False)
        if self.normalize:
            peak = img.amax((1, 2), keepdim=True)
            img = torch.where(peak > 0, img / torch.where(peak > 0, peak, torch.ones_like(peak)), img)
        if self.noise > 0:
            scale = img.amax((1, 2)) if not self.normalize else torch.ones(len(idx), dtype=img.dtype)
            for k, i in enumerate(idx):
                g = item_rng(self.seed, i, 1)
                img[k] += self.noise * float(scale[k]) * torch.from_numpy(g.standard_normal((self.size, self.size)))
        return img.to(self.dtype)

    def __getitem__(self, index: int) -> torch.Tensor:
        if index < 0:
            index += self.length
        if not 0 <= index < self.length:
            raise IndexError(f"index {index} outside [0, {self.length})")
        return self.batch(index, index + 1)[0]


class LightCurves(Dataset):
    """Light curves of one scenario seen through independent atmospheres.

    The geometry (``scenario``: orbit, Sun, observer, shadow) and the attitude are fixed; item
    ``i`` draws its own atmosphere and noise. Each item is a dict with ``times`` (``(T,)`` seconds
    from the first sample), ``clean`` (the atmosphere-free light curve, Eq. 10, W/m²) and
    ``curve``: the light curve measured through ``atmosphere`` (a :class:`cssat.physics.Atmosphere`;
    default the paper's Gaussian weights over the facets, Eq. 11; one over ``"pixels"`` weights
    the ``(T, size, size)`` renders, Eq. 12; ``None``: the clean curve) with ``noise``
    (a :class:`cssat.physics.NoiseModel`, default none). With ``images=True`` also the renders.
    """

    def __init__(self, mesh: Mesh, scenario, length: int, seed: int = 0, atmosphere="default",
                 noise=None, images: bool = False, size: int = 64, shadows: bool = True):
        from cssat.optics import simulate_light_curve
        from cssat.physics import Atmosphere, GaussianAtmosphere, NoiseModel

        if isinstance(atmosphere, str) and atmosphere == "default":
            atmosphere = GaussianAtmosphere(emitters="facets")
        if atmosphere is not None and not isinstance(atmosphere, Atmosphere):
            raise TypeError(f"atmosphere: expected a cssat.physics.Atmosphere or None, got {atmosphere!r}")
        if noise is not None and not isinstance(noise, NoiseModel):
            raise TypeError(f"noise: expected a cssat.physics.NoiseModel or None, got {noise!r}")
        self.mesh, self.scenario, self.length, self.seed = mesh, scenario, int(length), int(seed)
        self.atmosphere, self.noise, self.images, self.size = atmosphere, noise, images, size
        lc = simulate_light_curve(mesh, scenario, shadows=shadows)
        self.sun_body, self.obs_body = lc.sun, lc.observer
        self.facets = lc.facets  # (T, F)
        self.clean = lc.flux
        t = scenario.times
        self.times = torch.as_tensor((t - t[0]) / np.timedelta64(1, "s"), dtype=torch.float64)
        self._renders = None

    def __len__(self) -> int:
        return self.length

    def renders(self) -> torch.Tensor:
        """The ``(T, size, size)`` images of the scenario (rendered once, then kept)."""
        if self._renders is None:
            from cssat.optics import render

            self._renders = render(self.mesh, self.sun_body, self.obs_body, self.size,
                                   brightness=self.facets, dtype=torch.float64)
        return self._renders

    def __getitem__(self, index: int) -> dict:
        from cssat.physics import Measurement

        if not 0 <= index < self.length:
            raise IndexError(f"index {index} outside [0, {self.length})")
        seed = int(item_rng(self.seed, index, 2).integers(0, 2**62))
        item = {"times": self.times, "clean": self.clean}
        if self.atmosphere is None:
            gen = torch.Generator().manual_seed(seed + 1)
            item["curve"] = self.clean if self.noise is None else self.noise(self.clean, gen)
        else:
            frames = self.facets if self.atmosphere.emitters == "facets" else self.renders()
            n = frames[0].numel()
            op = self.atmosphere.operator(len(frames), n, seed=seed, dtype=frames.dtype)
            item["curve"] = Measurement(op, self.noise, seed=seed + 1).frames(frames)
        if self.images:
            item["images"] = self.renders()
        return item
