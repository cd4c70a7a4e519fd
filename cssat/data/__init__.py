"""Data: target images (and, later, torch Datasets of reference images and light curves)."""

from cssat.data.images import BUILTIN_IMAGES, load_target

__all__ = ["BUILTIN_IMAGES", "load_target"]
