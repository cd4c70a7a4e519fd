"""Photometric conversions: magnitudes ↔ photons ↔ photo-electrons, and the CCD equation.

The V band (Bessell 1990; zero point of Bessell, Castelli & Plez 1998): an object of V = 0 gives
``f_λ = 3.631e-11 W m⁻² nm⁻¹`` at 551 nm over an 88 nm wide band, i.e. about
``8.9e9 photons s⁻¹ m⁻²``. Magnitudes are only ever converted to fluxes; noise is added in
electrons (adding it in magnitudes biases the mean flux).
"""

from __future__ import annotations

import math

__all__ = ["V_ZERO_POINT_PHOTONS", "magnitude_to_photon_rate", "photon_rate_to_magnitude", "ccd_snr"]

_H, _C = 6.62607015e-34, 299792458.0
#: photons s⁻¹ m⁻² of a V = 0 source through the V band: f_λ Δλ / (h c / λ_eff)
V_ZERO_POINT_PHOTONS = 3.631e-11 * 88.0 / (_H * _C / 551e-9)


def magnitude_to_photon_rate(magnitude: float, zero_point: float = V_ZERO_POINT_PHOTONS) -> float:
    """Photons s⁻¹ m⁻² of a source of ``magnitude``: ``F₀ 10^(−0.4 m)``."""
    return zero_point * 10.0 ** (-0.4 * magnitude)


def photon_rate_to_magnitude(rate: float, zero_point: float = V_ZERO_POINT_PHOTONS) -> float:
    """The magnitude of a photon rate (s⁻¹ m⁻²): ``−2.5 log10(rate / F₀)``."""
    return -2.5 * math.log10(rate / zero_point)


def ccd_snr(signal_e: float, n_pix: float, background_e: float, dark_e: float, read_noise_e: float) -> float:
    """The CCD equation (Howell 2006): ``S / √(S + n_pix (B + D + R²))`` with ``S`` the source's
    electrons, ``B`` and ``D`` the sky and dark electrons per pixel, ``R`` the read noise (e rms)."""
    return signal_e / math.sqrt(signal_e + n_pix * (background_e + dark_e + read_noise_e ** 2))
