"""torch ``Dataset``s of rendered reference images and simulated light curves.

Every item is a pure function of ``(seed, index)``: its random numbers come from generators seeded
by that pair alone, so an item is the same whatever the order, the batch or the number of
DataLoader workers.
"""

from __future__ import annotations

import numbers
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch.utils.data import Dataset

from cssat._checks import FieldError, FieldTypeError
from cssat.optics import render, simulate_light_curve
from cssat.physics import Atmosphere, GaussianAtmosphere, Measurement, NoiseModel
from cssat.scene.attitude import random_unit_vectors
from cssat.scene.mesh import Mesh

if TYPE_CHECKING:
    from typing import Sequence

    from cssat.scene import Scenario


__all__ = ["ReferenceImages", "LightCurves", "item_rng"]


def check_index(index: Any, length: int) -> int:
    """``index`` as an item number in ``[0, length)`` (negative counts from the end); an index
    that is not an integer (``1.7``, ``True``, a string) is a TypeError, not truncated."""
    if isinstance(index, bool) or not isinstance(index, numbers.Integral):
        if not (hasattr(index, "ndim") and index.ndim == 0 and not getattr(index, "is_floating_point", lambda: True)()):
            raise TypeError(f"index: expected an integer, got {index!r}")
    index = int(index)
    if index < 0:
        index += length
    if not 0 <= index < length:
        raise IndexError(f"index {index} outside [0, {length})")
    return index


def item_rng(seed: int, index: int, stream: int = 0) -> np.random.Generator:
    """The generator of item ``index`` of a dataset with ``seed`` (``stream`` separates uses)."""
    return np.random.default_rng([int(seed), int(index), int(stream)])


