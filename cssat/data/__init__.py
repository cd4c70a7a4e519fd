"""Data: target images, torch Datasets of reference images and light curves, measured light curves
(:func:`read_light_curve`, any format registered with :func:`register_format`)."""

from cssat.data.datasets import LightCurves, ReferenceImages, item_rng
from cssat.data.images import BUILTIN_IMAGES, load_target
from cssat.data.observations import ObservedLightCurve, read_light_curve, write_light_curve
from cssat.data.registry import Format, identify_format, register_format, registered_formats, unregister_format

__all__ = ["BUILTIN_IMAGES", "LightCurves", "ReferenceImages", "item_rng", "load_target", "ObservedLightCurve",
           "read_light_curve", "write_light_curve", "Format", "register_format", "unregister_format", "registered_formats",
           "identify_format"]
