"""What a sensing matrix can measure: its mean, scintillation index, effective rank and coherence."""

from __future__ import annotations

from typing import Sequence

import torch
from torch import Tensor

from cssat.sparse import sensing_dictionary

__all__ = ["sensing_stats", "effective_rank"]


def effective_rank(phi: Tensor, energy: float = 0.99) -> int:
    """The number of singular values of ``phi`` that hold ``energy`` of ``Σ σᵢ²`` (its Frobenius norm²).

    ``σᵢ²`` are the eigenvalues of the smaller Gram matrix (``ΦΦᵀ`` or ``ΦᵀΦ``, float64): the
    cumulative energies equal those of an SVD to ~1e-15 and cost a quarter of its time
    (3306 × 4096: 3.2 s against 13 s on one thread)."""
    p = phi.double()
    g = p @ p.T if p.shape[0] <= p.shape[1] else p.T @ p
    s2 = torch.linalg.eigvalsh(g).flip(0).clamp_min(0)
    e = torch.cumsum(s2, 0)
    return int(torch.searchsorted(e, energy * e[-1]).item()) + 1


def sensing_stats(phi: Tensor, shape: Sequence[int] | None = None, *, max_rows: int = 4096,
                  full: bool = True) -> dict[str, float]:
    """``phi_mean``, ``phi_scintillation_index`` (``Var/mean²`` of the entries, per pixel then
    averaged; null for a Φ that is not a positive transmission, like the paper's zero-mean one),
    ``phi_effective_rank`` (99 % of the energy; of ``Φ`` itself, so a mean-1 ``Φ`` with
    fluctuations under 10 % has rank 1: its common row holds > 99 %), ``phi_effective_rank_centered``
    (of ``Φ`` less its mean row: the independent patterns the atmosphere adds to the common
    transmission, which is what a reconstruction can use) and ``phi_coherence`` (the largest ``|⟨aᵢ, aⱼ⟩| / ‖aᵢ‖‖aⱼ‖`` over columns of
    ``ΦΨ`` for a DCT Ψ on ``shape``; of ``Φ`` when ``shape`` is None). Computed on at most
    ``max_rows`` rows of ``phi (m, N)``; ``full=False`` skips the rank and the coherence (two
    Gram eigenvalue problems and a Gram of ``N`` columns: ~9 s at 64² on one thread, minutes at 128²)."""
    p = phi[:max_rows].double()
    mean = p.mean(0)
    positive = bool(p.mean() > 3 * p.std())  # a transmission; the paper's zero-mean Φ has no index
    out = {"phi_mean": float(p.mean()), "phi_std": float(p.std()),
           "phi_scintillation_index": float((p.var(0) / mean.pow(2)).mean()) if positive else None}
    if not full:
        return out
    out["phi_effective_rank"] = effective_rank(p)
    out["phi_effective_rank_centered"] = effective_rank(p - p.mean(0, keepdim=True))
    a = sensing_dictionary(p, tuple(shape)) if shape is not None else p
    a = a / torch.linalg.vector_norm(a, dim=0).clamp_min(1e-300)
    g = (a.T @ a).abs()
    g.fill_diagonal_(0)
    out["phi_coherence"] = float(g.max())
    return out
