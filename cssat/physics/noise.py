"""Noise models of the light-curve sensor, applied in flux units (never in magnitudes)."""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from cssat._checks import FieldError, float_param, opt

__all__ = ["NoiseModel", "NoNoise", "GaussianNoise", "PhotometricNoise"]


class NoiseModel:
    """``noise(y, generator) -> y_noisy`` for light curves ``y (B, m)``; all randomness from
    ``generator`` (a CPU ``torch.Generator``), so the same seed gives the same noise."""

    name = "noise"
    #: the scene's V magnitude where the model takes one (the realism maps set it on every model);
    #: a model whose noise does not depend on the brightness only records it
    magnitude: float | None = None

    def _record_magnitude(self, magnitude: float | None) -> None:
        self.magnitude = opt(magnitude, float_param, "magnitude", -30.0, 40.0)

    def __call__(self, y: Tensor, generator: torch.Generator, *, flux: Tensor | None = None) -> Tensor:  # pragma: no cover
        """``flux``: the atmosphere-free total flux of the scene (``Σ x`` per light curve), for
        models that need the light curve's physical scale."""
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """Flat settings for ``metrics.json`` (``noise``, ``noise_*``)."""
        return {"noise": self.name}


class NoNoise(NoiseModel):
    """Noiseless light curves: ``y`` is returned as it is."""

    name = "none"

    def __init__(self, *, magnitude: float | None = None):
        self._record_magnitude(magnitude)  # noiseless at any brightness

    def __call__(self, y: Tensor, generator: torch.Generator | None = None, *, flux: Tensor | None = None) -> Tensor:
        return y

    def __repr__(self) -> str:
        return "NoNoise()"


class GaussianNoise(NoiseModel):
    """Additive white Gaussian noise, ``y + σ ε`` with ``ε ~ N(0, 1)`` per sample.

    ``sigma`` is absolute (in ``y``'s units, W/m² for a light curve); ``relative`` sets
    ``σ = relative · rms(y)`` per light curve instead (the pre-0.2 ``cs.noise``). Exactly one of
    the two may be non-zero; both zero (or null) is noiseless.

    Physics: a stand-in for the sum of shot, background and read noise at a high photon count;
    it ignores that shot noise grows with the flux (see the photometric model for that).
    """

    name = "gaussian"

    def __init__(self, relative: float | None = None, sigma: float | None = None, *, magnitude: float | None = None):
        self._record_magnitude(magnitude)  # σ is set by relative or sigma, not by the brightness
        relative, sigma = opt(relative, float_param, "relative", 0.0), opt(sigma, float_param, "sigma", 0.0)
        if relative and sigma:
            raise FieldError("sigma", f"give either relative ({relative}) or sigma ({sigma}), not both")
        self.relative = float(relative or 0.0)
        self.sigma = float(sigma or 0.0)

    def __call__(self, y: Tensor, generator: torch.Generator, *, flux: Tensor | None = None) -> Tensor:
        if self.relative == 0 and self.sigma == 0:
            return y
        eps = torch.randn(*y.shape, generator=generator, dtype=y.dtype).to(y.device)
        if self.relative > 0:
            scale = y.pow(2).mean(-1, keepdim=True).sqrt() * self.relative
        else:
            scale = self.sigma
        return y + scale * eps

    def describe(self) -> dict[str, Any]:
        return {"noise": self.name, "noise_relative": self.relative, "noise_sigma": self.sigma}

    def __repr__(self) -> str:
        return f"GaussianNoise(relative={self.relative:g}, sigma={self.sigma:g})"


