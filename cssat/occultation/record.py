"""What telescopes record of a moving shadow (issue 25, point 1).

A telescope at ``p`` in the fundamental plane sees the shadow pattern ``I(x)`` move past at the
velocity ``v``: its ``k``-th exposure, starting at ``t_k``, is the pattern averaged over

* its aperture (a disk of ``aperture_m``; a central obstruction is neglected),
* the exposure (the segment ``p − v [t_k, t_k + t_exp]``),
* the star's disk projected to the satellite's distance (``star_diameter_m = θ⋆ z``; a linear
  limb darkening ``I(μ) ∝ 1 − u (1 − μ)``), and
* the filter's bandwidth (:func:`~cssat.occultation.shadow` ``wavelength_m`` as a sequence),

so the series is the pattern convolved with one kernel (aperture ∗ star ∗ smear) and sampled at
``p − v (t_k + t_exp/2)``. Then the noise (:func:`noisy`): photon (Poisson) counts of a star of
V magnitude ``star_mag`` (cssat's V zero point, ``throughput``), Gaussian read noise and the
atmosphere's scintillation — a gain per telescope frozen over the event (``gains``, drawn by
:func:`~cssat.occultation.nuisance.scintillation_gains` from the turbulence model: the event is
shorter than the scintillation's decorrelation time) times a white ``1 + σ_I ε`` per exposure
(the rest of the short-exposure index; without ``gains``, the whole index of
:func:`cssat.physics.turbulence.scintillation_index` for that aperture, exposure and airmass).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
import torch.nn.functional as Fn
from torch import Tensor

from cssat._checks import FieldError, float_param, int_param
from cssat.physics.photometry import magnitude_to_photon_rate

__all__ = ["pattern_kernel", "smooth", "record", "noisy", "photons"]


def pattern_kernel(pixel_m: float, *, aperture_m: float = 0.0, star_diameter_m: float = 0.0, limb_darkening: float = 0.6,
                   smear_m: float = 0.0, smear_dir: Any = (1.0, 0.0), supersample: int = 9) -> np.ndarray:
    """The averaging kernel ``(k, k)`` on the pattern's pixels (rows north, columns east), sum 1:
    a uniform disk of ``aperture_m`` ∗ a limb-darkened disk of ``star_diameter_m`` ∗ a segment
    of ``smear_m`` along ``smear_dir`` (east, north). Each part is sampled on one sub-pixel grid
    of ``supersample`` (made odd: a sub-sample at every pixel's centre) points a pixel, the parts
    convolved there, and the result integrated over the pixels once — binning each part first
    would add a pixel-wide box blur per part (three at 0.2 m pixels: the blur of a 1–1.5 mas star
    at GEO). A part narrower than a sub-sample is a point."""
    from scipy.signal import fftconvolve  # heavy: scipy.signal, only for pattern_kernel()

    pixel_m = float_param(pixel_m, "pixel_m", 0.0, open_lo=True)
    ss = int_param(supersample, "supersample", 1, 64)
    ss += 1 - ss % 2  # odd
    h = pixel_m / ss  # the sub-sample's pitch
    u = float_param(limb_darkening, "limb_darkening", 0.0, 1.0)

    def grid(radius_m):
        n = int(math.ceil(radius_m / h)) + 1
        c = np.arange(-n, n + 1) * h
        yy, xx = np.meshgrid(c, c, indexing="ij")
        return yy, xx

    def normed(w):
        if not w.sum() > 0:  # narrower than a sub-sample: a point
            return np.ones((1, 1))
        return w / w.sum()

    parts = []
    a = float_param(aperture_m, "aperture_m", 0.0)
    if a > 0:
        yy, xx = grid(a / 2)
        parts.append(normed((np.hypot(xx, yy) <= a / 2).astype(float)))
    s = float_param(star_diameter_m, "star_diameter_m", 0.0)
    if s > 0:
        yy, xx = grid(s / 2)
        r = np.hypot(xx, yy) / (s / 2)
        mu = np.sqrt(np.clip(1 - r * r, 0, None))
        parts.append(normed(np.where(r <= 1, 1 - u * (1 - mu), 0.0)))
    L = float_param(smear_m, "smear_m", 0.0)
    if L > 0:
        d = np.asarray(smear_dir, dtype=np.float64).reshape(2)
        d = d / np.linalg.norm(d)
        yy, xx = grid(L / 2)
        t = np.linspace(-L / 2, L / 2, max(int(4 * L / h), 2))
        w = np.zeros_like(xx)
        c = (xx.shape[0] - 1) // 2
        ix = np.clip(np.round(t * d[0] / h).astype(int) + c, 0, xx.shape[1] - 1)
        iy = np.clip(np.round(t * d[1] / h).astype(int) + c, 0, xx.shape[0] - 1)
        np.add.at(w, (iy, ix), 1.0)
        parts.append(normed(w))
    out = np.ones((1, 1))
    for k in parts:
        out = fftconvolve(out, k)
    K = (out.shape[0] - 1) // 2  # half-width in sub-samples (odd, centred: every part is)
    n = int(math.ceil((K - (ss - 1) // 2) / ss)) if K > (ss - 1) // 2 else 0
    pad = n * ss + (ss - 1) // 2 - K
    out = np.pad(np.clip(out, 0, None), pad)
    out = out.reshape(2 * n + 1, ss, 2 * n + 1, ss).sum((1, 3))
    return out / out.sum()


def smooth(I: Tensor, kernel: np.ndarray) -> Tensor:
    """The pattern ``I (..., H, W)`` averaged by ``kernel`` (linear convolution; 1 — the
    unocculted star — outside the grid). Differentiable in ``I``."""
    if kernel.shape == (1, 1):
        return I
    k = torch.as_tensor(kernel, dtype=I.dtype, device=I.device)
    H, W = I.shape[-2:]
    kh, kw = k.shape
    s = (H + kh - 1, W + kw - 1)
    F = torch.fft.rfft2(I - 1, s=s) * torch.fft.rfft2(k, s=s)
    full = torch.fft.irfft2(F, s=s)
    return full[..., kh // 2:kh // 2 + H, kw // 2:kw // 2 + W] + 1


def record(I: Tensor, pixel_m: float, positions_m: Any, velocity_m_s: Any, times_s: Any) -> Tensor:
    """The pattern ``I (..., H, W)`` (already :func:`smooth`-ed; any leading batch axes) sampled
    by telescopes at ``positions_m (J, 2)`` (east, north of the grid's centre, m) while it moves
    at ``velocity_m_s (2,)``: ``(..., J, K)`` at ``times_s (K,)`` (the exposures' mid-times; the
    pattern's centre passes the grid's centre at t = 0) — bilinear between the pixel centres,
    1 outside the grid. Differentiable in ``I`` (and in the positions, velocity and times when
    they are tensors)."""
    def tensor(x):  # a tensor keeps its graph (offsets and speeds fitted through autograd)
        if isinstance(x, Tensor):
            return x.to(dtype=I.dtype, device=I.device)
        return torch.as_tensor(np.asarray(x, dtype=np.float64), dtype=I.dtype, device=I.device)

    P, v, t = tensor(positions_m).reshape(-1, 2), tensor(velocity_m_s).reshape(2), tensor(times_s).reshape(-1)
    if I.ndim < 2:
        raise FieldError("pattern", f"expected patterns (..., H, W), got shape {tuple(I.shape)}")
    H, W = I.shape[-2:]
    batch = I.shape[:-2]
    xy = P[:, None, :] - t[None, :, None] * v  # (J, K, 2) where each telescope is in the pattern's frame
    gx = xy[..., 0] / (W * pixel_m / 2)  # grid_sample's [-1, 1] across the pixel edges (align_corners=False)
    gy = xy[..., 1] / (H * pixel_m / 2)
    grid = torch.stack([gx, gy], -1)[None]
    out = Fn.grid_sample((I - 1).reshape(1, -1, H, W), grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    return out[0].reshape(*batch, *out.shape[-2:]) + 1


def photons(star_mag: float, aperture_m: float, exposure_s: float, throughput: float = 0.5) -> float:
    """Photo-electrons of the unocculted star per exposure: ``F₀ 10^(−0.4 V) (π D²/4) τ t``."""
    return magnitude_to_photon_rate(float(star_mag)) * math.pi * aperture_m ** 2 / 4 * throughput * exposure_s


def noisy(series: Tensor, star_mag: float, aperture_m: float, exposure_s: float, *, throughput: float = 0.5,
          read_noise_e: float = 5.0, scintillation: bool = True, airmass: float = 1.0, gains: Any = None,
          scintillation_sigma: float | None = None, generator: torch.Generator | None = None) -> tuple[Tensor, Tensor]:
    """The recorded series with noise, relative to the unocculted star, and its 1σ: photon counts
    ``Poisson(N⋆ g_j I (1 + σ_I ε))``, read noise, divided by ``N⋆`` (:func:`photons`). ``gains``
    ``(J,)``: a frozen gain per telescope (rows; :func:`~cssat.occultation.nuisance.scintillation_gains`),
    default 1; ``σ_I`` the white scintillation per exposure: ``scintillation_sigma`` when given,
    else the short-exposure index of the aperture at ``airmass`` (0 without ``scintillation``).
    The 1σ is what an observer would assign from the *measured* counts ``c`` (not the true
    intensity, which the observer does not have): ``√(max(c, 1) + r² + (σ_I c)²) / N⋆``."""
    N = photons(star_mag, aperture_m, exposure_s, throughput)
    sig_i = 0.0
    if scintillation_sigma is not None:
        sig_i = float_param(scintillation_sigma, "scintillation_sigma", 0.0)
    elif scintillation:
        from cssat.physics.turbulence import scintillation_index  # heavy: cssat.physics.turbulence imports scipy

        sig_i = math.sqrt(scintillation_index(aperture_m, airmass, exposure_s))
    s = series.double().cpu().clamp_min(0)
    if gains is not None:
        gj = torch.as_tensor(np.asarray(gains, dtype=np.float64)).reshape(-1, *([1] * (s.ndim - 1)))
        if gj.shape[0] != s.shape[0]:
            raise FieldError("gains", f"expected one gain per telescope ({s.shape[0]}), got {gj.shape[0]}")
        s = s * gj.clamp_min(0)
    g = generator or torch.Generator().manual_seed(0)
    scint = 1 + sig_i * torch.randn(s.shape, generator=g, dtype=torch.float64)
    counts = torch.poisson((N * s * scint).clamp_min(0), generator=g)
    counts = counts + read_noise_e * torch.randn(s.shape, generator=g, dtype=torch.float64)
    c = counts.clamp_min(1.0)
    sigma = torch.sqrt(c + read_noise_e ** 2 + (sig_i * c) ** 2) / N
    return (counts / N).to(series.dtype).to(series.device), sigma.to(series.dtype).to(series.device)
