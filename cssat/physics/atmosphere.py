"""Atmosphere models: the random transmission of each emitter's light flux, sample by sample.

An :class:`Atmosphere` draws the weights ``w[t, j]`` by which the flux of emitter ``j`` (a pixel of
the resolved image, or a facet of the mesh) reaches the sensor in light-curve sample ``t``: a
sensing matrix ``Φ (m, n)``. The light curve of a static scene ``x (n,)`` is ``y = Φx``
(paper Eq. 15); of a changing scene ``x_t``, ``y_t = Σⱼ Φ[t, j] x_t[j]`` (Eq. 11, 12).

The :class:`Atmosphere` contract and what the models share are in :mod:`cssat.physics.atmosphere_base`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

import torch
from torch import Tensor

from cssat._checks import choice_param, float_param, int_param, opt
from cssat.physics.atmosphere_base import (ARCSEC, EMITTERS, Atmosphere, _geometry, _lognormal, _PositiveAtmosphere, _side,
                                           _unit_normals)
from cssat.sparse import MatrixOperator
from cssat.sparse.operators import GaussianSensing, LinearOperator

if TYPE_CHECKING:
    from cssat.physics.turbulence import Layers

__all__ = ["Atmosphere", "GaussianAtmosphere", "LognormalAtmosphere", "CorrelatedAtmosphere", "PhaseScreenAtmosphere",
           "EMITTERS", "ARCSEC"]


class GaussianAtmosphere(Atmosphere):
    """The paper's atmosphere (Eq. 11, 12, 15): i.i.d. Gaussian weights ``N(mean, std²)``, by
    default ``mean = 0`` and ``std = 1/√n`` for ``n`` emitters.

    Each row ``t`` is drawn from its own generator seeded by ``(seed, t)``
    (:class:`~cssat.sparse.GaussianSensing`): the first ``m`` rows do not depend on ``m``.

    Physics: a mathematical stand-in, not a model of turbulence. Real transmission is positive,
    with mean ≈ 1 and fluctuations of about 1 % (scintillation), and at GEO every pixel of a
    satellite sees nearly the same atmosphere; zero-mean weights imply negative fluxes. The
    paper uses this model because a Gaussian matrix satisfies the restricted isometry property.
    """

    name = "gaussian"

    def __init__(self, mean: float = 0.0, std: float | None = None, emitters: str = "pixels", *,
                 object_size_m: float | None = None, range_km: float | None = None):
        self.mean, self.std = float_param(mean, "mean"), opt(std, float_param, "std", 0.0, open_lo=True)
        self.emitters = choice_param(emitters, "emitters", EMITTERS)
        self._geometry(object_size_m, range_km)  # independent weights: no effect

    def operator(self, m: int, n: int, *, seed: int = 0, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> GaussianSensing:
        return GaussianSensing(m, n, seed=seed, dtype=dtype, device=device, mean=self.mean, std=self.std)

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "atmosphere_mean": self.mean, "atmosphere_std": self.std}

    def __repr__(self) -> str:
        return f"GaussianAtmosphere(mean={self.mean:g}, std={self.std}, emitters={self.emitters!r})"


# --- physical models: positive transmission, mean 1 -----------------------------------------------


class LognormalAtmosphere(_PositiveAtmosphere):
    """Positive, mean-1 transmission, independent for every pixel and sample: ``Φ = exp(s Z − s²/2)``,
    ``Z ~ N(0, 1)``, ``s² = ln(1 + σ_I²)`` so that ``E Φ = 1`` and ``Var Φ = σ_I²``.

    ``scintillation_index`` σ_I² is given, or (null) the weak-turbulence σ_I² of the continuous
    Hufnagel–Valley 5/7 profile with Bufton's wind for a telescope of ``diameter_m`` at
    ``airmass`` with ``exposure_s``, at ``site_altitude_m``
    (:func:`cssat.physics.turbulence.scintillation_index`, the phase-screen model's too): 1.24e-5
    for a 1 m telescope and a 1 s exposure at the zenith (1.4× Young's 1967 formula).

    Physics: the scintillation's log-normal statistics and mean are right; the independence between
    pixels is not — it holds only when the object's pixels are farther apart than the scintillation
    correlation angle (``correlated``), which a satellite at GEO is not (it subtends ≈ 0.06″).
    """

    name = "lognormal"

    def __init__(self, scintillation_index: float | None = None, diameter_m: float = 1.0, airmass: float = 1.0,
                 exposure_s: float = 1.0, site_altitude_m: float = 0.0, wavelength_m: float = 550e-9, *,
                 object_size_m: float | None = None, range_km: float | None = None):
        super().__init__(scintillation_index, diameter_m, airmass, exposure_s, site_altitude_m, wavelength_m)
        self._geometry(object_size_m, range_km)  # independent per pixel: no effect

    def operator(self, m: int, n: int, *, seed: int = 0, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> LinearOperator:
        dtype = dtype or torch.get_default_dtype()
        s2 = math.log1p(self.scintillation_index)
        w = _lognormal(math.sqrt(s2) * _unit_normals(m, n, seed, torch.float64), s2)
        return MatrixOperator(w.to(dtype=dtype, device=device))


class CorrelatedAtmosphere(_PositiveAtmosphere):
    """Positive, mean-1 transmission whose fluctuations are correlated between pixels:
    ``Φ[t] = exp(s G_t − s²/2)`` with ``G_t`` a Gaussian field over the ``n × n`` image of unit
    variance and correlation ``exp(−Δθ² / (2 θ_c²))`` between pixels ``Δθ`` apart.

    The image spans ``object_size_m / range_km`` radians (a 10 m satellite at GEO: 0.058″). The
    correlation angle ``θ_c`` is ``correlation_arcsec``, or (null) the scintillation's: a pattern
    at height h decorrelates once two directions see it shifted by its correlation length
    ``max(D, √(λ X h))``, so ``θ_c = max(D, r_F) / (X h)`` with h = 10 km (where scintillation
    comes from) — 20″ for a 1 m telescope. ``θ_c → 0`` gives :class:`LognormalAtmosphere`;
    ``θ_c → ∞`` rank 1 (all pixels share one transmission: only the total flux is measured).
    Drawn separably: ``G_t = L_x Z_t L_yᵀ`` with ``L`` the square root of the 1-D correlation.
    """

    name = "correlated"
    spatial = True

    def __init__(self, correlation_arcsec: float | None = None, object_size_m: float = 10.0, range_km: float = 35786.0,
                 scintillation_index: float | None = None, diameter_m: float = 1.0, airmass: float = 1.0,
                 exposure_s: float = 1.0, site_altitude_m: float = 0.0, wavelength_m: float = 550e-9):
        super().__init__(scintillation_index, diameter_m, airmass, exposure_s, site_altitude_m, wavelength_m)
        self.fov_rad = _geometry(object_size_m, range_km)
        if correlation_arcsec is not None:
            float_param(correlation_arcsec, "correlation_arcsec", 0.0)
        self.object_size_m, self.range_km, self.wavelength_m = float(object_size_m), float(range_km), float(wavelength_m)
        self.correlation_arcsec = correlation_arcsec

    @property
    def correlation_rad(self) -> float:
        if self.correlation_arcsec is not None:
            return self.correlation_arcsec * ARCSEC
        h = 10e3 * self.airmass
        return max(self.diameter_m, math.sqrt(self.wavelength_m * h)) / h

    def correlation_matrix(self, side: int) -> Tensor:
        """The 1-D correlation ``(side, side)`` between pixel rows ``Δθ = |i − j| · fov / side`` apart."""
        d = torch.arange(side, dtype=torch.float64) * (self.fov_rad / side)
        dd = d[:, None] - d[None, :]
        theta = self.correlation_rad
        if theta == 0:
            return torch.eye(side, dtype=torch.float64)
        return torch.exp(-0.5 * (dd / theta) ** 2)

    def operator(self, m: int, n: int, *, seed: int = 0, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> LinearOperator:
        side = _side(n)
        ev, vec = torch.linalg.eigh(self.correlation_matrix(side))
        root = (vec * ev.clamp_min(0).sqrt()) @ vec.T  # symmetric square root, exact also when singular
        z = _unit_normals(m, n, seed, torch.float64).reshape(m, side, side)
        g = (root @ z @ root.T).reshape(m, n)
        s2 = math.log1p(self.scintillation_index)
        w = _lognormal(math.sqrt(s2) * g, s2)
        return MatrixOperator(w.to(dtype=dtype or torch.get_default_dtype(), device=device))

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "atmosphere_correlation_arcsec": self.correlation_rad / ARCSEC,
                "atmosphere_fov_arcsec": self.fov_rad / ARCSEC, "atmosphere_size_over_correlation":
                self.fov_rad / self.correlation_rad if self.correlation_rad > 0 else math.inf}


class PhaseScreenAtmosphere(_PositiveAtmosphere):
    """Scintillation from multi-layer Kolmogorov / von Kármán turbulence, for each pixel's direction.

    Model (weak turbulence; Roddier 1981). Layer ``l`` at height ``h_l`` (the Hufnagel–Valley
    profile above the site, cut into ``n_layers``; Bufton's wind) carries a von Kármán phase
    screen with outer scale ``outer_scale_m``. In the pupil its log-amplitude is the Fresnel filter
    of the phase, ``χ̂(f) = sin(πλ z f²) φ̂(f)`` with ``z = X h_l`` — linear in the phase, so the
    relative intensity ``δI/I ≈ 2χ`` of every direction is one Gaussian field per layer. Averaged
    over the circular pupil (``|P̂(f)|²``) and over the exposure, during which the frozen screen
    moves by ``v_l t`` (``sinc²(π v t f·u)``), its PSD is :func:`cssat.physics.turbulence.intensity_psd`.
    Pixel ``p`` at angle ``θ_p`` from the image centre sees layer ``l`` shifted by ``z θ_p``, so

        ``Φ[t, p] = exp(Σ_l g_{l,t}(z_l θ_p) − σ²/2)``,   ``σ² = Σ_l Var g_l``

    (log-normal, mean 1; scintillation index ``e^{σ²} − 1``). Each ``g_{l,t}`` is synthesised
    spectrally on a log-polar grid of ``n_radial × n_angular`` frequencies (random Fourier
    amplitudes per sample): no periodic FFT grid, so millimetre shifts (GEO) and metre shifts (a
    large object in LEO) are both exact up to the quadrature. The ``n`` pixels of an ``n × n``
    image span ``object_size_m / range_km`` rad; GEO (35,786 km) by default.

    Assumptions, and where reality differs: weak turbulence (σ_I² ≪ 1; wrong near the horizon or
    for small apertures in strong scintillation); the log-normal form of the aperture-averaged
    intensity; samples independent (the screens move farther than the pupil between samples:
    at 10 m/s and a 1 s cadence, 10 m); no phase (image motion, seeing) effects on the total flux;
    a monochromatic wavelength ``wavelength_m`` (broad bands scintillate a little less).
    ``slew_rad_s``: a tracked LEO pass sweeps the line of sight across layer ``l`` at ``ω z_l``
    (:func:`~cssat.physics.turbulence.layers_from_profile`): more averaging in each exposure.
    """

    name = "phase_screen"
    spatial = True

    def __init__(self, object_size_m: float = 10.0, range_km: float = 35786.0, diameter_m: float = 1.0,
                 airmass: float = 1.0, exposure_s: float = 1.0, site_altitude_m: float = 0.0,
                 wavelength_m: float = 550e-9, n_layers: int = 8, ground_cn2: float = 1.7e-14,
                 rms_wind_m_s: float = 21.0, ground_wind_m_s: float = 5.0, jet_m_s: float = 30.0,
                 outer_scale_m: float = 25.0, n_radial: int = 96, n_angular: int = 64, slew_rad_s: float = 0.0):
        super().__init__(None, diameter_m, airmass, exposure_s, site_altitude_m, wavelength_m)
        self.fov_rad = _geometry(object_size_m, range_km)
        self.object_size_m, self.range_km = float(object_size_m), float(range_km)
        self.outer_scale_m = float_param(outer_scale_m, "outer_scale_m", 0.0, open_lo=True)
        self.n_layers, self.n_radial, self.n_angular = (int_param(v, f, 1) for f, v in
                                                        (("n_layers", n_layers), ("n_radial", n_radial), ("n_angular", n_angular)))
        self.slew_rad_s = float_param(slew_rad_s, "slew_rad_s", 0.0, 1.0)
        self.profile = dict(ground_cn2=float_param(ground_cn2, "ground_cn2", 0.0), rms_wind_m_s=float_param(rms_wind_m_s, "rms_wind_m_s", 0.0),
                            ground_wind_m_s=float_param(ground_wind_m_s, "ground_wind_m_s", 0.0), jet_m_s=float_param(jet_m_s, "jet_m_s", 0.0))

    def layers(self, seed: int = 0) -> Layers:
        """The :class:`~cssat.physics.turbulence.Layers` above the site (wind directions from
        ``seed``), computed once per seed."""
        cache = self.__dict__.setdefault("_layers", {})
        if seed not in cache:
            if not cache:
                cache[seed] = self._make_layers(seed)
            elif self.slew_rad_s:  # the slew adds to each wind vector: the layers again
                cache[seed] = self._make_layers(seed)
            else:  # the heights do not depend on the seed: only the wind directions are drawn again
                base = next(iter(cache.values()))
                dirs = np.random.default_rng(seed).uniform(0, 2 * math.pi, len(base.height_m))
                cache[seed] = base._replace(wind_dir_rad=dirs)
        return cache[seed]

    def _make_layers(self, seed: int) -> Layers:
        from cssat.physics.turbulence import layers_from_profile  # heavy: cssat.physics.turbulence imports scipy

        match = dict(diameter_m=self.diameter_m, exposure_s=self.exposure_s, airmass=self.airmass,
                     wavelength_m=self.wavelength_m, outer_scale_m=self.outer_scale_m)
        return layers_from_profile(self.n_layers, site_altitude_m=self.site_altitude_m, seed=seed, match=match,
                                   slew_rad_s=self.slew_rad_s, **self.profile)

    def spectrum(self, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The quadrature of every layer's intensity PSD: ``(frequency vectors (L K, 2) cycles/m,
        weights (L K,) — variances, summing to σ² —, layer index (L K,))``; computed once per seed
        (read-only arrays)."""
        cache = self.__dict__.setdefault("_spectra", {})
        if seed not in cache:
            out = self._make_spectrum(seed)
            for a in out:
                a.flags.writeable = False
            cache[seed] = out
        return cache[seed]

    def _make_spectrum(self, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        from cssat.physics.turbulence import intensity_psd  # heavy: cssat.physics.turbulence imports scipy

        lay = self.layers(seed)
        fvec, wts, idx = [], [], []
        for i in range(len(lay.height_m)):
            z = self.airmass * lay.height_m[i]
            fresnel = math.sqrt(self.wavelength_m * max(z, 1e-3))
            lo, hi = 1e-3 / max(self.diameter_m, fresnel, 1e-6), 30.0 / max(min(self.diameter_m, fresnel), 1e-6)
            lo = min(lo, 0.1 / self.outer_scale_m)
            f = np.geomspace(lo, hi, self.n_radial + 1)
            fc = np.sqrt(f[:-1] * f[1:])  # log-centres
            # directions: the half plane, dense near the normal to the wind, where the exposure's
            # averaging along the wind (sinc² of v t f·u) leaves the spectrum (its width ~ 1/(v t f))
            smear = lay.wind_m_s[i] * self.exposure_s * hi
            half = max(1, self.n_angular // 2)
            if smear > 1:
                e = np.concatenate([[0.0], np.geomspace(0.1 / smear, math.pi / 2, half)])
            else:
                e = np.linspace(0.0, math.pi / 2, half + 1)
            mid, width = 0.5 * (e[:-1] + e[1:]), np.diff(e)
            delta = np.concatenate([-mid[::-1], mid])
            da = np.concatenate([width[::-1], width])
            alpha = lay.wind_dir_rad[i] + math.pi / 2 + delta
            F, A = np.meshgrid(fc, alpha, indexing="ij")
            DA = np.broadcast_to(da, F.shape)
            psd = intensity_psd(F, A, lay, i, wavelength_m=self.wavelength_m, airmass=self.airmass,
                                diameter_m=self.diameter_m, exposure_s=self.exposure_s, outer_scale_m=self.outer_scale_m)
            w = 2 * psd * F * F * math.log(f[1] / f[0]) * DA  # f df dα = f² dln f dα, both half planes
            fvec.append(np.stack([F * np.cos(A), F * np.sin(A)], -1).reshape(-1, 2) * z)  # × z: per radian of angle
            wts.append(w.reshape(-1))
            idx.append(np.full(w.size, i))
        return np.concatenate(fvec), np.concatenate(wts), np.concatenate(idx)

    @property
    def log_variance(self) -> float:
        """σ², the variance of the log-transmission: the quadrature of the PSDs (in weak
        turbulence the scintillation index of the theory's formulas)."""
        return float(self.spectrum()[1].sum())

    @property
    def scintillation_index(self) -> float:
        """``Var Φ = e^{σ²} − 1`` of the model (≈ σ² when weak)."""
        return math.expm1(self.log_variance)

    def operator(self, m: int, n: int, *, seed: int = 0, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> LinearOperator:
        side = _side(n)
        fz, w, _ = self.spectrum(seed)
        keep = w > w.max() * 1e-9
        fz, w = fz[keep], w[keep]
        K = len(w)
        c = (np.arange(side) - (side - 1) / 2) * (self.fov_rad / side)  # pixel angles from the centre, rad
        ty, tx = np.meshgrid(c, c, indexing="ij")
        phase = 2 * math.pi * (np.stack([tx.ravel(), ty.ravel()], -1) @ fz.T)  # (n, K)
        dt = torch.float64 if dtype == torch.float64 else torch.float32
        basis = torch.cat([torch.as_tensor(np.cos(phase).T, dtype=dt), torch.as_tensor(np.sin(phase).T, dtype=dt)])  # (2K, n)
        amp = _unit_normals(m, 2 * K, seed, dt) * torch.as_tensor(np.sqrt(np.concatenate([w, w])), dtype=dt)
        g = (amp.to(device) @ basis.to(device)).double()
        return MatrixOperator(_lognormal(g, float(w.sum())).to(dtype=dtype or torch.get_default_dtype()))

    def describe(self) -> dict[str, Any]:
        from cssat.physics.turbulence import fried_parameter, isoplanatic_angle  # heavy: cssat.physics.turbulence imports scipy

        lay = self.layers()
        return {**super().describe(), "atmosphere_fov_arcsec": self.fov_rad / ARCSEC,
                "atmosphere_range_km": self.range_km, "atmosphere_object_size_m": self.object_size_m,
                "atmosphere_slew_rad_s": self.slew_rad_s,
                "atmosphere_r0_m": fried_parameter(lay, self.wavelength_m, self.airmass),
                "atmosphere_isoplanatic_arcsec": isoplanatic_angle(lay, self.wavelength_m, self.airmass) / ARCSEC}