class PhotometricNoise(NoiseModel):
    """The noise of CCD photometry, in electrons: Poisson shot noise of the source, the sky and the
    dark current, and Gaussian read noise; the known mean background is subtracted, as in aperture
    photometry, and the result is returned in the light curve's own units.

    Scale: with ``magnitude`` given, the atmosphere-free flux of the scene (``flux``, ``Σ x``)
    is a source of that V magnitude; with ``magnitude: null`` the light curve is taken to be in
    W/m² (cssat's photometry, Eq. 8) and converted through the Sun's V magnitude (−26.74 at
    1361 W/m²). Source electrons per sample: ``S = F₀ 10^(−0.4 V) A τ t`` with ``A`` the
    aperture's area (``diameter_m``, central ``obstruction``), ``τ`` the throughput × QE and
    ``t`` the exposure. Sky: ``sky_mag_arcsec2`` over each pixel of ``pixel_scale_arcsec``;
    ``n_pix`` pixels in a photometric aperture of ``aperture_radius_arcsec``. SNR of the
    atmosphere-free sample: the CCD equation (:func:`cssat.physics.photometry.ccd_snr`).

    A sample whose expected source count is negative (the paper's zero-mean Gaussian weights) has
    no Poisson law: its shot noise is drawn as Gaussian of variance ``|S|``.
    """

    name = "photometric"

    def __init__(self, magnitude: float | None = 12.0, diameter_m: float = 1.0, obstruction: float = 0.0,
                 throughput: float = 0.5, exposure_s: float = 1.0, sky_mag_arcsec2: float = 21.0,
                 aperture_radius_arcsec: float = 3.0, pixel_scale_arcsec: float = 0.5, dark_e_per_s: float = 0.01,
                 read_noise_e: float = 5.0):
        self.magnitude = opt(magnitude, float_param, "magnitude")  # null: the light curve in W/m²
        self.diameter_m = float_param(diameter_m, "diameter_m", 0.0, open_lo=True)
        self.obstruction = float_param(obstruction, "obstruction", 0.0)
        if self.obstruction >= 1:
            raise FieldError("obstruction", f"the central obstruction's diameter ratio must be < 1, got {obstruction}")
        self.throughput = float_param(throughput, "throughput", 0.0, 1.0, open_lo=True)  # throughput × QE
        self.exposure_s = float_param(exposure_s, "exposure_s", 0.0, open_lo=True)
        self.sky_mag_arcsec2 = float_param(sky_mag_arcsec2, "sky_mag_arcsec2", -100.0)
        self.aperture_radius_arcsec = float_param(aperture_radius_arcsec, "aperture_radius_arcsec", 0.0, open_lo=True)
        self.pixel_scale_arcsec = float_param(pixel_scale_arcsec, "pixel_scale_arcsec", 0.0, open_lo=True)
        self.dark_e_per_s = float_param(dark_e_per_s, "dark_e_per_s", 0.0)
        self.read_noise_e = float_param(read_noise_e, "read_noise_e", 0.0)

    # --- the photometric budget ---
    @property
    def area_m2(self) -> float:
        return math.pi / 4 * self.diameter_m ** 2 * (1 - self.obstruction ** 2)

    @property
    def n_pix(self) -> float:
        """Pixels in the photometric aperture."""
        return math.pi * self.aperture_radius_arcsec ** 2 / self.pixel_scale_arcsec ** 2

    def electrons(self, magnitude: float) -> float:
        """Source electrons per exposure of a source of V ``magnitude``."""
        from cssat.physics.photometry import magnitude_to_photon_rate

        return magnitude_to_photon_rate(magnitude) * self.area_m2 * self.throughput * self.exposure_s

    def magnitude_of(self, electrons: float) -> float:
        """The V magnitude whose source gives ``electrons`` per exposure (inverse of :meth:`electrons`)."""
        from cssat.physics.photometry import photon_rate_to_magnitude

        return photon_rate_to_magnitude(electrons / (self.area_m2 * self.throughput * self.exposure_s))

    @property
    def sky_e_per_pixel(self) -> float:
        return self.electrons(self.sky_mag_arcsec2) * self.pixel_scale_arcsec ** 2

    @property
    def dark_e_per_pixel(self) -> float:
        return self.dark_e_per_s * self.exposure_s

    def snr(self, magnitude: float | None = None) -> float:
        """SNR of one atmosphere-free sample of a source of ``magnitude`` (default: the model's)."""
        from cssat.physics.photometry import ccd_snr

        mag = self.magnitude if magnitude is None else magnitude
        if mag is None:
            raise FieldError("magnitude", "give the source's magnitude (the model has none: its light curves are in W/m²)")
        return ccd_snr(self.electrons(mag), self.n_pix, self.sky_e_per_pixel, self.dark_e_per_pixel, self.read_noise_e)

    def _scale(self, y: Tensor, flux: Tensor | None) -> Tensor:
        """Electrons per unit of ``y``, per light curve ``(B, 1)``."""
        if self.magnitude is None:  # y in W/m²: through the Sun's V magnitude
            from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V

            return torch.full((*y.shape[:-1], 1), self.electrons(SUN_MAGNITUDE_V) / SOLAR_IRRADIANCE_W_M2,
                              dtype=torch.float64, device=y.device)
        if flux is None:
            raise FieldError("flux", "the photometric model with a magnitude needs the scene's atmosphere-free flux")
        f = torch.as_tensor(flux, dtype=torch.float64, device=y.device).reshape(*y.shape[:-1], 1)
        if not bool((f > 0).all()):
            raise FieldError("flux", "the scene's atmosphere-free flux must be > 0 to carry a magnitude")
        return self.electrons(self.magnitude) / f

    def __call__(self, y: Tensor, generator: torch.Generator, *, flux: Tensor | None = None) -> Tensor:
        scale = self._scale(y, flux)
        signal = y.double() * scale  # expected source electrons per sample
        bg = self.n_pix * (self.sky_e_per_pixel + self.dark_e_per_pixel)
        counts = _poisson((signal.clamp_min(0) + bg).cpu(), generator)  # source + sky + dark
        neg = (signal < 0).cpu()
        if bool(neg.any()):  # no Poisson law for a negative mean: a Gaussian source of variance |S|
            s = signal.cpu()
            counts = torch.where(neg, counts + s + s.abs().sqrt() * torch.randn(s.shape, generator=generator, dtype=torch.float64), counts)
        read = torch.randn(counts.shape, generator=generator, dtype=torch.float64) * (self.read_noise_e * math.sqrt(self.n_pix))
        measured = (counts + read - bg).to(y.device)  # background-subtracted electrons
        return (measured / scale).to(y.dtype)

    def describe(self) -> dict:
        out = {"noise": self.name, "noise_magnitude": self.magnitude, "noise_diameter_m": self.diameter_m,
               "noise_exposure_s": self.exposure_s, "noise_n_pix": self.n_pix, "noise_sky_e_per_pixel": self.sky_e_per_pixel}
        if self.magnitude is not None:
            out.update(noise_signal_e=self.electrons(self.magnitude), noise_snr=self.snr())
        return out

    def __repr__(self) -> str:
        return f"PhotometricNoise(magnitude={self.magnitude}, diameter_m={self.diameter_m:g}, exposure_s={self.exposure_s:g})"


#: above this mean, photon counts are drawn from the normal law N(λ, λ) (its relative error is
#: ~λ^(-1/2) < 1e-7 there): torch.poisson draws into int64 and returns -2⁶³ above λ ≈ 9.2e18
POISSON_NORMAL_ABOVE = 1e15


def _poisson(rate: Tensor, generator: torch.Generator) -> Tensor:
    """Poisson counts of ``rate`` (float64, CPU): torch's Poisson draws up to
    :data:`POISSON_NORMAL_ABOVE`, the normal approximation beyond (any finite rate)."""
    if not bool(torch.isfinite(rate).all()):
        raise FieldError("noise", "the expected electron counts are not finite (the magnitude or flux is out of range)")
    big = rate > POISSON_NORMAL_ABOVE
    if not bool(big.any()):
        return torch.poisson(rate, generator=generator)
    counts = torch.poisson(torch.where(big, torch.zeros_like(rate), rate), generator=generator)
    normal = rate + rate.sqrt() * torch.randn(rate.shape, generator=generator, dtype=rate.dtype)
    return torch.where(big, normal, counts)
