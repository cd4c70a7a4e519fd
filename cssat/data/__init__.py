"""Data: target images, torch Datasets of reference images and light curves, measured light curves."""

from cssat.data.datasets import LightCurves, ReferenceImages, item_rng
from cssat.data.images import BUILTIN_IMAGES, load_target
from cssat.data.observations import ObservedLightCurve, read_light_curve, write_light_curve

__all__ = ["BUILTIN_IMAGES", "LightCurves", "ReferenceImages", "item_rng", "load_target", "ObservedLightCurve",
           "read_light_curve", "write_light_curve"]
