"""What an observer does not know about an occultation, drawn and estimated (issue 37, points 1 and 3).

**The atmosphere during the event** (:func:`scintillation_gains`). A GEO satellite's shadow
crosses a 0.5 m telescope in ~10 ms, shorter than the scintillation's decorrelation time
(the wind moves the pattern by ``v t`` ≈ 0.1–0.3 m, under one aperture), so each telescope
sees the star through a gain nearly frozen over the event: ``y_jk = g_j (1 + ε_jk) I_jk``. Its
variance is the scintillation index averaged over the event (:func:`~cssat.physics.turbulence.
scintillation_index` with ``exposure_s`` the event's duration), its correlation between
telescopes ``C(d)/C(0)`` of :func:`~cssat.physics.turbulence.scintillation_covariance` (the
layers' Fresnel scales and the apertures against the spacing); the white part ``ε`` carries the
rest of the short-exposure index, independent between exposures (an approximation: it is
correlated over ``t ≲ D/v``). Weak turbulence, the HV 5/7 profile with Bufton's wind, Gaussian
gains.

**The event's unknowns** given a silhouette (:func:`fit_nuisances`): the shadow's offset in the
fundamental plane from its prediction (a time offset along the track, a path offset across it),
the shadow speed's relative error, one gain per telescope (frozen scintillation and the
flat-field; linear, profiled out in closed form) and the star's angular diameter (profiled on a
grid: the limb-darkened disk's kernel is not differentiable in its size). The silhouette's own
position and the offset are one unknown (a shifted silhouette casts the shifted shadow), so the
offset is reported for the silhouette's centroid (:func:`mask_centroid`).

**A first guess of the offset** (:func:`dip_offset`): the centroid, in the pattern's frame, of the
samples that deviate from the unocculted star by more than 3σ.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, float_param
from cssat.occultation.fresnel import shadow
from cssat.occultation.record import pattern_kernel, record, smooth

__all__ = ["scintillation_gains", "dip_offset", "fit_nuisances", "mask_centroid", "gap_sigma"]


def scintillation_gains(positions_m: Any, aperture_m: float, exposure_s: float, event_s: float, *, airmass: float = 1.0,
                        wavelength_m: float = 550e-9, rng: np.random.Generator | None = None,
                        size: int | None = None) -> dict[str, Any]:
    """One frozen gain per telescope at ``positions_m (J, 2)`` (fundamental plane, m) over an event
    of ``event_s`` (s), and the white part's 1σ per exposure of ``exposure_s``: ``gains (J,)``
    ``= 1 + L z`` with ``L Lᵀ = σ_T² ρ(|p_i − p_j|)`` (σ_T² the index averaged over the event, ρ the
    zero-exposure correlation), ``white_sigma = √(σ²(exposure) − σ_T²)``, ``frozen_sigma = σ_T``
    and the ``correlation (J, J)``; ``size``: that many independent draws, ``gains (size, J)``.
    Assumptions: the module's docstring."""
    from cssat.physics.turbulence import scintillation_covariance, scintillation_index  # heavy: scipy

    P = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    if not len(P) or not np.all(np.isfinite(P)):
        raise FieldError("positions_m", f"expected at least one telescope's finite (east, north) in m, got {P.tolist()}")
    wavelength_m = float_param(wavelength_m, "wavelength_m", 0.0, open_lo=True)
    D = float_param(aperture_m, "array.aperture_m", 0.0, open_lo=True)
    t_exp = float_param(exposure_s, "array.exposure_s", 0.0)
    T = float_param(event_s, "event_s", 0.0)
    X = float_param(airmass, "airmass", 1.0, 40.0)
    s2_short = scintillation_index(D, X, t_exp, wavelength_m=wavelength_m)
    s2_frozen = min(scintillation_index(D, X, T, wavelength_m=wavelength_m), s2_short)
    dist = np.linalg.norm(P[:, None, :] - P[None, :, :], axis=-1)
    u, inv = np.unique(np.round(dist, 6), return_inverse=True)
    c = scintillation_covariance(u, D, X, wavelength_m)
    rho = (c / c[0])[inv].reshape(dist.shape)
    cov = s2_frozen * rho + 1e-12 * np.eye(len(P))
    rng = rng if rng is not None else np.random.default_rng(0)
    L = np.linalg.cholesky(cov)
    g = 1.0 + (L @ rng.standard_normal(len(P)) if size is None else rng.standard_normal((int(size), len(P))) @ L.T)
    return {"gains": g, "white_sigma": math.sqrt(max(s2_short - s2_frozen, 0.0)), "frozen_sigma": math.sqrt(s2_frozen),
            "correlation": rho}


