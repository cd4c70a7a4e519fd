"""Optical turbulence: Cn² profiles, layers, and the weak-turbulence formulas of scintillation.

Units: heights and lengths in metres, wavelengths in metres, angles in radians, times in seconds,
Cn² in m^(-2/3), Cn² dh in m^(1/3). ``airmass`` X = sec(zenith angle) stretches every path
(a layer at height h is at distance z = X h) and every Cn² dh (by X).

References: Hufnagel (1974) and Valley (1980) for the HV 5/7 profile; Bufton (1973) for the wind
profile; Roddier (1981, Prog. Optics 19) for the weak-turbulence spectra; Young (1967, AJ 72, 747)
for the empirical scintillation of a telescope; Osborn et al. (2015, MNRAS 452, 1707), who find
real scintillation ~1.5× Young's; Kornilov (2012, MNRAS 425, 1549) for the long-exposure limit.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from scipy.integrate import trapezoid as _trapezoid

from cssat._checks import FieldError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "Layers", "hufnagel_valley", "bufton_wind", "layers_from_profile", "fried_parameter", "isoplanatic_angle",
    "rytov_index", "young_index", "phase_psd", "aperture_filter", "intensity_psd", "layer_scintillation",
    "scintillation_index", "scintillation_covariance",
]


class Layers(NamedTuple):
    """A discrete turbulence profile: ``height_m (L,)`` above the telescope, ``cn2dh (L,)`` in
    m^(1/3) (zenith), ``wind_m_s (L,)`` and ``wind_dir_rad (L,)``."""

    height_m: np.ndarray
    cn2dh: np.ndarray
    wind_m_s: np.ndarray
    wind_dir_rad: np.ndarray


def hufnagel_valley(h_m: ArrayLike, ground_cn2: float = 1.7e-14, rms_wind_m_s: float = 21.0) -> np.ndarray:
    """The Hufnagel–Valley Cn²(h) (m^(-2/3)) at heights ``h_m`` above the ground:
    ``0.00594 (W/27)² (1e-5 h)^10 e^(−h/1000) + 2.7e-16 e^(−h/1500) + A e^(−h/100)``.
    The defaults ``A = 1.7e-14``, ``W = 21 m/s`` are HV 5/7: r₀ = 5 cm and θ₀ = 7 µrad at 0.5 µm."""
    h = np.asarray(h_m, dtype=np.float64)
    return (0.00594 * (rms_wind_m_s / 27.0) ** 2 * (1e-5 * h) ** 10 * np.exp(-h / 1000.0)
            + 2.7e-16 * np.exp(-h / 1500.0) + ground_cn2 * np.exp(-h / 100.0))


def bufton_wind(h_m: ArrayLike, ground_m_s: float = 5.0, jet_m_s: float = 30.0) -> np.ndarray:
    """Bufton's wind profile ``v(h) = v_g + v_jet exp(−((h − 9400)/4800)²)`` (m/s)."""
    h = np.asarray(h_m, dtype=np.float64)
    return ground_m_s + jet_m_s * np.exp(-(((h - 9400.0) / 4800.0) ** 2))


