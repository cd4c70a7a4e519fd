"""The Fresnel shadow of an occulter (issue 25, point 1).

A star far away sends a plane wave of unit amplitude; an opaque occulter ``m(x, y) ∈ [0, 1]``
(1 = opaque; a transmission ``1 − m``) at distance ``z`` casts on the ground the field

    ``U(x, y) = 1 − (h * m)(x, y)``,  ``h(x, y) = exp(iπ (x² + y²)/(λ z)) / (i λ z)``

by Babinet's principle (the occulter's field is the unobstructed wave less that of an aperture
of its shape) and the Fresnel (paraxial) approximation of the propagation; the intensity relative
to the unocculted star is ``|U|²`` (→ 1 far from the shadow). The constant phase ``e^{ikz}`` is
dropped.

The mask is piecewise constant on square pixels of side ``pixel_m``, and the convolution is
computed **exactly for such a mask**: the kernel of each pixel is the Fresnel integral over the
pixel, separable into ``(1/2i) k(m) k(n)`` with ``k(m) = ΔC + iΔS`` — differences of the Fresnel
integrals ``C``, ``S`` (``scipy.special.fresnel``) at ``v = √(2/(λz)) pixel (m ± ½)`` — so a
straight edge or a square gives the textbook pattern to round-off, however coarse the pixels.
The convolution is a zero-padded FFT, circular on a grid just large enough that no sample of
the output wraps (overlap-save: ``H + Hg − 1`` for a mask of ``H`` rows on a ground of ``Hg``).

Sampling: the values are exact at the pixel centres; between them the pattern must be resolved
for averages over apertures, exposures or stars drawn from those samples. The local fringe
frequency at distance ``r`` from the occulter is ``r/(λz)``, so the grid must satisfy
``r_max ≤ λz/(2 pixel)`` (``r_max`` the grid's half-diagonal); :func:`shadow` raises a
:class:`~cssat._checks.FieldError` naming ``pixel_m`` otherwise.

Assumptions: scalar, paraxial (Fresnel) diffraction; a thin occulter (its silhouette); a point
star and one wavelength per call (finite stars and bandwidths are averages of such calls).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, float_param

__all__ = ["shadow", "aperture_field", "fresnel_scale", "pixel_kernel"]


def fresnel_scale(wavelength_m: float, distance_m: float) -> float:
    """``√(λ z)`` (m): 4.4 m for 550 nm at GEO's 35,786 km."""
    return math.sqrt(float(wavelength_m) * float(distance_m))


def pixel_kernel(n: int, pixel_m: float, wavelength_m: float, distance_m: float) -> np.ndarray:
    """The 1-D pixel-integrated Fresnel kernel ``k(m)``, ``m = −(n−1) … n−1`` (``(2n−1,)``
    complex128): ``k(m) = [C(v₊) − C(v₋)] + i [S(v₊) − S(v₋)]``, ``v± = √(2/(λz)) pixel (m ± ½)``;
    the 2-D kernel of a pixel offset ``(m, n)`` is ``k(m) k(n) / (2i)``."""
    from scipy.special import fresnel  # heavy: scipy.special, only for pixel_kernel()

    scale = math.sqrt(2.0 / (wavelength_m * distance_m)) * pixel_m
    edges = (np.arange(-(n - 1), n + 1) - 0.5) * scale  # 2n edges around the 2n − 1 offsets
    S, C = fresnel(edges)
    return np.diff(C) + 1j * np.diff(S)


def _ground_shape(mask: Tensor, ground: Any) -> tuple[int, int]:
    """The ground grid ``(Hg, Wg)``: the mask's, or ``ground`` — a shape ``(Hg, Wg)`` ≥ the mask's
    with ``Hg − H`` and ``Wg − W`` even (so the centres coincide) or one factor ≥ 1 (rounded to
    that parity)."""
    H, W = mask.shape[-2:]
    if ground is None:
        return H, W
    if np.ndim(ground) == 0:
        f = float_param(ground, "ground", 1.0)
        Hg, Wg = (int(round(f * n)) for n in (H, W))
        return Hg + (Hg - H) % 2, Wg + (Wg - W) % 2
    try:
        Hg, Wg = (int(v) for v in ground)
    except (TypeError, ValueError):
        raise FieldError("ground", f"expected a factor >= 1 or a shape (Hg, Wg), got {ground!r}") from None
    if Hg < H or Wg < W or (Hg - H) % 2 or (Wg - W) % 2:
        raise FieldError("ground", f"the ground grid {(Hg, Wg)} must cover the mask's {(H, W)} with an even margin on each axis")
    return Hg, Wg


def _check(mask: Tensor, pixel_m: float, wavelength_m: float, distance_m: float, ground: tuple[int, int] | None = None) -> None:
    H, W = mask.shape[-2:] if ground is None else ground
    r_max = 0.5 * math.hypot(H, W) * pixel_m  # the farthest a grid point is from the occulter's centre
    limit = wavelength_m * distance_m / (2 * pixel_m)
    if r_max > limit:
        raise FieldError("pixel_m", f"a {H} × {W} grid of {pixel_m:g} m pixels reaches {r_max:.3g} m from the occulter, where "
                                    f"the fringes (r/(λz) cycles per metre) are finer than the pixels: keep the half-diagonal "
                                    f"≤ λz/(2·pixel_m) = {limit:.3g} m (smaller pixels or a smaller grid)")


_SPECTRA: dict = {}