class ReferenceImages(Dataset):
    """Reference images of a satellite (the paper's ``X_ref``): ``length`` renders of ``mesh`` at
    ``size × size`` under random Sun and view directions (uniform on the sphere), with optional
    white Gaussian noise of standard deviation ``noise`` (as a fraction of the image's maximum).

    Item ``i`` is a ``(size, size)`` float tensor (``(1, size, size)`` with ``channel_axis``, the
    ``(C, H, W)`` layout of deepinv and torchvision). With a ``measurement`` (a
    :class:`cssat.physics.Measurement` of ``size²`` pixels) an item is the training pair
    ``(x, y)``: the image and its light curve ``y = noise(Φx)``, the noise drawn from the item's
    own generator. :meth:`batch` renders a range of items in one vectorised call and
    ``__getitems__`` any list of them (what a ``DataLoader`` asks for), giving the same values as
    item by item (``y`` to the rounding of a batched ``Φx``). All images share the field of view ``fov_m`` (default: the mesh's bounding
    sphere), hence the same scale. ``normalize`` divides each image by its maximum (before
    noise), so images lie in [0, 1].

    ``resample=True`` draws fresh noise (the images' white noise and the light curves') in every
    epoch: call :meth:`set_epoch` at the start of each (as with torch's ``DistributedSampler``);
    item ``i`` of epoch ``e`` is a pure function of ``(seed, i, e)``, so training stays
    reproducible. The Sun and view directions of an item never change. Default: the same noise
    in every epoch.
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
        *,
        channel_axis: bool = False,
        measurement: Measurement | None = None,
        resample: bool = False,
    ):
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise FieldError("reference.size", f"must be a positive integer, got {size!r}")
        if isinstance(length, bool) or not isinstance(length, int) or length < 0:
            raise FieldError("reference.n", f"must be a non-negative integer, got {length!r}")
        if not noise >= 0:
            raise FieldError("reference.noise", f"must be >= 0, got {noise!r}")
        if measurement is not None:
            if not isinstance(measurement, Measurement):
                raise FieldTypeError("measurement", f"expected a cssat.physics.Measurement, got {type(measurement).__name__}")
            if measurement.shape[1] != size * size:
                raise FieldError("measurement", f"its operator takes {measurement.shape[1]} pixels, the images have "
                                 f"{size}² = {size * size}")
        self.mesh, self.size, self.length, self.seed = mesh, size, length, int(seed)
        self.noise, self.fov_m, self.shadows, self.normalize, self.dtype = float(noise), fov_m, shadows, normalize, dtype
        self.channel_axis, self.measurement = bool(channel_axis), measurement
        if not isinstance(resample, bool):
            raise FieldError("resample", f"expected true or false, got {resample!r}")
        self.resample, self.epoch = resample, 0

    def set_epoch(self, epoch: int) -> None:
        """The epoch whose noise the items draw (``resample=True``; ignored otherwise)."""
        if isinstance(epoch, bool) or not isinstance(epoch, (int, np.integer)) or epoch < 0:
            raise FieldError("epoch", f"expected an integer >= 0, got {epoch!r}")
        self.epoch = int(epoch)

    def _noise_rng(self, index: int, stream: int) -> np.random.Generator:
        """The generator of item ``index``'s noise ``stream`` (this epoch's, with ``resample``)."""
        if self.resample:
            return np.random.default_rng([self.seed, int(index), stream, self.epoch + 1])
        return item_rng(self.seed, index, stream)

    def __len__(self) -> int:
        return self.length

    def directions(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """The Sun and view directions (body frame, unit) of item ``index``."""
        d = random_unit_vectors(2, item_rng(self.seed, index, 0))
        return d[0], d[1]

    def _index(self, index: int) -> int:
        return check_index(index, self.length)

    def images(self, indices: Sequence[int]) -> torch.Tensor:
        """The images of ``indices`` (any order, repeats allowed) rendered in one vectorised
        call: ``(len(indices), size, size)`` (no channel axis)."""
        idx = [self._index(i) for i in indices]
        if not idx:
            return torch.zeros(0, self.size, self.size, dtype=self.dtype)
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
                g = self._noise_rng(i, 1)
                img[k] += self.noise * float(scale[k]) * torch.from_numpy(g.standard_normal((self.size, self.size)))
        return img.to(self.dtype)

    def light_curves(self, indices: Sequence[int], images: torch.Tensor) -> torch.Tensor:
        """``y = noise(Φx)`` of ``images`` ``(B, size, size)`` of items ``indices`` under the
        measurement: ``Φx`` batched, the noise of each item from its own generator (stream 3), so
        a pair is the same in any batch. ``(B, m)``."""
        meas = self.measurement
        flat = images.reshape(len(images), -1)
        y = meas.A(flat)
        flux = flat.sum(-1)
        for k, i in enumerate(indices):
            gen = torch.Generator().manual_seed(int(self._noise_rng(self._index(i), 3).integers(0, 2**62)))
            y[k] = meas.add_noise(y[k], gen, flux=flux[k])
        return y

    def _stacked(self, indices: Sequence[int]) -> tuple[torch.Tensor, torch.Tensor | None]:
        """``(x, y)`` of ``indices`` stacked: the images in one vectorised render (with the channel
        axis when asked), their light curves (``None`` without a measurement)."""
        x = self.images(indices)
        y = self.light_curves(indices, x) if self.measurement is not None else None
        return (x[:, None] if self.channel_axis else x), y

    def __getitems__(self, indices: Sequence[int]) -> list:
        """Items ``indices`` as a list, rendered (and measured) in one vectorised call: what a
        ``DataLoader`` fetches for a batch, so loading is as fast as :meth:`batch`."""
        x, y = self._stacked(indices)
        return list(x.unbind(0)) if y is None else list(zip(x.unbind(0), y.unbind(0)))

    def batch(self, start: int, stop: int) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        """Items ``start .. stop-1`` stacked: ``(B, size, size)`` (``(B, 1, size, size)`` with
        ``channel_axis``), or the pair ``(x, y (B, m))`` with a ``measurement``."""
        if start < 0 or stop > self.length or start > stop:
            raise IndexError(f"index range [{start}, {stop}) outside [0, {self.length})")
        x, y = self._stacked(range(start, stop))
        return x if y is None else (x, y)

    def __getitem__(self, index: int) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        return self.__getitems__([index])[0]


class LightCurves(Dataset):
    """Light curves of one scenario seen through independent atmospheres.

    The geometry (``scenario``: orbit, Sun, observer, shadow) and the attitude are fixed; item
    ``i`` draws its own atmosphere and noise. Each item is a dict with ``times`` (``(T,)`` seconds
    from the first sample), ``clean`` (the atmosphere-free light curve, Eq. 10, W/m²) and
    ``curve``: the light curve measured through ``atmosphere`` (a :class:`cssat.physics.Atmosphere`;
    default the paper's Gaussian weights over the facets, Eq. 11; one over ``"pixels"`` weights
    the ``(T, size, size)`` renders, Eq. 12; ``None``: the clean curve) with ``noise``
    (a :class:`cssat.physics.NoiseModel`, default none). With ``images=True`` also the renders.
    ``attitude``: a :mod:`cssat.scene.attitudes` object (default: nadir pointing).
    """

    def __init__(self, mesh: Mesh, scenario: Scenario, length: int, seed: int = 0,
                 atmosphere: Atmosphere | str | None = "default", noise: NoiseModel | None = None,
                 images: bool = False, size: int = 64, shadows: bool = True, attitude: Any = None):

        if isinstance(atmosphere, str) and atmosphere == "default":
            atmosphere = GaussianAtmosphere(emitters="facets")
        if atmosphere is not None and not isinstance(atmosphere, Atmosphere):
            raise FieldTypeError("atmosphere", f"expected a cssat.physics.Atmosphere or None, got {atmosphere!r}")
        if noise is not None and not isinstance(noise, NoiseModel):
            raise FieldTypeError("noise", f"expected a cssat.physics.NoiseModel or None, got {noise!r}")
        self.mesh, self.scenario, self.length, self.seed = mesh, scenario, int(length), int(seed)
        self.atmosphere, self.noise, self.images, self.size = atmosphere, noise, images, size
        lc = simulate_light_curve(mesh, scenario, shadows=shadows, attitude=attitude)
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
            self._renders = render(self.mesh, self.sun_body, self.obs_body, self.size,
                                   brightness=self.facets, dtype=torch.float64)
        return self._renders

    def __getitem__(self, index: int) -> dict:
        index = check_index(index, self.length)
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
