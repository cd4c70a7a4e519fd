"""Shadow imaging of a satellite by stellar occultation (issue 25): the Fresnel diffraction
shadow of an occulter on the ground and its sampling by telescopes.

:mod:`cssat.occultation.fresnel`: ``shadow`` (the ground intensity behind an opaque mask, by
Babinet's principle and an exactly pixel-integrated Fresnel kernel) and ``aperture_field``.
"""

from cssat.occultation.fresnel import aperture_field, fresnel_scale, shadow

__all__ = ["shadow", "aperture_field", "fresnel_scale"]