def dip_offset(series: Any, sigma: Any, positions_m: Any, velocity_m_s: Any, times_s: Any, *, window: int = 9,
               nsigma: float = 3.0) -> np.ndarray:
    """The shadow's offset ``(2,)`` (east, north; m) from its predicted place, first guess: the
    weighted centroid of the sampled points ``p_j − v t_k`` (the pattern's frame). Each sample's
    ``r² = ((y/ȳ_j − 1)/σ)²`` (``ȳ_j`` the series' median: the frozen gain) is averaged over
    ``window`` exposures (a matched filter for fringes wider than one exposure); the excess
    ``e = ⟨r²⟩ − 1`` counts where it exceeds ``nsigma`` and ``√(2 ln(100 N))`` times its noise
    ``√(2/window)`` (``N`` samples: noise alone passes with ~1 % chance), and weights the centroid.
    Raises :class:`FieldError` when fewer than 3 samples pass: the shadow missed the array (or is
    too faint to see)."""
    y = np.asarray(series, dtype=np.float64)
    s = np.broadcast_to(np.asarray(sigma, dtype=np.float64), y.shape)
    med = np.median(y, axis=1, keepdims=True)
    r2 = ((y / med - 1) / (s / med)) ** 2
    k = max(1, min(int(window), y.shape[1]))
    e = np.apply_along_axis(lambda row: np.convolve(row, np.ones(k) / k, mode="same"), 1, r2) - 1
    z = max(float(nsigma), math.sqrt(2 * math.log(100 * y.size))) * math.sqrt(2 / k)
    w = np.where(e > z, e, 0.0)
    if (w > 0).sum() < 3:
        raise FieldError("event", "no telescope recorded the shadow (fewer than 3 samples deviate significantly): the path "
                                  "missed the array, or the shadow is too faint to see")
    P = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(velocity_m_s, dtype=np.float64).reshape(2)
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    pts = P[:, None, :] - t[None, :, None] * v
    return (w[..., None] * pts).sum((0, 1)) / w.sum()


