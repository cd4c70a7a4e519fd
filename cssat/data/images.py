"""Target images for the compressed-sensing experiments."""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING

import numpy as np

from cssat._checks import FieldError
from cssat._record import read_input
from cssat.scene import tess_like

if TYPE_CHECKING:
    import trimesh

    from cssat.scene import Mesh


__all__ = ["BUILTIN_IMAGES", "load_target"]

#: built-in targets: ``tess`` (the procedural TESS-like spacecraft rendered with shadows, the
#: paper's target) and scikit-image test images that ship inside that package (no download).
BUILTIN_IMAGES = ("tess", "camera", "moon", "astronaut", "checkerboard", "brick", "grass", "gravel")

#: Sun and view directions (body frame, from the object) of the built-in ``tess`` target
TESS_VIEW = {"sun": (0.4, -0.7, 0.6), "observer": (0.8, -0.5, 0.3)}


def render_tess(size: int) -> np.ndarray:
    """The procedural TESS-like model in the paper's single material (Eq. 8: C_d 0.8, C_s 0.2) rendered at
    ``size × size`` by :func:`render_exposed` — the paper's target image."""
    return render_exposed(tess_like(material="uniform"), size)


def render_exposed(mesh: Mesh | trimesh.Trimesh, size: int, view: dict = TESS_VIEW) -> np.ndarray:
    """``mesh`` rendered at ``size × size`` (flat shading, shadows, the model's bounding-sphere field
    of view) from ``view`` (body-frame ``sun`` and ``observer`` directions), exposed like a
    photograph: scaled so the 99th percentile of the lit pixels is 1 and clipped there (a few
    pixels that collect the flux of several sub-pixel facets would otherwise leave the rest of the
    spacecraft near black)."""
    import torch  # heavy: torch (~1 s); the module imports without it

    from cssat.optics import render  # heavy: cssat.optics imports torch

    unit = [np.asarray(v, float) / np.linalg.norm(v) for v in (view["sun"], view["observer"])]
    img = render(mesh, unit[0][None], unit[1][None], size, shadows=True, dtype=torch.float64)[0].numpy()
    lit = img[img > 0]
    return np.clip(img / np.percentile(lit, 99), 0.0, 1.0) if lit.size else img


#: the smallest image file a target is read from (pixels per side)
MIN_IMAGE_SIDE = 4


def load_target(image: str, size: int, field: str = "target.image") -> np.ndarray:
    """Load a target image as a gray ``(size, size)`` float64 array in ``[0, 1]``.

    ``image`` is a file path (anything Pillow reads: PNG, JPEG, TIFF, …) or one of
    :data:`BUILTIN_IMAGES`. Colour is converted to luminance (ITU-R 601 weights, dropping an alpha
    channel), and the image is resized with anti-aliasing. It must be square: a CS image is
    ``n × n`` and stretching would distort it. ``field`` names the config field in error messages.
    """
    from skimage.transform import resize  # heavy: scikit-image, only for load_target()

    if not isinstance(size, int) or isinstance(size, bool) or size < 2:
        raise FieldError("target.size", f"must be an integer >= 2, got {size!r}")
    if not isinstance(image, str) or not image:
        raise FieldError(field, f"expected a file path or one of {list(BUILTIN_IMAGES)}, got {image!r}")
    if image == "tess" and not os.path.exists(image):
        return render_tess(size)
    if image in BUILTIN_IMAGES and not os.path.exists(image):
        import skimage.data  # heavy: scikit-image, only for load_target()

        arr = np.asarray(getattr(skimage.data, image)())
    else:
        if not os.path.isfile(image):
            raise FieldError(
                field, f"{image!r} is neither a readable file nor a built-in image "
                f"({', '.join(BUILTIN_IMAGES)})"
            )
        from PIL import Image, UnidentifiedImageError  # heavy: pillow, only for load_target()

        data = read_input(image, 1 << 30, field)  # hashed as read: the manifest's input is what was loaded
        try:
            with Image.open(io.BytesIO(data)) as im:
                im.load()
                if im.mode in ("F", "I") or im.mode.startswith("I;16"):
                    arr = np.asarray(im, dtype=np.float64)  # keep float and 16-bit data as they are
                elif im.mode in ("1", "L"):
                    arr = np.asarray(im)
                else:
                    arr = np.asarray(im.convert("RGB"))  # colour, palette, alpha: luminance below
        except Image.DecompressionBombError as err:
            raise FieldError(field, f"{image!r} is too large to load safely ({err}); resize it first") from None
        except (UnidentifiedImageError, OSError, ValueError) as err:
            raise FieldError(field, f"cannot read {image!r} as an image: {err}") from None
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim == 3:
        rgb = arr[..., :3]
        arr = rgb @ np.array([0.299, 0.587, 0.114]) if rgb.shape[-1] == 3 else rgb[..., 0]
    if arr.ndim != 2:
        raise FieldError(field, f"expected a 2-D gray or colour image, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise FieldError(field, "the image contains NaN or Inf pixels")
    h, w = arr.shape
    if h != w:
        raise FieldError(field, f"image is {h}×{w} pixels; a square image is required (crop it first)")
    if h < MIN_IMAGE_SIDE:
        raise FieldError(field, f"image is {h}×{w} pixels; at least {MIN_IMAGE_SIDE}×{MIN_IMAGE_SIDE} are needed "
                                "(a smaller one holds no image to reconstruct)")
    lo, hi = float(arr.min()), float(arr.max())
    if hi > lo:
        arr = (arr - lo) / (hi - lo)
    else:
        arr = np.zeros_like(arr)
    if h != size:
        arr = resize(arr, (size, size), order=3, anti_aliasing=h > size, mode="reflect")
    return np.clip(arr, 0.0, 1.0)
