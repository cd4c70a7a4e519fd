"""What the light curve can tell about the image without prior knowledge of it: Fisher information
and Cramér–Rao bounds of the image's low-frequency modes.

For ``y = Φx + n`` with independent Gaussian noise of variance ``σᵢ²`` per sample (the photon,
read and systematic noise of :meth:`cssat.physics.PhotometricNoise.variance`), the Fisher
information of the image is ``F = Φᵀ Σ⁻¹ Φ`` (Kay 1993, Eq. 3.31). In the 2-D DCT basis ``Ψ``
restricted to its ``K`` lowest-frequency modes (the image's flux, gradients, second moments,
…), ``F_K = (ΦΨ_K)ᵀ Σ⁻¹ (ΦΨ_K)``; the Cramér–Rao bound of mode ``k`` is ``[F_K⁻¹]_kk`` and its
SNR is ``|α_k| / √[F_K⁻¹]_kk`` for the true coefficient ``α_k``.

What the bound proves, and what it does not. It bounds the variance of **unbiased** estimators
of the modes, given the model: Φ known exactly (an oracle), the noise Gaussian with these
variances, every mode above ``K`` known. A mode with SNR < 1 cannot be told from zero at 1σ by
any unbiased estimator that knows no more than that. It does **not** bound a biased estimator:
a prior — sparsity in a basis, non-negativity, total variation, a shape model, the set of
satellites it could be — trades bias for variance and may recover a mode the bound calls
unmeasurable (it then recovers it from the prior as much as from the light curve, and is as right
as the prior is). It is optimistic about the model (Φ and the higher modes known), so a mode it
calls measurable may still be lost by a real solver that has to estimate them; and the SNR is that
of the truth's own coefficient, not a probability of detection.

Φ unknown, its statistics known: with independent samples the light curve is a sequence of
draws whose law depends on ``x`` only through the moments of ``φᵀx``; to second order (a
Gaussian law of mean ``μ = φ̄ᵀx`` and variance ``v = xᵀCx + σ²``, ``C`` the covariance of Φ's
rows) the Fisher matrix of ``m`` samples is ``m [φ̄φ̄ᵀ/v + 2 (Cx)(Cx)ᵀ/v²]`` (Kay 1993, Eq. 3.32):
rank 2 — the flux and one more number (the image's extent through ``xᵀCx``), whatever ``m``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError

__all__ = ["dct_modes", "mode_information", "statistics_fisher"]


def dct_modes(shape: tuple[int, int], k: int) -> np.ndarray:
    """The ``k`` lowest-frequency orthonormal 2-D DCT-II basis images, ``(k, H·W)``, ordered by
    ``i + j`` then ``i`` (the DC mode first)."""
    from scipy.fft import idctn  # heavy: scipy.fft, only for dct_modes()

    H, W = shape
    order = sorted(((i, j) for i in range(H) for j in range(W)), key=lambda t: (t[0] + t[1], t[0]))[:k]
    out = np.empty((len(order), H * W))
    for r, (i, j) in enumerate(order):
        c = np.zeros((H, W))
        c[i, j] = 1.0
        out[r] = idctn(c, norm="ortho").reshape(-1)
    return out


def mode_information(phi: Tensor, noise_var: Tensor, truth: np.ndarray, n_modes: int = 64) -> dict[str, Any]:
    """Fisher information and Cramér–Rao SNR of the ``n_modes`` lowest DCT modes of ``truth
    (H, W)`` measured through ``phi (m, H·W)`` with noise variances ``noise_var (m,)`` (all zero:
    noiseless, every identifiable mode's SNR is infinite).

    Returns ``info_modes`` (modes after the DC with SNR ≥ 1), ``info_n_modes`` (``K``),
    ``info_snr_flux`` (the DC mode's SNR), ``info_snr_max`` (the best non-DC mode's),
    ``info_snr_median`` (the median non-DC SNR), ``info_rank`` (the numerical rank of ``F_K``)
    and ``info_snr (K,)`` as an array."""
    H, W = truth.shape
    K = min(int(n_modes), H * W)
    if K < 2:
        raise FieldError("n_modes", f"expected at least 2 modes, got {n_modes}")
    basis = torch.as_tensor(dct_modes((H, W), K), dtype=torch.float64)
    G = phi.double().cpu() @ basis.T  # (m, K)
    var = torch.as_tensor(noise_var, dtype=torch.float64).reshape(-1).cpu()
    if var.numel() not in (1, G.shape[0]) or not bool(torch.isfinite(var).all()) or bool((var < 0).any()):
        raise FieldError("noise_var", "expected one finite variance >= 0 per sample")
    noiseless = not bool((var > 0).any())  # every identifiable mode is then known exactly
    var = torch.ones_like(var) if noiseless else var.clamp_min(float(var.max()) * 1e-12)
    F = G.T @ (G / var.expand(G.shape[0])[:, None])
    evals, evecs = torch.linalg.eigh(F)
    keep = evals > evals.max() * 1e-13
    crb = (evecs[:, keep] ** 2 / evals[keep]).sum(1)  # diag of the pseudo-inverse
    crb = torch.where((evecs[:, ~keep] ** 2).sum(1) > 1e-6, torch.full_like(crb, math.inf), crb)  # unidentifiable
    alpha = basis @ torch.as_tensor(truth, dtype=torch.float64).reshape(-1)
    snr = (alpha.abs() / crb.sqrt()).numpy()
    if noiseless:
        snr = np.where(np.isfinite(crb.numpy()) & (alpha.abs().numpy() > 0), np.inf, 0.0)
    rest = snr[1:]
    return {"info_modes": int((rest >= 1).sum()), "info_n_modes": K, "info_snr_flux": float(snr[0]),
            "info_snr_max": float(rest.max()), "info_snr_median": float(np.median(rest)),
            "info_rank": int(keep.sum()), "info_snr": snr}


def statistics_fisher(phi: Tensor, noise_var: float, x: Tensor) -> Tensor:
    """The Fisher matrix ``(N, N)`` of ``x (N,)`` from ``m`` independent samples when only Φ's
    statistics are known: ``m [φ̄φ̄ᵀ/v + 2 (Cx)(Cx)ᵀ/v²]`` with ``φ̄`` and ``C`` the mean and
    covariance of ``phi``'s rows ``(m, N)`` and ``v = xᵀCx + noise_var`` (rank ≤ 2)."""
    p = phi.double()
    m = p.shape[0]
    mean = p.mean(0)
    d = p - mean
    xx = x.double().reshape(-1)
    Cx = d.T @ (d @ xx) / (m - 1)
    v = float(xx @ Cx) + float(noise_var)
    mu = mean.reshape(-1, 1)
    return m * (mu @ mu.T / v + 2 * Cx.reshape(-1, 1) @ Cx.reshape(1, -1) / v ** 2)
