"""Shadow imaging of a satellite by stellar occultation (issue 25): the Fresnel diffraction
shadow of an occulter on the ground and its sampling by telescopes.

:mod:`cssat.occultation.fresnel`: ``shadow`` (the ground intensity behind an opaque mask, by
Babinet's principle and an exactly pixel-integrated Fresnel kernel) and ``aperture_field``;
:mod:`cssat.occultation.geometry`: the fundamental plane, the shadow's track and velocity from a
scenario and a star, the mesh's silhouette; :mod:`cssat.occultation.record`: the averages over
aperture, exposure and the star's disk, the telescopes' series and their noise;
:mod:`cssat.occultation.invert`: the silhouette from the series (non-linear, autograd);
:mod:`cssat.occultation.linear`: the linearised (weak-occulter) model as a linear operator for
cssat's linear solvers; :mod:`cssat.occultation.shapes`: the silhouette as a union of a few
superellipses (a sparse model) fitted to the series; :mod:`cssat.occultation.prior`: the prior
(pixels or superellipses) and the superellipses' multi-start chosen by held-out telescopes; :mod:`cssat.occultation.rate`: how often
such occultations happen; :mod:`cssat.occultation.spectrum`: the star's photons through a
passband as quadrature wavelengths for a polychromatic shadow; :mod:`cssat.occultation.nuisance`:
frozen scintillation gains, the shadow's offset, speed, gains and the star's diameter for a
given silhouette; :mod:`cssat.occultation.event`: the silhouette and those nuisances together;
:mod:`cssat.occultation.results`: the fits' results (``EventFit``, ``SilhouetteFit``: read-only
mappings with attributes).
"""

from cssat.occultation.fresnel import aperture_field, fresnel_scale, shadow
from cssat.occultation.geometry import (bar_target, ground_to_plane, plane_basis, plane_to_ground, shadow_track, silhouette,
                                        star_direction)
from cssat.occultation.invert import edge_width, feature_contrast, invert_silhouette, iou, registered_iou, resample_mask
from cssat.occultation.linear import ShadowOperator, invert_linear
from cssat.occultation.rate import occultation_rate, stars_brighter_than
from cssat.occultation.shapes import fit_shape_params, fit_shapes, heldout_chi2, render_shapes, shapes_from_mask
from cssat.occultation.spectrum import band_wavelengths, teff_from_bv
from cssat.occultation.record import noisy, pattern_kernel, photons, record, smooth
from cssat.occultation.nuisance import dip_offset, fit_nuisances, mask_centroid, scintillation_gains
from cssat.occultation.event import event_geometry, invert_event
from cssat.occultation.prior import choose_prior, shape_starts
from cssat.occultation.results import EventFit, PriorChoice, SilhouetteFit

__all__ = ["bar_target", "shadow", "aperture_field", "fresnel_scale", "plane_basis", "ground_to_plane", "plane_to_ground", "shadow_track", "silhouette", "star_direction",
           "invert_silhouette", "iou", "registered_iou", "resample_mask", "edge_width", "feature_contrast", "ShadowOperator", "invert_linear", "occultation_rate", "stars_brighter_than", "fit_shapes", "fit_shape_params", "heldout_chi2", "render_shapes",
           "shapes_from_mask", "band_wavelengths", "teff_from_bv", "noisy", "pattern_kernel", "photons", "record", "smooth",
           "dip_offset", "fit_nuisances", "mask_centroid", "scintillation_gains", "invert_event", "event_geometry",
           "EventFit", "SilhouetteFit", "PriorChoice", "choose_prior", "shape_starts"]