def _centres(shape: tuple[int, int], pixel_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The pixel centres ``(yy, xx)`` (north, east of the grid's centre; m) of a grid ``shape``."""
    H, W = shape
    return np.meshgrid((np.arange(H) + 0.5 - H / 2) * pixel_m, (np.arange(W) + 0.5 - W / 2) * pixel_m, indexing="ij")


def mask_centroid(mask: Any, pixel_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The centroid ``(2,)`` (east, north of the grid's centre; m; rows north, columns east) of a
    mask ``(H, W)`` in [0, 1], and its 1σ ``(2,)`` if each pixel were opaque with probability
    its value (independent Bernoulli: ``var = Σ m(1−m)(x − x̄)² / (Σ m)²``) — the grey pixels'
    share of the silhouette's position."""
    m = np.clip(np.asarray(mask, dtype=np.float64), 0, 1)
    yy, xx = _centres(m.shape, pixel_m)
    A = m.sum()
    if not A > 0:
        return np.zeros(2), np.full(2, np.inf)
    c = np.array([(m * xx).sum() / A, (m * yy).sum() / A])
    v = m * (1 - m)
    var = np.array([(v * (xx - c[0]) ** 2).sum(), (v * (yy - c[1]) ** 2).sum()]) / A ** 2
    return c, np.sqrt(var)


def gap_sigma(mask: Any, pixel_m: float, across_m: Any, direction: Any, aperture_m: float) -> float:
    """The 1σ (m) of a silhouette's centroid across the track that the gaps between telescopes
    leave: each of the mask's two extreme edges across the track (``direction``, a unit vector
    east, north; where the mask's across profile first and last exceeds one pixel row) lies in
    the unobserved part of the gap between the telescopes around it (``across_m (J,)``, less one
    ``aperture_m``), uniform there (``gap/√12``); the centroid moves by half an edge's move.
    Beyond the outermost telescope the gap is open: its width is taken as the largest gap."""
    m = np.clip(np.asarray(mask, dtype=np.float64), 0, 1)
    yy, xx = _centres(m.shape, pixel_m)
    d = np.asarray(direction, dtype=np.float64).reshape(2)
    x = xx * d[0] + yy * d[1]
    edges = np.arange(x.min(), x.max() + pixel_m, pixel_m)
    prof, _ = np.histogram(x, edges, weights=m)
    inside = np.flatnonzero(prof >= 0.5)  # at least half a pixel of mask in the across bin
    t = np.sort(np.asarray(across_m, dtype=np.float64).reshape(-1))
    if not inside.size or not t.size:
        return 0.0
    gaps = np.diff(t) - aperture_m
    widest = float(gaps.max()) if gaps.size else float(aperture_m)

    def gap_at(e):
        k = np.searchsorted(t, e)
        if k == 0 or k == len(t):
            return max(widest, 0.0)
        return max(float(t[k] - t[k - 1]) - aperture_m, 0.0)

    lo, hi = edges[inside[0]], edges[inside[-1] + 1]
    return 0.5 * math.sqrt(gap_at(lo) ** 2 + gap_at(hi) ** 2) / math.sqrt(12)


def _profiled(Is, pixel_m, P, v, times, Y, S, q, s0):
    """χ² of the pattern ``Is`` with the offset ``s0 + q[:2]`` and the speed ``(1 + 1e-3 q[2])``,
    the gains profiled out (``g_j = Σ y r/σ² / Σ r²/σ²``); returns ``(χ², gains, Σ r²/σ²,
    the normalised residuals (J, K))``."""
    r = record(Is, pixel_m, P - s0 - q[:2], v * (1 + 1e-3 * q[2]), times)
    a = (Y * r / S ** 2).sum(1)
    b = (r * r / S ** 2).sum(1)
    g = a / b
    res = (Y - g[:, None] * r) / S
    return (res * res).sum(), g, b, res


def fit_nuisances(mask: Any, series: Any, sigma: Any, pixel_m: float, wavelength_m: Any, distance_m: float, positions_m: Any,
                  velocity_m_s: Any, times_s: Any, *, offset_m: Any, weights: Any = None, ground: Any = None,
                  aperture_m: float = 0.0, smear_m: float = 0.0, limb_darkening: float = 0.6,
                  diameters_m: Any = (0.0,), iters: int = 60) -> dict[str, Any]:
    """The event's nuisances for a fixed silhouette ``mask (H, W)`` (its grid centred on the
    shadow's offset ``offset_m (2,)`` from the prediction): the offset's correction, the speed's
    relative error, the gains per telescope and the star's diameter on the grid ``diameters_m``
    (its kernel with the aperture, the exposure's smear along the velocity and the assumed
    ``limb_darkening``, :func:`~cssat.occultation.record.pattern_kernel`). For each diameter the
    offset and the speed by L-BFGS on the χ² with the gains profiled out; the diameter at the
    profile's minimum. 1σ: the offset's and speed's from the profiled χ²'s Hessian (``cov = 2 H⁻¹``),
    the gains' ``1/√(Σ r²/σ²)`` × √ of that telescope's own χ² per sample (≥ 1), the diameter's where the profile rises by 1 — each scaled by
    √(χ²/dof) when it exceeds 1. Returns ``offset_m``, ``offset_cov``, ``speed_error``,
    ``speed_error_sigma``, ``gains``, ``gains_sigma``, ``diameter_m``, ``diameter_sigma_m``,
    ``diameter_upper2_m`` (the profile's 2σ upper end), ``profile`` and ``chi2_per_dof``."""
    P = torch.as_tensor(np.asarray(positions_m, dtype=np.float64).reshape(-1, 2))
    v = torch.as_tensor(np.asarray(velocity_m_s, dtype=np.float64).reshape(2))
    t = torch.as_tensor(np.asarray(times_s, dtype=np.float64).reshape(-1))
    Y = torch.as_tensor(np.asarray(series, dtype=np.float64))
    S = torch.as_tensor(np.broadcast_to(np.asarray(sigma, dtype=np.float64), tuple(Y.shape)).copy())
    s0 = torch.as_tensor(np.asarray(offset_m, dtype=np.float64).reshape(2))
    with torch.no_grad():
        I = shadow(torch.as_tensor(np.asarray(mask, dtype=np.float64)), pixel_m, wavelength_m, distance_m, weights=weights,
                   ground=ground)
    speed = float(torch.linalg.norm(v))
    dirn = (v / speed).numpy()
    dias = np.atleast_1d(np.asarray(diameters_m, dtype=np.float64))
    q = torch.zeros(3, dtype=torch.float64)
    prof, fits = [], []
    for dia in dias:
        k = pattern_kernel(pixel_m, aperture_m=aperture_m, star_diameter_m=float(dia), limb_darkening=limb_darkening,
                           smear_m=smear_m, smear_dir=dirn)
        Is = smooth(I, k)
        qv = q.clone().requires_grad_(True)
        opt = torch.optim.LBFGS([qv], lr=1.0, max_iter=iters, tolerance_grad=1e-10, tolerance_change=1e-14,
                                line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad()
            c2 = _profiled(Is, pixel_m, P, v, t, Y, S, qv, s0)[0]
            c2.backward()
            return c2

        opt.step(closure)
        with torch.no_grad():
            c2 = _profiled(Is, pixel_m, P, v, t, Y, S, qv, s0)[0]
        prof.append(float(c2))
        fits.append((qv.detach().clone(), Is))
    prof_a = np.array(prof)
    i = int(np.argmin(prof_a))
    qb, Is = fits[i]
    n, J = Y.numel(), Y.shape[0]
    red = max(1.0, prof_a[i] / max(n - J - 3 - 1, 1))
    H = torch.autograd.functional.hessian(lambda x: _profiled(Is, pixel_m, P, v, t, Y, S, x, s0)[0], qb)
    Hn = H.numpy()
    if not (np.isfinite(Hn).all() and np.linalg.eigvalsh(0.5 * (Hn + Hn.T)).min() > 0):
        cov = np.diag(np.full(3, np.inf))  # not at a minimum, or flat: unconstrained
    else:
        cov = 2 * np.linalg.inv(Hn) * red
    with torch.no_grad():
        _, g, b, res = _profiled(Is, pixel_m, P, v, t, Y, S, qb, s0)
        row = (res * res).mean(1).clamp_min(1.0)  # each telescope's own misfit
    d_lo, d_hi, d_up = _profile_interval(dias, (prof_a - prof_a[i]) / red, i)
    return {"offset_m": (s0 + qb[:2]).numpy(), "offset_cov": cov[:2, :2], "speed_error": 1e-3 * float(qb[2]),
            "speed_error_sigma": 1e-3 * math.sqrt(max(cov[2, 2], 0.0)), "gains": g.numpy(),
            "gains_sigma": (torch.sqrt(row / b)).numpy(), "diameter_m": float(dias[i]),
            "diameter_sigma_m": 0.5 * (d_hi - d_lo), "diameter_upper2_m": d_up, "profile": prof_a,
            "chi2_per_dof": prof_a[i] / max(n - J - 3 - 1, 1)}


def _profile_interval(x: np.ndarray, delta: np.ndarray, i: int) -> tuple[float, float, float]:
    """Where a profile ``delta`` (Δχ², 0 at ``i``) on the grid ``x`` crosses 1 on each side of its
    minimum (linear interpolation; the grid's end where it does not), and where it crosses 4 above."""
    def cross(level, step):
        j = i
        while 0 <= j + step < len(x) and delta[j + step] < level:
            j += step
        if not 0 <= j + step < len(x):
            return float(x[j])
        a, b = delta[j], delta[j + step]
        return float(x[j] + (x[j + step] - x[j]) * (level - a) / (b - a))

    return cross(1.0, -1), cross(1.0, 1), cross(4.0, 1)