def layers_from_profile(n_layers: int = 8, h_max_m: float = 25e3, site_altitude_m: float = 0.0,
                        ground_cn2: float = 1.7e-14, rms_wind_m_s: float = 21.0, ground_wind_m_s: float = 5.0,
                        jet_m_s: float = 30.0, seed: int = 0, match: dict | None = None, slew_rad_s: float = 0.0) -> Layers:
    """``n_layers`` layers of the HV profile above an observatory at ``site_altitude_m``: the
    profile above the site is cut into bins of equal log-height from 10 m to ``h_max_m``
    (the first bin starts at the telescope), each a layer carrying the bin's integral of Cn²;
    wind from Bufton's profile with directions drawn from ``seed``.

    Where the layer sits in its bin: at the bin's Cn²-weighted height, or — with ``match``, the
    telescope's settings ``{diameter_m, exposure_s, airmass, wavelength_m, outer_scale_m}`` — at
    the height whose scintillation per unit Cn² dh (:func:`layer_scintillation`, Bufton's wind
    there) is the bin's Cn²-weighted mean of it. Then every bin keeps its part of the
    continuous-profile σ_I² (:func:`scintillation_index`) exactly, whatever ``n_layers``: the
    weighted mean height under-weights the ∫Cn² h²/v moment of long exposures (8 layers gave 0.55
    of the integral at 1 m / 1 s).

    ``slew_rad_s``: the line of sight's angular rate (a LEO pass tracked by the telescope): the
    layer at slant distance ``z = X h`` then moves across the beam at ``ω z`` on top of its wind,
    along the image's x axis — each layer's velocity is the vector sum, and the height matching
    uses the rms speed ``√(v² + (ω z)²)`` (the wind directions are random)."""
    if n_layers < 1:
        raise FieldError("n_layers", f"must be >= 1, got {n_layers}")
    edges = np.concatenate([[0.0], np.geomspace(10.0, h_max_m, n_layers)])
    h = np.linspace(0.0, h_max_m, 200001)
    c = hufnagel_valley(h + site_altitude_m, ground_cn2, rms_wind_m_s)
    height, cn2dh = np.empty(n_layers), np.empty(n_layers)
    F = None
    if match is not None:
        hf = np.concatenate([[0.0], np.geomspace(0.01, h_max_m, 600)])  # 600 × 1500: heights within 3e-4 of 4000 × 3000
        speed = np.hypot(bufton_wind(hf + site_altitude_m, ground_wind_m_s, jet_m_s), slew_rad_s * match.get("airmass", 1.0) * hf)
        F = layer_scintillation(hf, speed, n_freq=1500, **match)
    for i in range(n_layers):
        sel = (h >= edges[i]) & (h <= edges[i + 1])
        w = _trapezoid(c[sel], h[sel])
        cn2dh[i] = w
        height[i] = _trapezoid(c[sel] * h[sel], h[sel]) / w if w > 0 else 0.5 * (edges[i] + edges[i + 1])
        if F is not None and w > 0:
            height[i] = _matched_height(h[sel], c[sel], np.interp(h[sel], hf, F), height[i])
    rng = np.random.default_rng(seed)
    wind, wdir = bufton_wind(height + site_altitude_m, ground_wind_m_s, jet_m_s), rng.uniform(0, 2 * math.pi, n_layers)
    if slew_rad_s:
        X = (match or {}).get("airmass", 1.0)
        vx, vy = wind * np.cos(wdir) + slew_rad_s * X * height, wind * np.sin(wdir)
        wind, wdir = np.hypot(vx, vy), np.arctan2(vy, vx)
    return Layers(height, cn2dh, wind, wdir)


def _matched_height(h: np.ndarray, c: np.ndarray, F: np.ndarray, fallback: float) -> float:
    """The height in ``h`` (a bin, ascending) where ``F`` equals its ``c``-weighted mean over the
    bin, by linear interpolation at the first crossing; ``fallback`` when there is none."""
    target = _trapezoid(c * F, h) / _trapezoid(c, h)
    d = F - target
    cross = np.flatnonzero(np.sign(d[:-1]) != np.sign(d[1:]))
    if not cross.size or not np.isfinite(target):
        return float(fallback)
    k = cross[0]
    return float(h[k] + (h[k + 1] - h[k]) * d[k] / (d[k] - d[k + 1])) if d[k] != d[k + 1] else float(h[k])


def _exposure_average(u: np.ndarray) -> np.ndarray:
    """``A(u) = ∫₀^{2π} sinc²(u cos α) dα`` (numpy's normalised sinc): a frozen screen moving by
    ``v t`` during the exposure, averaged over the directions of the frequency vector. Tabulated
    up to u = 100 (20001-point trapezoid on [0, π/2]), ``2/u`` beyond (its asymptote, reached to
    4e-5 at u = 100)."""
    u = np.asarray(u, dtype=np.float64)
    grid, table = _exposure_table()
    inner = np.interp(np.log(np.clip(u, grid[0], grid[-1])), np.log(grid), table)
    return np.where(u <= grid[-1], inner, 2.0 / np.maximum(u, 1e-300))


