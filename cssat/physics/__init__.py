"""The measurement: an atmosphere as a sensing operator plus a photometric noise model.

``y = noise(Φ x)``: :class:`Measurement` joins a sensing operator ``Φ (m, N)`` — drawn by an
:class:`Atmosphere` model — and a :class:`NoiseModel`, in the shape of deepinv's ``LinearPhysics``
(``A``, ``A_adjoint``, ``forward = noise(A(x))``). Every experiment and the ``LightCurves``
dataset take their light curves from here; the Hydra groups ``atmosphere`` and ``noise`` build
the two parts.
"""

from cssat.physics.atmosphere import (
    Atmosphere,
    CorrelatedAtmosphere,
    GaussianAtmosphere,
    LognormalAtmosphere,
    PhaseScreenAtmosphere,
)
from cssat.physics.measurement import Centered, Measurement, centered
from cssat.physics.noise import GaussianNoise, NoiseModel, NoNoise, PhotometricNoise
from cssat.physics.stats import sensing_stats

__all__ = ["Atmosphere", "GaussianAtmosphere", "LognormalAtmosphere", "CorrelatedAtmosphere", "PhaseScreenAtmosphere",
           "Measurement", "centered", "Centered", "NoiseModel", "NoNoise", "GaussianNoise", "PhotometricNoise", "sensing_stats"]
