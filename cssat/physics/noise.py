"""Noise models of the light-curve sensor, applied in flux units (never in magnitudes)."""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from cssat._checks import FieldError, choice_param, float_param, opt
from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V
from cssat.physics.photometry import ccd_snr, magnitude_to_photon_rate, photon_rate_to_magnitude

__all__ = ["NoiseModel", "NoNoise", "GaussianNoise", "PhotometricNoise", "MAX_FLOOR", "add_floor"]

#: the largest photometric floor a noise model takes (10 %: all-sky photometry of GEO objects has 1–3 %)
MAX_FLOOR = 0.1


class NoiseModel:
    """``noise(y, generator) -> y_noisy`` for light curves ``y (B, m)``; all randomness from
    ``generator`` (a CPU ``torch.Generator``), so the same seed gives the same noise.

    ``floor`` (the Gaussian and photometric models; 0 to :data:`MAX_FLOOR`, default 0): a
    relative 1σ added in quadrature to every sample's error — the 1–3 % floor of real all-sky
    photometry of GEO objects (transparency, calibration, comparison stars) — drawn as
    ``+ floor · y · ε`` (``y`` the noiseless sample) after the model's own noise; its
    :meth:`variance` gains ``(floor · y)²``."""

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

    def variance(self, y: Tensor, *, flux: Tensor | None = None) -> Tensor:
        """The noise variance of each sample of a measured light curve ``y (..., m)`` in ``y``'s
        units squared, as an observer computes it from the data and the detector's settings (the
        measured values stand in for the expected ones); used by the discrepancy principle."""
        raise FieldError("noise", f"the {self.name} noise model does not state its variance")

    def describe(self) -> dict[str, Any]:
        """Flat settings for ``metrics.json`` (``noise``, ``noise_*``)."""
        return {"noise": self.name, **self._describe_floor()}

    # --- the photometric floor: a relative 1σ added in quadrature to every sample's error ---
    #: the floor's relative rms (0: none, today's default); at most :data:`MAX_FLOOR`
    floor: float = 0.0

    def _set_floor(self, floor: float | None) -> None:
        self.floor = float(opt(floor, float_param, "floor", 0.0, MAX_FLOOR) or 0.0)

    def _add_floor(self, noisy: Tensor, clean: Tensor, generator: torch.Generator) -> Tensor:
        """``noisy + floor · clean · ε``, ``ε ~ N(0, 1)`` per sample, drawn after the model's own
        draws (nothing is drawn when ``floor`` is 0: the generator's stream is as without it)."""
        if not self.floor:
            return noisy
        eps = torch.randn(clean.shape, generator=generator, dtype=torch.float64).to(clean.device)
        return (noisy.double() + self.floor * clean.double() * eps).to(noisy.dtype)

    def _floor_variance(self, var: Tensor, y: Tensor) -> Tensor:
        return var + (self.floor * y.double()) ** 2 if self.floor else var

    def _describe_floor(self) -> dict[str, Any]:
        return {"noise_floor": self.floor} if self.floor else {}


