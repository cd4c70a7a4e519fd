"""Data: target images and torch Datasets of reference images and light curves."""

from cssat.data.datasets import LightCurves, ReferenceImages, item_rng
from cssat.data.images import BUILTIN_IMAGES, load_target

__all__ = ["BUILTIN_IMAGES", "LightCurves", "ReferenceImages", "item_rng", "load_target"]