def _exposure_table() -> tuple[np.ndarray, np.ndarray]:
    global _TABLE
    if _TABLE is None:
        grid = np.geomspace(1e-4, 1e2, 600)
        a = np.linspace(0.0, np.pi / 2, 20001)
        _TABLE = grid, np.array([4 * _trapezoid(np.sinc(x * np.cos(a)) ** 2, a) for x in grid])
    return _TABLE


_TABLE: tuple[np.ndarray, np.ndarray] | None = None


def layer_scintillation(height_m: ArrayLike, wind_m_s: ArrayLike, *, diameter_m: float = 1.0, exposure_s: float = 1.0,
                        airmass: float = 1.0, wavelength_m: float = 550e-9, outer_scale_m: float = 25.0,
                        n_freq: int = 2000) -> np.ndarray:
    """The scintillation index per unit ``Cn² dh`` (m^(-1/3)) of a thin layer at each height
    (above the telescope, m) moving at each wind speed: the integral over the frequency plane of
    :func:`intensity_psd` for a layer of unit ``Cn² dh``,

        ``F(h) = ∫ 4 W_φ(f) sin²(πλ X h f²) |P̂(f)|² A(v t f) f df``

    with ``W_φ`` the von Kármán phase PSD per unit ``Cn² dh`` and ``A`` the exposure average over
    the frequency's direction (:func:`_exposure_average`; the wind's direction drops out of an
    isotropic pupil). Weak turbulence. ``f`` from 1e-4 cycles/m to 30 / min(D, the smallest
    Fresnel radius), ``n_freq`` log-spaced points (trapezoid in ln f). Vectorised over heights."""
    h = np.atleast_1d(np.asarray(height_m, dtype=np.float64))
    v = np.broadcast_to(np.asarray(wind_m_s, dtype=np.float64), h.shape)
    lam, X = float(wavelength_m), float(airmass)
    r_min = math.sqrt(lam * X * max(float(h[h > 0].min()) if (h > 0).any() else 1.0, 1e-2))
    f = np.geomspace(1e-4, min(1e6, 30.0 / max(min(diameter_m, r_min), 1e-9)), int(n_freq))
    W = phase_psd(f, 1.0, lam, X, outer_scale_m) * aperture_filter(f, diameter_m)
    out = np.empty(h.shape)
    for k in range(0, h.size, 256):  # blocks of heights: (256, n_freq) temporaries
        hb, vb = h[k:k + 256, None], v[k:k + 256, None]
        g = 4 * W * np.sin(np.pi * lam * X * hb * f * f) ** 2 * _exposure_average(vb * exposure_s * f) * f * f
        out[k:k + 256] = _trapezoid(g, np.log(f), axis=1)
    return out


def scintillation_index(diameter_m: float = 1.0, airmass: float = 1.0, exposure_s: float = 1.0,
                        site_altitude_m: float = 0.0, wavelength_m: float = 550e-9, *, ground_cn2: float = 1.7e-14,
                        rms_wind_m_s: float = 21.0, ground_wind_m_s: float = 5.0, jet_m_s: float = 30.0,
                        outer_scale_m: float = 25.0, h_max_m: float = 25e3, n_heights: int = 1000) -> float:
    """The long- (or short-, ``exposure_s = 0``) exposure scintillation index of a telescope from
    the continuous Hufnagel–Valley profile (HV 5/7 by default) with Bufton's wind, weak
    turbulence: ``σ_I² = X ∫₀^{h_max} Cn²(h) F(h) dh`` with ``F`` :func:`layer_scintillation`
    (the factor X is in the phase PSD) — the one source of σ_I² of every cssat atmosphere model.
    ``n_heights`` log-spaced heights from 1 cm (trapezoid in ln h; 1000 × 2000 frequencies are
    converged to 2e-6 of 6000 × 3000, in 0.09 s). For 1 m, 1 s, the zenith:
    1.24e-5: 1.42× Young's (1967) formula (σ_I 1.19× Young's), 0.63× Young's with Osborn et al.'s
    (2015) median correction of 1.5 on σ_I."""
    h = np.geomspace(0.01, h_max_m, int(n_heights))
    F = layer_scintillation(h, bufton_wind(h + site_altitude_m, ground_wind_m_s, jet_m_s), diameter_m=diameter_m,
                            exposure_s=exposure_s, airmass=airmass, wavelength_m=wavelength_m, outer_scale_m=outer_scale_m)
    c = hufnagel_valley(h + site_altitude_m, ground_cn2, rms_wind_m_s)
    return float(_trapezoid(c * F * h, np.log(h)))