class NoNoise(NoiseModel):
    """Noiseless light curves: ``y`` is returned as it is."""

    name = "none"

    def __init__(self, *, magnitude: float | None = None, floor: float | None = None):
        self._record_magnitude(magnitude)  # noiseless at any brightness
        self._set_floor(floor)
        if self.floor:
            raise FieldError("floor", f"a photometric floor ({self.floor:g}) is noise: use the gaussian or photometric "
                                      "noise model (the none model takes floor 0)")

    def __call__(self, y: Tensor, generator: torch.Generator | None = None, *, flux: Tensor | None = None) -> Tensor:
        return y

    def variance(self, y: Tensor, *, flux: Tensor | None = None) -> Tensor:
        return torch.zeros_like(y, dtype=torch.float64)

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

    def __init__(self, relative: float | None = None, sigma: float | None = None, *, magnitude: float | None = None,
                 floor: float | None = None):
        self._record_magnitude(magnitude)  # σ is set by relative or sigma, not by the brightness
        self._set_floor(floor)
        relative, sigma = opt(relative, float_param, "relative", 0.0), opt(sigma, float_param, "sigma", 0.0)
        if relative and sigma:
            raise FieldError("sigma", f"give either relative ({relative}) or sigma ({sigma}), not both")
        self.relative = float(relative or 0.0)
        self.sigma = float(sigma or 0.0)

    def __call__(self, y: Tensor, generator: torch.Generator, *, flux: Tensor | None = None) -> Tensor:
        if self.relative == 0 and self.sigma == 0:
            return self._add_floor(y, y, generator)
        eps = torch.randn(*y.shape, generator=generator, dtype=y.dtype).to(y.device)
        if self.relative > 0:
            scale = y.pow(2).mean(-1, keepdim=True).sqrt() * self.relative
        else:
            scale = self.sigma
        return self._add_floor(y + scale * eps, y, generator)

    def variance(self, y: Tensor, *, flux: Tensor | None = None) -> Tensor:
        yy = y.double()
        if self.relative > 0:  # rms(y_noisy)² = rms(y)² (1 + relative²)
            var = (yy.pow(2).mean(-1, keepdim=True) * self.relative ** 2 / (1 + self.relative ** 2)).expand_as(yy)
        else:
            var = torch.full_like(yy, self.sigma ** 2)
        return self._floor_variance(var, yy)

    def describe(self) -> dict[str, Any]:
        return {"noise": self.name, "noise_relative": self.relative, "noise_sigma": self.sigma, **self._describe_floor()}

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

    Detector limits: the source falls on the CCD as a circular Gaussian of
    ``seeing_fwhm_arcsec``; its brightest pixel holds ``P = S f_peak + sky + dark`` electrons with
    ``f_peak = erf(p / (2√2 σ))²`` (``p`` the pixel scale, ``σ = FWHM/2.3548``). Above
    ``full_well_e`` the pixel saturates: ``saturation: flag`` keeps the counts and records the
    fraction of saturated samples (``noise_saturated``; an experiment marks such settings
    unreachable), ``clip`` removes from each sample the electrons above the full well,
    ``(2πσ²/p²)(P − W − W ln(P/W))`` for a Gaussian profile clipped at ``W`` (a biased,
    non-linear photometry), ``error`` refuses the setting. ``readout_s``: the dead time between
    exposures (the cadence is ``exposure_s + readout_s``; ``noise_duty_cycle``). ``systematic``:
    a multiplicative per-sample error of that relative rms — transparency, flat-field and
    aperture-centring errors, the floor of ground photometry (≈ 1e-3 at good sites) — drawn as
    ``y (1 + systematic ε)``, ``ε ~ N(0, 1)``. Assumes a static, well-sampled PSF and independent
    samples.
    """

    name = "photometric"

    def __init__(self, magnitude: float | None = 12.0, diameter_m: float = 1.0, obstruction: float = 0.0,
                 throughput: float = 0.5, exposure_s: float = 1.0, sky_mag_arcsec2: float = 21.0,
                 aperture_radius_arcsec: float = 3.0, pixel_scale_arcsec: float = 0.5, dark_e_per_s: float = 0.01,
                 read_noise_e: float = 5.0, full_well_e: float | None = 1.0e5, seeing_fwhm_arcsec: float = 1.5,
                 saturation: str = "flag", readout_s: float = 0.0, systematic: float = 1.0e-3, floor: float | None = None):
        self._set_floor(floor)
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
        self.full_well_e = opt(full_well_e, float_param, "full_well_e", 0.0, open_lo=True)  # null: no limit
        self.seeing_fwhm_arcsec = float_param(seeing_fwhm_arcsec, "seeing_fwhm_arcsec", 0.0, open_lo=True)
        self.saturation = choice_param(saturation, "saturation", ("flag", "clip", "error"))
        self.readout_s = float_param(readout_s, "readout_s", 0.0)
        self.systematic = float_param(systematic, "systematic", 0.0, 1.0)
        self.saturated = float("nan")  #: the fraction of saturated samples of the last call

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
        return magnitude_to_photon_rate(magnitude) * self.area_m2 * self.throughput * self.exposure_s

    def magnitude_of(self, electrons: float) -> float:
        """The V magnitude whose source gives ``electrons`` per exposure (inverse of :meth:`electrons`)."""
        return photon_rate_to_magnitude(electrons / (self.area_m2 * self.throughput * self.exposure_s))

    @property
    def sky_e_per_pixel(self) -> float:
        return self.electrons(self.sky_mag_arcsec2) * self.pixel_scale_arcsec ** 2

    @property
    def dark_e_per_pixel(self) -> float:
        return self.dark_e_per_s * self.exposure_s

    @property
    def psf_sigma_arcsec(self) -> float:
        """The Gaussian star image's σ: ``FWHM / (2 √(2 ln 2))``."""
        return self.seeing_fwhm_arcsec / (2 * math.sqrt(2 * math.log(2)))

    @property
    def peak_fraction(self) -> float:
        """The share of the source's electrons in its brightest pixel (a Gaussian PSF centred on it)."""
        return math.erf(self.pixel_scale_arcsec / (2 * math.sqrt(2) * self.psf_sigma_arcsec)) ** 2

    def peak_electrons(self, source_e: Tensor | float) -> Tensor | float:
        """Electrons in the brightest pixel for ``source_e`` source electrons per exposure."""
        return source_e * self.peak_fraction + self.sky_e_per_pixel + self.dark_e_per_pixel

    def clipped_electrons(self, peak_e: Tensor) -> Tensor:
        """The electrons above the full well, summed over the Gaussian image whose brightest pixel
        expects ``peak_e``: ``(2πσ²/p²)(P − W − W ln(P/W))`` where ``P > W``, else 0."""
        W = self.full_well_e
        P = peak_e.clamp_min(W)
        return 2 * math.pi * self.psf_sigma_arcsec ** 2 / self.pixel_scale_arcsec ** 2 * (P - W - W * torch.log(P / W))

    @property
    def cadence_s(self) -> float:
        """Seconds from one sample to the next: the exposure and the readout's dead time."""
        return self.exposure_s + self.readout_s

    def reachable(self, magnitude: float | None = None, *, excursion: float = 1.0) -> bool:
        """Whether a source of ``magnitude`` (default the model's), brightened by ``excursion``,
        stays below the full well in its brightest pixel."""
        if self.full_well_e is None:
            return True
        mag = self.magnitude if magnitude is None else magnitude
        return bool(self.peak_electrons(self.electrons(mag) * excursion) <= self.full_well_e)

    def snr(self, magnitude: float | None = None) -> float:
        """SNR of one atmosphere-free sample of a source of ``magnitude`` (default: the model's)."""
        mag = self.magnitude if magnitude is None else magnitude
        if mag is None:
            raise FieldError("magnitude", "give the source's magnitude (the model has none: its light curves are in W/m²)")
        return ccd_snr(self.electrons(mag), self.n_pix, self.sky_e_per_pixel, self.dark_e_per_pixel, self.read_noise_e)

    def _scale(self, y: Tensor, flux: Tensor | None) -> Tensor:
        """Electrons per unit of ``y``, per light curve ``(B, 1)``."""
        if self.magnitude is None:  # y in W/m²: through the Sun's V magnitude
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
        measured = counts + read - bg  # background-subtracted electrons
        measured = self._detector(measured, signal.cpu(), generator)
        return self._add_floor((measured.to(y.device) / scale).to(y.dtype), y, generator)

    def _detector(self, measured: Tensor, signal: Tensor, generator: torch.Generator) -> Tensor:
        """Saturation and the systematic floor on background-subtracted electrons (CPU, float64)."""
        if self.full_well_e is not None:
            peak = self.peak_electrons(signal.clamp_min(0))
            over = peak > self.full_well_e
            self.saturated = float(over.double().mean())
            if bool(over.any()):
                if self.saturation == "error":
                    raise FieldError("noise.magnitude", f"the brightest pixel holds up to {float(peak.max()):.3g} e⁻, over "
                                                        f"the full well of {self.full_well_e:.3g} e⁻ (saturation: error): "
                                                        f"use a fainter source, a shorter exposure_s or saturation: flag or clip")
                if self.saturation == "clip":
                    measured = measured - self.clipped_electrons(peak)
        else:
            self.saturated = 0.0
        if self.systematic > 0:
            measured = measured * (1 + self.systematic * torch.randn(measured.shape, generator=generator, dtype=torch.float64))
        return measured

    def variance(self, y: Tensor, *, flux: Tensor | None = None) -> Tensor:
        """``(|S| + n_pix (sky + dark + read²) + (systematic S)²) / scale²`` per sample, ``S`` the
        measured source electrons."""
        scale = self._scale(y, flux)
        S = y.double() * scale
        e = S.abs() + self.n_pix * (self.sky_e_per_pixel + self.dark_e_per_pixel + self.read_noise_e ** 2)
        return self._floor_variance((e + (self.systematic * S) ** 2) / scale ** 2, y)

    def describe(self) -> dict:
        out = {"noise": self.name, "noise_magnitude": self.magnitude, "noise_diameter_m": self.diameter_m,
               "noise_exposure_s": self.exposure_s, "noise_n_pix": self.n_pix, "noise_sky_e_per_pixel": self.sky_e_per_pixel}
        out.update(noise_full_well_e=self.full_well_e, noise_saturation=self.saturation, noise_systematic=self.systematic,
                   noise_readout_s=self.readout_s, noise_duty_cycle=self.exposure_s / self.cadence_s)
        if self.magnitude is not None:
            out.update(noise_signal_e=self.electrons(self.magnitude), noise_snr=self.snr(),
                       noise_peak_e=self.peak_electrons(self.electrons(self.magnitude)), noise_reachable=self.reachable())
        if self.saturated == self.saturated:  # after a call
            out["noise_saturated"] = self.saturated
        out.update(self._describe_floor())
        return out

    def __repr__(self) -> str:
        return f"PhotometricNoise(magnitude={self.magnitude}, diameter_m={self.diameter_m:g}, exposure_s={self.exposure_s:g})"


def add_floor(y: Tensor, sigma: Tensor | None, floor: float, generator: torch.Generator) -> tuple[Tensor, Tensor]:
    """A photometric floor on an already-noisy light curve: ``(y + floor · y · ε, sqrt(σ² + (floor · y)²))``
    with ``ε ~ N(0, 1)`` from ``generator`` (``y`` the measured values standing in for the
    noiseless ones; ``sigma`` None: 0). For code that draws its noise without a noise model."""
    floor = float_param(floor, "floor", 0.0, MAX_FLOOR)
    yy = torch.as_tensor(y, dtype=torch.float64)
    sg = torch.zeros_like(yy) if sigma is None else torch.as_tensor(sigma, dtype=torch.float64)
    if not floor:
        return yy, sg
    eps = torch.randn(yy.shape, generator=generator, dtype=torch.float64).to(yy.device)
    return yy + floor * yy * eps, torch.sqrt(sg**2 + (floor * yy) ** 2)


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
