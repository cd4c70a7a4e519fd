"""The silhouette from recorded shadow series (issue 25, point 3b): the full non-linear model
inverted by gradient descent through the differentiable forward (torch autograd).

Unknown: the mask ``m = σ(θ) ∈ (0, 1)`` on the pattern's grid. Objective (Adam on ``θ``):

    ``½ Σ ((R(S(m)) − y)/σ)² / n + λ_TV TV(m) + λ_bin Σ m (1 − m) / N``

with ``S`` :func:`~cssat.occultation.shadow` (wavelengths and weights), the averaging kernel and
``R`` :func:`~cssat.occultation.record.record`; ``TV`` the isotropic total variation (smoothed
by 1e-6), the binary prior pushing each pixel to 0 or 1. Minimised by L-BFGS (strong Wolfe line
search; ``method="adam"``: Adam at ``lr``), the first start ``init`` or the empty mask
(``θ = −2``), the others random; the lowest objective kept. Ambiguities: the data are intensities only, ``I = 1 − 2 Re(h∗m) + |h∗m|²``; the
in-line-holography twin (the mask propagated by −2z, which matches the linear term) is not a
real mask in [0, 1], so the bounds and the binary prior remove it. The orientation ambiguity of
intensity-only data — ``m(x)`` and its point reflection ``m(−x)`` share a far-field (Fraunhofer)
pattern — is broken in the near field the ground samples (Fresnel number ``a²/(λz) ≈ 1`` for
10 m at GEO: the reflected mask's ground pattern is the reflected pattern, which fixed telescopes
tell apart), but it returns as the Fresnel scale outgrows the object. And a mask is only
determined up to what the array samples: rows between telescopes are interpolated by the priors,
not measured; features below the aperture and the exposure's smear (~0.5 m) come back grey.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.occultation.fresnel import shadow
from cssat.occultation.record import record, smooth
from cssat.occultation.results import SilhouetteFit

__all__ = ["invert_silhouette", "iou", "registered_iou", "resample_mask", "edge_width", "feature_contrast"]


def iou(a: Any, b: Any, threshold: float = 0.5) -> float:
    """Intersection over union of two masks thresholded at ``threshold``."""
    A = np.asarray(a) >= threshold
    B = np.asarray(b) >= threshold
    union = (A | B).sum()
    return float((A & B).sum() / union) if union else 1.0


def resample_mask(mask: np.ndarray, pixel_m: float, shape: tuple[int, int], pixel_to_m: float, shift_m: tuple[float, float]) -> np.ndarray:
    """``mask (H, W)`` of ``pixel_m`` pixels, bilinearly resampled onto a centred grid ``shape`` of
    ``pixel_to_m`` pixels, displaced by ``shift_m`` (rows north, columns east; m); 0 outside."""
    from scipy.ndimage import map_coordinates  # heavy: scipy.ndimage, only for registered_iou()

    H, W = mask.shape
    r = ((np.arange(shape[0]) + 0.5 - shape[0] / 2) * pixel_to_m - shift_m[0]) / pixel_m + H / 2 - 0.5
    c = ((np.arange(shape[1]) + 0.5 - shape[1] / 2) * pixel_to_m - shift_m[1]) / pixel_m + W / 2 - 0.5
    rr, cc = np.meshgrid(r, c, indexing="ij")
    return map_coordinates(mask, [rr, cc], order=1, mode="constant", cval=0.0)


def registered_iou(mask: Any, truth: Any, *, pixel_m: float, truth_pixel_m: float, threshold: float = 0.5,
                   max_shift_m: float | None = None, subpixel: int = 4) -> dict[str, float]:
    """IoU of a reconstruction against the truth after registration, scored on the truth's grid:
    ``mask (H, W)`` on centred pixels of ``pixel_m`` (m) is resampled bilinearly onto the grid of
    ``truth (Ht, Wt)`` (centred pixels of ``truth_pixel_m``, typically finer: no inverse crime of
    one shared pixel basis), displaced by the shift that maximises the overlap of the two masks
    thresholded at ``threshold`` — first the best whole truth pixel by FFT cross-correlation
    (within ``max_shift_m``, default a quarter of the truth's extent), then a search of ``1/subpixel``
    of a pixel steps within one pixel of it — and the IoU of the two thresholded masks taken there.
    Returns ``iou`` (registered), ``iou_unregistered`` (the same resampling, no shift) and
    ``shift_north_m``, ``shift_east_m`` (the displacement applied to ``mask``). A time or
    cross-track offset of the shadow's path moves the silhouette as a whole; this score forgives
    it, so report the path's offsets beside it."""
    m = np.asarray(mask, dtype=np.float64)
    t = np.asarray(truth, dtype=np.float64)
    T = t >= threshold
    if m.ndim != 2 or T.ndim != 2:
        raise FieldError("mask", f"expected two 2-D masks, got shapes {m.shape} and {T.shape}")
    pm = float_param(pixel_m, "pixel_m", 0.0, open_lo=True)
    pt = float_param(truth_pixel_m, "truth_pixel_m", 0.0, open_lo=True)
    k = int_param(subpixel, "subpixel", 1, 64)
    reach = 0.25 * min(T.shape) * pt if max_shift_m is None else float_param(max_shift_m, "max_shift_m", 0.0)

    def score(shift):
        return iou(resample_mask(m, pm, T.shape, pt, shift), t, threshold)

    m0 = resample_mask(m, pm, T.shape, pt, (0.0, 0.0))
    A0 = (m0 >= threshold).astype(np.float64)
    # overlap(d) = Σ_x T(x) A0(x − d): the whole-pixel shift by a circular cross-correlation on a grid padded twice
    shape = (2 * T.shape[0], 2 * T.shape[1])
    corr = np.fft.irfft2(np.fft.rfft2(T.astype(np.float64), shape) * np.conj(np.fft.rfft2(A0, shape)), shape)
    dr = np.fft.fftfreq(shape[0], 1.0 / shape[0])[:, None]
    dc = np.fft.fftfreq(shape[1], 1.0 / shape[1])[None, :]
    corr = np.where(np.hypot(dr, dc) * pt <= reach, corr, -np.inf)
    i, j = np.unravel_index(int(np.argmax(corr)), corr.shape)
    base = (float(dr[i, 0]) * pt, float(dc[0, j]) * pt)
    best = (score(base), base)
    steps = np.arange(-k, k + 1) / k * pt
    for a in steps:
        for b in steps:
            cand = (base[0] + a, base[1] + b)
            if np.hypot(*cand) <= reach + 1e-12:
                best = max(best, (score(cand), cand))
    return {"iou": best[0], "iou_unregistered": iou(m0, t, threshold), "shift_north_m": float(best[1][0]), "shift_east_m": float(best[1][1])}


def _signed_distance(truth: np.ndarray, pixel_m: float) -> np.ndarray:
    """Each pixel centre's distance (m) to the truth's boundary, > 0 inside (opaque)."""
    from scipy.ndimage import distance_transform_edt  # heavy: scipy.ndimage, only for _signed_distance()

    T = np.asarray(truth) >= 0.5
    return np.where(T, distance_transform_edt(T) - 0.5, -(distance_transform_edt(~T) - 0.5)) * float(pixel_m)


def edge_width(mask: Any, truth: Any, pixel_m: float, *, reach_m: float = 3.0) -> float:
    """The 10–90 % width (m) of the reconstruction's mean edge profile: ``mask`` averaged over
    the pixels at each signed distance ``d`` from the true silhouette's boundary (bins of half a
    pixel, ``|d| ≤ reach_m``; > 0 inside), made monotone (running maximum from outside), the
    distance between where it crosses 10 % and 90 % of its rise. A perfect binary mask gives
    under a pixel (0.8: the bins' own step); an edge blurred by a Gaussian of σ gives 2.56 σ.
    ``nan`` when the profile never reaches 90 % of its rise."""
    d = _signed_distance(truth, pixel_m).reshape(-1)
    m = np.asarray(mask, dtype=np.float64).reshape(-1)
    step = float(pixel_m) / 2
    edges = np.arange(-reach_m, reach_m + step, step)
    idx = np.digitize(d, edges)
    centres, prof = [], []
    for i in range(1, len(edges)):
        sel = idx == i
        if sel.any():
            centres.append(0.5 * (edges[i - 1] + edges[i]))
            prof.append(m[sel].mean())
    if len(prof) < 3:
        return float("nan")
    c, p = np.array(centres), np.maximum.accumulate(np.array(prof))
    lo, hi = p[0], p[-1]
    if hi - lo <= 0:
        return float("nan")
    q = (p - lo) / (hi - lo)
    x10 = np.interp(0.1, q, c)  # np.interp needs increasing q: the running maximum is non-decreasing
    x90 = np.interp(0.9, q, c)
    return float(x90 - x10)


def feature_contrast(mask: Any, truth: Any, pixel_m: float, width_m: float = 0.5) -> dict[str, Any]:
    """How well features up to ``width_m`` wide come back: the true silhouette's opaque
    features that an opening by a disk of diameter ``width_m`` (rounded up to odd pixels) removes (booms, yokes, thin
    edges) and its clear gaps that a closing fills (gaps between panels), each scored by the
    reconstruction's contrast against its surroundings within ``width_m`` (the clear ones for a
    thin feature, the opaque ones for a gap): 1 for a perfect mask, 0 where the feature is lost.
    Returns ``thin_contrast``, ``gap_contrast`` (None where the truth has no such feature) and
    their pixel counts."""
    from scipy import ndimage as ndi  # heavy: scipy.ndimage, only for feature_contrast()

    T = np.asarray(truth) >= 0.5
    m = np.asarray(mask, dtype=np.float64)
    r = max(1, math.ceil(float(width_m) / float(pixel_m) / 2 - 1e-9))  # a disk ≥ width_m across: it bridges gaps ≤ width_m
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    disk = xx * xx + yy * yy <= r * r
    pad = ((r + 1, r + 1), (r + 1, r + 1))
    Tp = np.pad(T, pad)
    thin = (Tp & ~ndi.binary_opening(Tp, structure=disk))[r + 1:-r - 1, r + 1:-r - 1]
    gaps = (ndi.binary_closing(Tp, structure=disk) & ~Tp)[r + 1:-r - 1, r + 1:-r - 1]
    out: dict[str, Any] = {"thin_pixels": int(thin.sum()), "gap_pixels": int(gaps.sum())}
    if thin.any():
        ring = ndi.binary_dilation(thin, structure=disk) & ~T
        out["thin_contrast"] = float(m[thin].mean() - m[ring].mean()) if ring.any() else None
    else:
        out["thin_contrast"] = None
    if gaps.any():
        ring = ndi.binary_dilation(gaps, structure=disk) & T
        out["gap_contrast"] = float(m[ring].mean() - m[gaps].mean()) if ring.any() else None
    else:
        out["gap_contrast"] = None
    return out


def recorded(m: Tensor, pixel_m: float, wavelength_m: Any, distance_m: float, positions_m: Any, velocity_m_s: Any,
             times_s: Any, *, kernel: Any = None, weights: Any = None, ground: Any = None) -> Tensor:
    """The full forward model: the series ``(J, K)`` the telescopes record behind the mask ``m``
    (:func:`~cssat.occultation.shadow`, the averaging ``kernel``, :func:`~cssat.occultation.record.record`)."""
    k = np.ones((1, 1)) if kernel is None else np.asarray(kernel, dtype=np.float64)
    I = shadow(m, pixel_m, wavelength_m, distance_m, weights=weights, ground=ground)
    return record(smooth(I, k), pixel_m, positions_m, velocity_m_s, times_s)


def _tv(m: Tensor) -> Tensor:
    dx = m[..., :, 1:] - m[..., :, :-1]
    dy = m[..., 1:, :] - m[..., :-1, :]
    return torch.sqrt(dx[..., :-1, :] ** 2 + dy[..., :, :-1] ** 2 + 1e-6).sum()


def invert_silhouette(series: Any, sigma: Any, shape: tuple[int, int], pixel_m: float, wavelength_m: Any,
                      distance_m: float, positions_m: Any, velocity_m_s: Any, times_s: Any, *, kernel: Any = None,
                      weights: Any = None, tv: float = 1e-3, binary: float = 0.0, n_starts: int = 1, iters: int = 1500,
                      lr: float = 0.1, seed: int = 0, method: str = "lbfgs", init: Any = None, ground: Any = None,
                      dtype: torch.dtype = torch.float64, device: Any = None) -> tuple[np.ndarray, dict]:
    """The occulter mask ``(H, W)`` in [0, 1] whose recorded shadow matches ``series (J, K)``
    (1σ ``sigma``, scalar or ``(J, K)``), for the recording geometry of
    :func:`~cssat.occultation.record.record` and the averaging ``kernel``
    (:func:`~cssat.occultation.record.pattern_kernel`; None: none). ``init``: a mask ``(H, W)``
    in [0, 1] for the first start (e.g. :func:`~cssat.occultation.invert_linear`'s; clipped to
    [0.02, 0.98] before its logit), else the empty mask. ``ground``: the pattern's grid when
    larger than the mask's (:func:`~cssat.occultation.shadow`). Returns ``(mask, info)``,
    ``info`` a :class:`~cssat.occultation.results.SilhouetteFit` (a read-only mapping):
    ``loss``, ``chi2_per_sample`` of the kept start, every start's ``losses``."""
    H, W = (int_param(v, "shape", 1, 1 << 12) for v in shape)
    tv = float_param(tv, "tv", 0.0)
    binary = float_param(binary, "binary", 0.0)
    n_starts, iters = int_param(n_starts, "n_starts", 1), int_param(iters, "iters", 1)
    y = torch.as_tensor(np.asarray(series, dtype=np.float64), dtype=dtype, device=device)
    s = torch.as_tensor(np.broadcast_to(np.asarray(sigma, dtype=np.float64), tuple(y.shape)).copy(), dtype=dtype, device=device)
    g = torch.Generator(device="cpu").manual_seed(int(seed))
    if init is not None and (np.shape(init) != (H, W) or not np.isfinite(np.asarray(init, dtype=np.float64)).all()):
        raise FieldError("init", f"expected a finite mask of shape {(H, W)}, got shape {np.shape(init)}")

    def model(m):
        return recorded(m, pixel_m, wavelength_m, distance_m, positions_m, velocity_m_s, times_s, kernel=kernel,
                        weights=weights, ground=ground)

    method = choice_param(method, "method", ("lbfgs", "adam"))
    best, losses = None, []
    n = y.numel()

    def objective(m):
        r = (model(m) - y) / s
        return 0.5 * (r * r).sum() / n + tv * _tv(m) / (H * W) ** 0.5 + binary * (m * (1 - m)).sum() / (H * W), r

    for start in range(n_starts):
        if start == 0:
            th0 = torch.full((H, W), -2.0, dtype=torch.float64) if init is None else \
                torch.logit(torch.as_tensor(np.clip(np.asarray(init, dtype=np.float64), 0.02, 0.98)))
        else:
            th0 = 0.5 * torch.randn((H, W), generator=g, dtype=torch.float64) - 1.0
        theta = th0.to(dtype=dtype, device=device).requires_grad_(True)
        if method == "lbfgs":
            opt = torch.optim.LBFGS([theta], lr=1.0, max_iter=iters, max_eval=int(1.25 * iters), history_size=20,
                                    tolerance_grad=1e-9, tolerance_change=1e-12, line_search_fn="strong_wolfe")

            def closure():
                opt.zero_grad()
                loss, _ = objective(torch.sigmoid(theta))
                loss.backward()
                return loss

            opt.step(closure)
        else:
            opt = torch.optim.Adam([theta], lr=float(lr))
            for _ in range(iters):
                opt.zero_grad()
                loss, _ = objective(torch.sigmoid(theta))
                loss.backward()
                opt.step()
        with torch.no_grad():
            m = torch.sigmoid(theta)
            final, r = objective(m)
            losses.append(float(final))
            if best is None or float(final) < best[0]:
                best = (float(final), m.detach().cpu().numpy(), float((r * r).sum() / n))
    return best[1], SilhouetteFit({"loss": best[0], "chi2_per_sample": best[2], "losses": losses})
