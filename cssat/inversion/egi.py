"""The extended Gaussian image (EGI) and the light curve's sensing operator in it.

Without shadowing, a body of facets with normals ``n_k``, areas ``A_k`` and one BRDF ``f``
sends, per unit solar irradiance and at unit range,

    ``y(t) = Σ_k G(t, k) a_k``,  ``G(t, k) = f(n_k, s_t, o_t) max(0, s_t·n_k) max(0, o_t·n_k)``

with ``s_t``, ``o_t`` the Sun and observer directions in the body frame and ``a_k`` the area
(× albedo, for a Lambert ``f`` of albedo 1) facing ``n_k``: the EGI (Horn 1984; Kaasalainen &
Torppa 2001). ``G`` is known exactly from the geometry — compressed sensing with a real sensing
matrix. Assumptions: no self-shadowing or occlusion (exact for convex bodies), single
scattering, one BRDF shape for every facet (its albedo goes into ``a_k``).

Unknown, mixed materials: :class:`Lobes` gives every scattering lobe its own
EGI, ``y(t) = Σ_l Σ_k G_l(t, k) a_{l,k}`` — a diffuse (Lambert) one and specular Blinn–Phong
lobes of fixed shininess, each normalised to unit reflectance at normal incidence — so each
normal's diffuse and specular reflectance are fitted, non-negative, with its area: the
"EGI per lobe" of the light-curve literature's combined scattering laws (Kaasalainen, Torppa &
Muinonen 2001 fit a Lommel–Seeliger + Lambert mix with one weight; here each normal has its own).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, float_param, int_param
from cssat.optics.brdf import Lambert
from cssat.scene import as_mesh
from cssat.sparse.differences import knn_differences
from cssat.sparse.operators import MatrixOperator

__all__ = ["EGIOperator", "Lobes", "egi", "egi_operator", "fibonacci_sphere", "egi_light_curve", "geometry_matrix", "split_lobes"]


def fibonacci_sphere(k: int, *, dtype: torch.dtype = torch.float64, device: Any = None) -> Tensor:
    """``k`` nearly uniform unit vectors ``(k, 3)`` on the sphere (the Fibonacci lattice: equal
    area per point, ``z = 1 − (2i + 1)/k``, golden-angle longitudes)."""
    k = int_param(k, "k", 1)
    i = torch.arange(k, dtype=torch.float64)
    z = 1 - (2 * i + 1) / k
    phi = math.pi * (3 - math.sqrt(5)) * i
    r = torch.sqrt(torch.clamp(1 - z * z, min=0))
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1).to(dtype=dtype, device=device)


class Lobes:
    """An EGI per scattering lobe: ``G = [G_0 | G_1 | … | G_L]`` over the same normals ``(K, 3)``,
    the unknown ``a = [a_0; a_1; …]`` ``(L+1)·K`` lobe-major. Lobe 0 is Lambert of albedo 1,
    ``G_0 = μ₀μ/π``; lobe ``l`` is a normalised Blinn–Phong lobe of shininess ``n_l``,
    ``G_l = μ₀μ (n_l + 8)/(8π) (n·h)^{n_l}`` (``μ₀ = (s·n)₊``, ``μ = (o·n)₊``, ``h`` the half
    vector of ``s`` and ``o``), so ``a_{l,k}`` is the area facing ``n_k`` times that lobe's
    reflectance. ``shininess``: the lobes' exponents (default one lobe of 100, ~7° half width in
    ``n·h``; the EGI grid must resolve it: ~1000 normals space them 6°).

    Assumptions: each facet's BRDF is a non-negative mix of these fixed lobes (its specular
    reflectance and roughness free between lobes, not continuously); no shadowing (as the EGI);
    a glint narrower than the sharpest lobe is fitted only in part. Each specular lobe is cut
    where ``(n·h)ⁿ < floor`` (default 0.1: within 12° of the mirror direction for ``n = 100``):
    a normal whose glint the data saw only in its far tail would otherwise take an area
    10⁶–10¹⁰ times its diffuse one to explain a small residual, and predict a huge glint on the
    next night. The shape taken from such an EGI uses the sum over lobes (area × total
    reflectance)."""

    name = "lobes"

    def __init__(self, shininess: Any = (100.0,), floor: float = 0.1):
        vals = [shininess] if np.isscalar(shininess) else list(shininess)
        if not vals:
            raise FieldError("shininess", "expected one or more lobe exponents (e.g. [100]), got none")
        self.shininess = tuple(float_param(v, "shininess", 1.0, 1e5) for v in vals)
        self.floor = float_param(floor, "floor", 0.0, 0.99)

    def _cut(self, n: float) -> float:
        """``(n·h)`` below which the lobe of shininess ``n`` is cut: where ``(n·h)ⁿ < floor``."""
        return self.floor ** (1.0 / n)

    @property
    def n_lobes(self) -> int:
        """``L + 1``: the diffuse lobe and the specular ones."""
        return 1 + len(self.shininess)

    def brdfs(self) -> list[Any]:
        """The lobes as :mod:`cssat.optics.brdf` objects: ``Lambert(1)``, ``BlinnPhong(0, 1, n_l)``."""
        from cssat.optics.brdf import BlinnPhong  # heavy: cssat.optics.brdf imports torch

        return [Lambert(1.0)] + [BlinnPhong(kd=0.0, ks=1.0, shininess=n) for n in self.shininess]

    def matrix(self, sun_body: np.ndarray, obs_body: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """``G (..., T, (L+1)·K)`` in numpy for ``sun_body``, ``obs_body (..., T, 3)`` and
        ``normals (K, 3)`` (the search loops' path; :func:`egi_operator` the same in torch)."""
        base = np.clip(sun_body @ normals.T, 0, None) * np.clip(obs_body @ normals.T, 0, None)
        h = sun_body + obs_body
        h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
        nh = np.clip(h @ normals.T, 0, None)
        return np.concatenate([base / math.pi] + [base * ((n + 8) / (8 * math.pi)) * np.where(nh >= self._cut(n), nh ** n, 0.0)
                                                  for n in self.shininess], -1)

    def describe(self) -> dict[str, Any]:
        return {"brdf": self.name, "brdf_shininess": list(self.shininess)}

    def __repr__(self) -> str:
        return f"Lobes(shininess={list(self.shininess)})"


def split_lobes(a: np.ndarray, normals: np.ndarray, brdf: Any, rel: float = 1e-9
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """A solved EGI ``a`` on the grid ``normals (K, 3)``: ``(normals (M, 3), areas (M,),
    lobe_areas ((L+1), M) or None, keep (K,))`` — the normals that carry area (more than ``rel``
    of the largest), their areas (summed over the lobes for :class:`Lobes`: area × total
    reflectance) and, for :class:`Lobes`, each lobe's: :func:`egi_light_curve`'s arguments."""
    a = np.asarray(a, dtype=np.float64)
    if isinstance(brdf, Lobes):  # each lobe's own threshold: a lobe's scale says nothing of another's
        A = a.reshape(brdf.n_lobes, len(normals))
        keep = (A > rel * np.maximum(A.max(1, keepdims=True), 1e-300)).any(0)
        return normals[keep], A.sum(0)[keep], A[:, keep], keep
    keep = a > rel * max(float(a.max()), 1e-300)
    return normals[keep], a[keep], None, keep


def egi_light_curve(sun_body: Any, obs_body: Any, normals: np.ndarray, areas: np.ndarray, brdf: Any = None,
                    lobe_areas: np.ndarray | None = None) -> np.ndarray:
    """A solved EGI's light curve ``(T,)`` for body-frame ``sun_body``, ``obs_body (T, 3)``:
    ``G @ areas`` of :func:`egi_operator` on ``normals (M, 3)``, or for :class:`Lobes`
    ``G @`` the lobes' areas ``lobe_areas ((L+1), M)`` stacked (:func:`split_lobes`' output);
    zeros without any normal."""
    if not len(areas):
        return np.zeros(len(np.asarray(sun_body)))
    w = np.asarray(areas if lobe_areas is None else np.asarray(lobe_areas).reshape(-1), dtype=np.float64)
    return egi_operator(sun_body, obs_body, normals, brdf).matrix().numpy() @ w


class EGIOperator(MatrixOperator):
    """``G (T, K)`` as a :class:`~cssat.sparse.MatrixOperator` (``A``/``A_adjoint``, batched rows,
    the device and dtype of its inputs), with the ``normals (K, 3)`` it was built on — for
    :class:`Lobes` ``(L+1)·K`` columns and the normals repeated per lobe (``n_lobes``), so the
    closure and the TV see one column per (lobe, normal)."""

    def __init__(self, matrix: Tensor, normals: Tensor, n_lobes: int = 1):
        super().__init__(matrix)
        self.n_lobes = n_lobes
        self.register_buffer("normals", normals.repeat(n_lobes, 1) if n_lobes > 1 else normals)

    def equalities(self) -> Any:
        """``C (3, K)``: the unknown's exact constraint ``C a = 0`` — a closed body's EGI sums to
        the zero vector, ``Σ a_k n_k = 0`` (Minkowski) — as a float64 array (the non-negative
        solvers' ``closure`` rows)."""
        return self.normals.detach().cpu().double().numpy().T

    def differences(self, k: int = 6) -> Any:
        """``D (E, K)`` sparse: the unknown's neighbours for TV — each normal to its ``k`` nearest."""
        N = self.normals.detach().cpu().double().numpy()
        if self.n_lobes == 1:
            return knn_differences(N, k)
        from scipy.sparse import block_diag  # heavy: scipy.sparse; each lobe's EGI its own neighbours

        K = len(N) // self.n_lobes
        D = knn_differences(N[:K], k)
        return block_diag([D] * self.n_lobes, format="csr")


def egi_operator(sun_body: Any, obs_body: Any, normals: Any, brdf: Any = None) -> EGIOperator:
    """The light curve's sensing operator in the EGI: ``G(t, k) = f(n_k, s_t, o_t)
    max(0, s_t·n_k) max(0, o_t·n_k)`` for ``sun_body``, ``obs_body`` ``(T, 3)`` body-frame unit
    vectors from the object and ``normals (K, 3)``; ``brdf`` a :mod:`cssat.optics.brdf` object
    (default ``Lambert(1)``: ``G = (s·n)₊(o·n)₊/π``) or :class:`Lobes` (``(T, (L+1)·K)``). Per
    unit irradiance and range: multiply by ``I₀ / r²`` for W/m². Follows the dtype and device of
    ``normals`` when it is a tensor."""
    ref = normals if isinstance(normals, Tensor) else None
    dtype = ref.dtype if ref is not None and ref.is_floating_point() else torch.float64
    device = ref.device if ref is not None else None
    S, O, N = (torch.as_tensor(x, dtype=dtype, device=device) for x in (sun_body, obs_body, normals))
    for name, x in (("sun_body", S), ("obs_body", O), ("normals", N)):
        if x.ndim != 2 or x.shape[1] != 3 or not bool(torch.isfinite(x).all()):
            raise FieldError(name, f"expected finite unit vectors (n, 3), got shape {tuple(x.shape)}")
    if S.shape != O.shape:
        raise FieldError("obs_body", f"{O.shape[0]} observer directions for {S.shape[0]} Sun directions")
    cos2 = (S @ N.T).clamp_min(0) * (O @ N.T).clamp_min(0)
    if isinstance(brdf, Lobes):
        nh = (torch.nn.functional.normalize(S + O, dim=-1, eps=1e-30) @ N.T).clamp_min(0)
        lobes = [b.evaluate(N[None], S[:, None], O[:, None]) * cos2 for b in brdf.brdfs()]
        lobes[1:] = [g * (nh >= brdf._cut(n)) for g, n in zip(lobes[1:], brdf.shininess)]
        G = torch.cat(lobes, 1)
        return EGIOperator(G, N, brdf.n_lobes)
    f = (brdf or Lambert(1.0)).evaluate(N[None], S[:, None], O[:, None])
    return EGIOperator(f * cos2, N)


def lambert_scale(brdf: Any) -> float | None:
    """``albedo/π`` when ``brdf`` is ``None`` (Lambert, albedo 1) or exactly a
    :class:`~cssat.optics.brdf.Lambert`; ``None`` for any other BRDF."""
    return 1.0 / math.pi if brdf is None else brdf.albedo / math.pi if type(brdf) is Lambert else None


def geometry_matrix(sun_body: np.ndarray, obs_body: np.ndarray, normals: np.ndarray, brdf: Any = None) -> np.ndarray:
    """:func:`egi_operator`'s ``G`` as a float64 array for the search loops: ``(..., T, K)`` for
    body-frame ``sun_body``, ``obs_body`` ``(..., T, 3)`` and ``normals (K, 3)`` — for a Lambert
    surface by two clipped products in numpy (no tensor round trip), any other BRDF through
    :func:`egi_operator` batch by batch."""
    if isinstance(brdf, Lobes):
        return brdf.matrix(sun_body, obs_body, normals)
    lam = lambert_scale(brdf)
    if lam is not None:
        return lam * np.clip(sun_body @ normals.T, 0, None) * np.clip(obs_body @ normals.T, 0, None)
    S = sun_body.reshape(-1, *sun_body.shape[-2:])
    O = obs_body.reshape(-1, *obs_body.shape[-2:])
    G = np.stack([egi_operator(s_, o_, normals, brdf).matrix().numpy() for s_, o_ in zip(S, O)])
    return G.reshape(*sun_body.shape[:-1], len(normals))


def egi(mesh: Any, *, decimals: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's own EGI: ``(normals (U, 3), areas (U,))`` — the facets' areas × their diffuse
    albedo ``cd`` summed over identical normals (rounded to ``decimals``), so that the mesh's
    Lambertian light curve without shadows is ``egi_operator(s, o, normals) @ areas``."""
    m = as_mesh(mesh)
    keep = m.areas > 0
    N = np.round(m.normals[keep], decimals) + 0.0
    w = (m.areas * m.cd)[keep]
    uniq, inv = np.unique(N, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    areas = np.bincount(inv, weights=w, minlength=len(uniq))
    # each group's normal: the area-weighted mean of its facets' own (equal to round-off)
    normals = np.stack([np.bincount(inv, weights=m.areas[keep] * m.normals[keep][:, i], minlength=len(uniq))
                        for i in range(3)], 1)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True), areas
