"""What a geometry can observe of the EGI.

The light curve is ``y = G a``; the directions of the sphere it constrains are those in the row
space of ``G``. With ``G = U S Vᵀ`` (singular values ``s_i``), the components of ``a`` along
right singular vectors with ``s_i / s_1 < rcond`` are lost to any noise above that level. Per
normal ``k``, its *leverage* ``Σ_{i: s_i ≥ rcond s_1} V_ki²`` (in [0, 1]) is how much of that
normal's area the geometry can tell apart from the others: 1 — determined, 0 — invisible (never
lit while seen) or confused with others. Assumptions: those of :func:`~cssat.inversion.egi_operator`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["observability"]


def observability(sun_body: Any, obs_body: Any, normals: Any, *, brdf: Any = None, rcond: float = 1e-3) -> dict[str, Any]:
    """``{"singular_values" (min(T, K),) normalised to the largest, "effective_rank" (the count
    at ≥ rcond), "leverage" (K,), "seen" (K,) bool — the normal is ever lit while seen}`` of the
    EGI operator of this geometry."""
    from cssat.inversion.egi import egi_operator  # heavy: cssat.inversion.egi imports torch

    G = egi_operator(sun_body, obs_body, normals, brdf).matrix().double().cpu().numpy()
    if not np.any(G):
        K = G.shape[1]
        return {"singular_values": np.zeros(min(G.shape)), "effective_rank": 0, "leverage": np.zeros(K),
                "seen": np.zeros(K, bool)}
    _, s, Vt = np.linalg.svd(G, full_matrices=False)
    keep = s >= rcond * s[0]
    return {"singular_values": s / s[0], "effective_rank": int(keep.sum()),
            "leverage": (Vt[keep] ** 2).sum(0), "seen": (G > 0).any(0)}