def fried_parameter(layers: Layers, wavelength_m: float = 550e-9, airmass: float = 1.0) -> float:
    """r₀ = (0.423 k² X Σ Cn² dh)^(−3/5), metres."""
    k = 2 * math.pi / wavelength_m
    return float((0.423 * k * k * airmass * layers.cn2dh.sum()) ** (-3 / 5))


def isoplanatic_angle(layers: Layers, wavelength_m: float = 550e-9, airmass: float = 1.0) -> float:
    """θ₀ = (2.914 k² X^(8/3) Σ Cn² dh h^(5/3))^(−3/5), radians (Fried 1982)."""
    k = 2 * math.pi / wavelength_m
    return float((2.914 * k * k * airmass ** (8 / 3) * (layers.cn2dh * layers.height_m ** (5 / 3)).sum()) ** (-3 / 5))


def rytov_index(layers: Layers, wavelength_m: float = 550e-9, airmass: float = 1.0) -> float:
    """Scintillation index of a point source seen by a point receiver in weak turbulence (the
    Rytov variance of a plane wave): ``σ_I² = 2.25 k^(7/6) X^(11/6) Σ Cn² dh h^(5/6)``."""
    k = 2 * math.pi / wavelength_m
    return float(2.25 * k ** (7 / 6) * airmass ** (11 / 6) * (layers.cn2dh * layers.height_m ** (5 / 6)).sum())


def young_index(diameter_m: float, airmass: float = 1.0, exposure_s: float = 1.0, site_altitude_m: float = 0.0,
                osborn: float = 1.5) -> float:
    """Young's (1967) scintillation index of a telescope, ``σ_I² = (c · 0.09 D^(−2/3) X^1.75
    (2t)^(−1/2) e^(−h/8000))²`` with D in cm, times Osborn et al.'s (2015) empirical correction
    ``c`` (median ≈ 1.5; ``osborn=1`` gives Young's own). Valid for long exposures, D ≫ the
    Fresnel radius."""
    s = 0.09 * (100 * diameter_m) ** (-2 / 3) * airmass ** 1.75 * (2 * exposure_s) ** -0.5 * math.exp(-site_altitude_m / 8000)
    return float((osborn * s) ** 2)