def _kernel_spectrum(H, W, Hg, Wg, pixel_m, wavelength_m, distance_m, cdtype, device):
    """The 2-D transfer function ``k(m) k(n)/(2i)`` on the FFT grid ``(Py, Px)``, cached (an
    inversion calls the forward hundreds of times with one geometry).

    A circular convolution of size ``P`` equals the linear one on the ground samples when
    ``P ≥ H + Hg − 1``: the full linear convolution is ``2H + Hg − 2`` long and the ground
    samples are its indices ``H − 1 … H + Hg − 2``, which nothing from beyond ``P`` wraps onto
    (overlap-save) — 511 rather than 766 for a 256² mask on its own grid, 0.44× the FFT work."""
    from scipy.fft import next_fast_len  # heavy: scipy.fft, only for _kernel_spectrum()

    key = (H, W, Hg, Wg, pixel_m, wavelength_m, distance_m, cdtype, str(device))
    hit = _SPECTRA.get(key)
    if hit is not None:
        return hit
    Py, Px = next_fast_len(H + Hg - 1), next_fast_len(W + Wg - 1)
    # offsets between a mask pixel and a ground pixel reach ±((H + Hg)/2 − 1)
    ky = torch.as_tensor(pixel_kernel((H + Hg) // 2, pixel_m, wavelength_m, distance_m), dtype=cdtype, device=device)
    kx = torch.as_tensor(pixel_kernel((W + Wg) // 2, pixel_m, wavelength_m, distance_m), dtype=cdtype, device=device)
    K = torch.fft.fft(ky, n=Py)[:, None] * (torch.fft.fft(kx, n=Px) / 2j)[None, :]
    if len(_SPECTRA) >= 16:
        _SPECTRA.pop(next(iter(_SPECTRA)))
    _SPECTRA[key] = (K, (Py, Px))
    return _SPECTRA[key]


def aperture_field(mask: Any, pixel_m: float, wavelength_m: float, distance_m: float, *,
                   check_sampling: bool = True, ground: Any = None) -> Tensor:
    """``(h * m)`` on the mask's grid: the complex field (unit incident amplitude) on the ground
    behind an *aperture* of transmission ``mask (..., H, W)``, Fresnel-propagated over
    ``distance_m``; complex, the mask's device, float64 → complex128 (float32 → complex64).
    Differentiable in ``mask``. ``check_sampling=False`` skips the fringe-sampling check (the
    values at the pixel centres are exact either way; only what is drawn from them between the
    centres needs it). ``ground``: a larger ground grid, centred on the mask's, same pixels —
    ``(Hg, Wg)`` or a factor — on which the field is returned ``(..., Hg, Wg)`` (the fringes
    beyond the occulter's own extent, at no extra cost to the unknowns)."""
    pixel_m = float_param(pixel_m, "pixel_m", 0.0, open_lo=True)
    wavelength_m = float_param(wavelength_m, "wavelength_m", 0.0, open_lo=True)
    distance_m = float_param(distance_m, "distance_m", 0.0, open_lo=True)
    m = torch.as_tensor(mask)
    if not m.is_floating_point():
        m = m.to(torch.float64)
    if m.ndim < 2:
        raise FieldError("mask", f"expected an occulter mask (..., H, W), got shape {tuple(m.shape)}")
    if not bool(torch.isfinite(m).all()):
        raise FieldError("mask", "the mask must be finite (1 = opaque, 0 = clear)")
    Hg, Wg = _ground_shape(m, ground)
    if check_sampling:
        _check(m, pixel_m, wavelength_m, distance_m, (Hg, Wg))
    H, W = m.shape[-2:]
    cdtype = torch.complex128 if m.dtype == torch.float64 else torch.complex64
    K, (Py, Px) = _kernel_spectrum(H, W, Hg, Wg, pixel_m, wavelength_m, distance_m, cdtype, m.device)
    full = torch.fft.ifft2(torch.fft.fft2(m.to(cdtype), s=(Py, Px)) * K)
    return full[..., H - 1:H - 1 + Hg, W - 1:W - 1 + Wg]


def shadow(mask: Any, pixel_m: float, wavelength_m: float | Any, distance_m: float, *,
           weights: Any = None, check_sampling: bool = True, ground: Any = None) -> Tensor:
    """The ground intensity ``|1 − (h * m)|²`` behind an opaque occulter ``mask (..., H, W)``
    (1 = opaque) on a grid of ``pixel_m``, relative to the unocculted star (→ 1 far from the
    shadow), for a point star at ``wavelength_m`` over ``distance_m``; on the mask's own grid
    (padded internally). ``wavelength_m`` may be a sequence: the intensity averaged over it with
    ``weights`` (a filter's band × the star's spectrum; default equal). Real, the mask's dtype
    and device; differentiable in ``mask``. ``ground``: a larger ground grid ``(Hg, Wg)`` (or a
    factor) centred on the mask's, as in :func:`aperture_field`."""
    lams = np.atleast_1d(np.asarray(wavelength_m, dtype=np.float64))
    w = np.ones(len(lams)) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != lams.shape or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
        raise FieldError("weights", f"expected {len(lams)} finite weights >= 0 with a positive sum")
    w = w / w.sum()
    out = None
    for lam, wi in zip(lams, w):
        f = aperture_field(mask, pixel_m, float(lam), distance_m, check_sampling=check_sampling, ground=ground)
        I = ((1 - f.real) ** 2 + f.imag ** 2) * float(wi)  # |1 − f|², without abs's square root
        out = I if out is None else out + I
    return out.to(torch.as_tensor(mask).dtype if torch.as_tensor(mask).is_floating_point() else torch.float64)