def scintillation_covariance(separation_m: ArrayLike, diameter_m: float = 1.0, airmass: float = 1.0,
                             wavelength_m: float = 550e-9, *, layers: Layers | None = None, site_altitude_m: float = 0.0,
                             ground_cn2: float = 1.7e-14, rms_wind_m_s: float = 21.0, outer_scale_m: float = 25.0,
                             h_max_m: float = 25e3, n_heights: int = 400, n_freq: int = 3000) -> np.ndarray:
    """The covariance of the relative intensities ``δI/I`` that two telescopes of ``diameter_m``
    a ``separation_m`` apart (any shape; m, in the plane ⟂ the line of sight) record at the same
    instant (zero exposure), weak turbulence, the frozen pattern of every layer:

        ``C(d) = ∫ dh Cn²(h) ∫₀^∞ 2π f df 4 W_φ(f) sin²(πλ X h f²) |P̂(f)|² J₀(2π f d)``

    — :func:`layer_scintillation`'s integrand with the isotropic average of ``exp(2πi f·d)``,
    ``2π J₀(2π f d)``, in place of the exposure's (Roddier 1981). ``C(0)`` is
    :func:`scintillation_index` at ``exposure_s = 0``; ``C(d)/C(0)`` the correlation, which falls
    over about one aperture (a large aperture) or the largest Fresnel radius ``√(λ X h)`` (a small
    one). The continuous HV profile (``n_heights`` log-spaced heights from 1 cm), or the discrete
    ``layers`` when given. ``n_freq`` log-spaced frequencies from 1e-4 cycles/m to 30 / min(D,
    the smallest Fresnel radius)."""
    from scipy.special import j0  # heavy: scipy.special, only for scintillation_covariance()

    d = np.asarray(separation_m, dtype=np.float64)
    lam, X = float(wavelength_m), float(airmass)
    if layers is None:
        h = np.geomspace(0.01, h_max_m, int(n_heights))
        w = hufnagel_valley(h + site_altitude_m, ground_cn2, rms_wind_m_s) * h  # Cn² dh per unit ln h
        w = w * np.gradient(np.log(h))  # trapezoid-like weights in ln h
    else:
        h, w = np.asarray(layers.height_m, dtype=np.float64), np.asarray(layers.cn2dh, dtype=np.float64)
    r_min = math.sqrt(lam * X * max(float(h[h > 0].min()) if (h > 0).any() else 1.0, 1e-2))
    f = np.geomspace(1e-4, min(1e6, 30.0 / max(min(diameter_m, r_min), 1e-9)), int(n_freq))
    G = (w[:, None] * np.sin(np.pi * lam * X * h[:, None] * f * f) ** 2).sum(0)  # Σ_layers Cn² dh sin²(…)
    base = 2 * np.pi * 4 * phase_psd(f, 1.0, lam, X, outer_scale_m) * aperture_filter(f, diameter_m) * G * f * f
    flat = d.reshape(-1)
    out = np.array([_trapezoid(base * j0(2 * np.pi * f * x), np.log(f)) for x in flat])
    return out.reshape(d.shape)


def phase_psd(f: ArrayLike, cn2dh: float, wavelength_m: float = 550e-9, airmass: float = 1.0,
              outer_scale_m: float = 25.0) -> np.ndarray:
    """The von Kármán phase PSD of one layer, ``W_φ(f) = 0.38 λ⁻² X Cn² dh (f² + L₀⁻²)^(−11/6)``,
    rad² m² at spatial frequency ``f`` (cycles/m)."""
    f = np.asarray(f, dtype=np.float64)
    return 0.38 * wavelength_m ** -2 * airmass * cn2dh * (f * f + outer_scale_m ** -2) ** (-11 / 6)


def aperture_filter(f: ArrayLike, diameter_m: float) -> np.ndarray:
    """``|P̂(f)|²`` of a circular pupil normalised to 1 at f = 0: ``(2 J₁(πDf)/(πDf))²``."""
    from scipy.special import j1  # heavy: scipy.special, only for aperture_filter()

    x = np.pi * diameter_m * np.asarray(f, dtype=np.float64)
    safe = np.where(x > 1e-8, x, 1.0)
    return np.where(x > 1e-8, (2 * j1(safe) / safe) ** 2, 1.0)


def intensity_psd(f: ArrayLike, angle_rad: ArrayLike, layers: Layers, index: int, *, wavelength_m: float = 550e-9,
                  airmass: float = 1.0, diameter_m: float = 1.0, exposure_s: float = 0.0,
                  outer_scale_m: float = 25.0) -> np.ndarray:
    """The PSD of the relative intensity ``δI/I ≈ 2χ`` that layer ``index`` makes in the pupil,
    aperture- and exposure-averaged (weak turbulence, Roddier 1981):
    ``4 W_φ(f) sin²(πλz f²) |P̂(f)|² sinc²(π v t f cos(α − α_wind))`` with ``z = X h``.
    ``f`` in cycles/m, ``angle_rad`` the direction of the frequency vector."""
    z = airmass * layers.height_m[index]
    f = np.asarray(f, dtype=np.float64)
    fresnel = np.sin(np.pi * wavelength_m * z * f * f) ** 2
    shift = np.pi * layers.wind_m_s[index] * exposure_s * f * np.cos(np.asarray(angle_rad) - layers.wind_dir_rad[index])
    return (4 * phase_psd(f, layers.cn2dh[index], wavelength_m, airmass, outer_scale_m) * fresnel
            * aperture_filter(f, diameter_m) * np.sinc(shift / np.pi) ** 2)
