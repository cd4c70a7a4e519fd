"""Facet photometry: the BRDF of the paper's Eq. 8–9, visibility with self- and observer-shadowing,
light curves (Eq. 10) and apparent magnitudes.

Geometry inputs are body-frame unit vectors *from the object*: ``sun (T, 3)`` (the paper's S̄) and
``observer (T, 3)`` (V̄). Brightness is the irradiance the facet produces at the observer, in W/m²
(the paper's ``I(t)`` units with ``I₀`` in W/m²).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError
from cssat.optics.shadow_sampling import check_resolution, lit_and_seen, sampled_visibility
from cssat.optics.sun import AU_KM, SOLAR_IRRADIANCE_W_M2, SUN_MAGNITUDE_V, SUN_RADIUS_KM  # re-exported
from cssat.scene.mesh import Mesh, as_mesh

if TYPE_CHECKING:
    from cssat._types import Array, Vectors

__all__ = [
    "DEFAULT_GLINT",
    "DEFAULT_SPECTRAL",
    "GLINT_CHOICES",
    "SOLAR_IRRADIANCE_W_M2",
    "SUN_RADIUS_KM",
    "AU_KM",
    "facet_brightness",
    "shadow_mask",
    "apparent_magnitude",
    "check_unit",
]

#: the specular term of Eq. 8–9 (:func:`facet_brightness`, :class:`cssat.optics.PaperBRDF`) when
#: none is asked for: ``"paper"`` (the paper's Eq. 9, ≈11× a flat mirror's energy over the Sun's
#: disk) or ``"physical"`` (a real mirror of reflectance ``C_s`` reflecting the Sun's disk)
DEFAULT_GLINT = "physical"
GLINT_CHOICES = ("paper", "physical")


#: whether a ``band`` given to :func:`facet_brightness` colours the facets by their materials'
#: spectral reflectance (:func:`cssat.optics.passbands.band_coefficients`) when ``spectral`` is
#: None; False: every surface grey (the object has the Sun's colours)
DEFAULT_SPECTRAL = False


def check_glint(glint: str | None, field: str = "glint") -> str:
    """``glint`` (None: :data:`DEFAULT_GLINT`) if it is one of :data:`GLINT_CHOICES`, else a FieldError."""
    g = DEFAULT_GLINT if glint is None else glint
    if not isinstance(g, str) or g not in GLINT_CHOICES:
        raise FieldError(field, f"expected one of {list(GLINT_CHOICES)} (or null: {DEFAULT_GLINT!r}), got {glint!r}")
    return g


def check_unit(v: Vectors, name: str, tol: float = 1e-6) -> Tensor:
    """``v`` as a float tensor ``(T, 3)`` of unit vectors; a clear error naming ``name`` if not."""
    t = torch.as_tensor(v)
    if not t.is_floating_point():
        t = t.double()
    if t.ndim == 1:
        t = t[None]
    if t.ndim != 2 or t.shape[1] != 3:
        raise FieldError(name, f"expected unit vectors of shape (T, 3), got {tuple(t.shape)}")
    if not bool(torch.isfinite(t).all()):
        raise FieldError(name, "contains NaN or Inf")
    err = (torch.linalg.vector_norm(t.detach(), dim=1) - 1).abs()
    if t.shape[0] and float(err.max()) > tol:
        i = int(err.argmax())
        raise FieldError(name, f"row {i} has norm {float(torch.linalg.vector_norm(t[i])):.6g}, expected unit vectors")
    return t


def facet_brightness(
    mesh: Mesh,
    sun: Tensor | np.ndarray,
    observer: Tensor | np.ndarray,
    *,
    range_km: Tensor | np.ndarray | float = 1.0,
    sun_range_km: Tensor | np.ndarray | float = AU_KM,
    visible: Tensor | np.ndarray | None = None,
    sunlit: Tensor | np.ndarray | float = 1.0,
    irradiance: float = SOLAR_IRRADIANCE_W_M2,
    specular_window_deg: float = 0.5,
    shadows: bool = False,
    shadow_resolution_m: float | None = None,
    brdf: Any = None,
    materials: Any = None,
    glint: str | None = None,
    band: Any = None,
    spectral: bool | None = None,
) -> Tensor:
    """Brightness of every facet at every step, ``(T, F)``, paper Eq. 8–9.

    .. math::
        I_i = I_0 \\frac{A_i}{\\pi r_{topo}^2} (\\bar S\\cdot\\bar N_i)
              \\Big\\{ C_d (\\bar V\\cdot\\bar N_i) + \\frac{\\pi \\tau_i C_s r_{Sun}^2}{a_{Sun}^2} \\Big\\}

    for facets with ``S·N > 0`` and ``V·N > 0`` (zero otherwise), times ``sunlit`` (the fraction
    of the solar disk not hidden by the Earth; the paper ignores the eclipse) and ``visible``
    (a ``(T, F)`` mask, e.g. from :func:`shadow_mask`; or ``shadows=True`` to cast the rays here:
    from each facet's centroid, or with ``shadow_resolution_m`` (m) from points that far apart on
    it, the facet's lit-and-seen fraction — a shadow edge then moves smoothly over a coarse mesh).

    Units: ``A_i`` m², ``r_topo = range_km`` converted to m, result in W/m² at the observer.

    **Specular term, exactly as normalised here.** ``r_Sun`` is the object–Sun distance
    (``sun_range_km``) and ``a_Sun`` the solar radius, so ``(r_Sun/a_Sun)² = π/Ω_Sun`` with
    ``Ω_Sun`` the solid angle of the Sun's disk. ``τ_i = 1`` when the mirror direction of the Sun,
    ``R = 2(S·N)N − S``, lies within ``specular_window_deg`` (0.5°, Eq. 9) of ``V`` — the
    angle between incoming and outgoing rays measured in the plane of incidence *and* across it.
    The term is Eq. 8 as printed; a perfect mirror reflecting the Sun's disk would give
    ``r²/a²`` without the factor π, so this glint is π times that mirror's (a 1 m² facet with
    ``C_s = 0.2`` glints ≈ 2.9·10⁴ times as bright as a Lambertian ``C_d = 1`` facet at normal view).
    Integrated over the viewing directions, the window's 0.5° (against the Sun's angular radius
    ``α = asin(a_Sun/r_Sun)`` = 0.2665° at 1 AU) makes its energy ``2π(1 − cos 0.5°) (r_Sun/a_Sun)² C_s``
    = 11.06 ``C_s`` times the incident flux at 1 AU: ≈11× a flat mirror's.

    ``glint`` (None: :data:`DEFAULT_GLINT`): ``"paper"`` is the paper's Eq. 9 as above (≈11× a
    flat mirror's energy over the Sun's disk); ``"physical"`` is a real mirror of reflectance
    ``C_s`` reflecting the Sun's disk, a top-hat (uniform disk, no limb darkening): radiance
    ``C_s L_Sun`` (``L_Sun = I_0/(π sin²α)``, the disk's radiance) where ``V`` lies within ``α``
    of the mirror direction ``R`` — the term ``C_s (r_Sun/a_Sun)² τ_α (V·N)/(S·N)`` in the
    braces, ``τ_α = 1`` when ``angle(R, V) ≤ α`` (``specular_window_deg`` unused). Its energy over
    the viewing directions is ``C_s`` times the incident flux (exact for a uniform disk: the mean
    of ``V·N`` over the cap is ``(R·N)(1 + cos α)/2``, the cap ``2π(1 − cos α)``, their product
    ``π sin²α (S·N)``), except near grazing where part of the cap lies below the surface.

    **Other BRDFs** (:mod:`cssat.optics.brdf`): with ``brdf`` a BRDF object, every facet sends
    ``I_0 A_i f(N_i, S, V) (S·N_i)(V·N_i) / r_topo²`` (the mesh's ``cd``/``cs`` unused); with a
    sequence of BRDFs, ``materials (F,)`` gives each facet's index into it (materials as face
    attributes); with a ``{part name: BRDF}`` mapping (``"default"`` for the rest), each body of a
    multi-body mesh (``mesh.part_names``) gets its own. ``brdf=None`` is Eq. 8–9 above, unchanged.

    **Colours.** ``band`` (a :class:`~cssat.optics.passbands.Passband` or a band name) with
    ``spectral`` (None: :data:`DEFAULT_SPECTRAL`, False today): each facet's ``C_d``, ``C_s``
    become its material's band averages (:func:`cssat.optics.passbands.band_coefficients`), so the
    result is the flux in that band as a fraction of the Sun's flux through it (give it to
    :func:`cssat.optics.passbands.magnitude` with the same band). Without ``spectral`` the band is
    ignored (grey surfaces). BRDF objects (``brdf``) stay grey.
    """
    mesh = as_mesh(mesh)
    glint = check_glint(glint)
    if spectral is not None and not isinstance(spectral, bool):
        raise FieldError("spectral", f"expected true, false or null ({DEFAULT_SPECTRAL}), got {spectral!r}")
    if band is not None and (DEFAULT_SPECTRAL if spectral is None else spectral):
        from cssat.optics.passbands import band_coefficients  # heavy: the solar spectrum's table, only for colours

        mesh = band_coefficients(mesh, band)
    if getattr(mesh, "joints", ()):  # articulated parts (Sun-tracking arrays): posed at every sample
        return _per_pose(mesh, sun, observer, facet_brightness, dict(
            range_km=range_km, sun_range_km=sun_range_km, visible=visible, sunlit=sunlit, irradiance=irradiance,
            specular_window_deg=specular_window_deg, shadows=shadows, brdf=brdf, materials=materials, glint=glint,
            shadow_resolution_m=shadow_resolution_m))
    _checked_light(sunlit, shadows, shadow_resolution_m)
    sun_t = check_unit(sun, "sun")
    dtype = sun_t.dtype if sun_t.dtype in (torch.float32, torch.float64) else torch.float64
    dev = sun_t.device
    obs_t = check_unit(observer, "observer").to(dtype=dtype, device=dev)
    T = sun_t.shape[0]
    if obs_t.shape[0] != T:
        raise FieldError("observer", f"{obs_t.shape[0]} directions for {T} Sun directions")
    if not (math.isfinite(specular_window_deg) and specular_window_deg >= 0):
        raise FieldError("specular_window_deg", f"must be >= 0, got {specular_window_deg}")

    def col(x, name):
        t = torch.as_tensor(x, dtype=dtype, device=dev)
        t = t.reshape(-1, 1) if t.ndim else t.reshape(1, 1)
        if t.shape[0] not in (1, T):
            raise FieldError(name, f"expected a scalar or {T} values, got {t.shape[0]}")
        if not bool(torch.isfinite(t).all()) or bool((t < 0).any()):
            raise FieldError(name, "must be finite and >= 0")
        return t

    r_topo_m = col(range_km, "range_km") * 1e3
    if bool((r_topo_m <= 0).any()):
        raise FieldError("range_km", "must be > 0")
    r_sun = col(sun_range_km, "sun_range_km")
    lit = col(sunlit, "sunlit")

    N = torch.as_tensor(mesh.normals, dtype=dtype, device=dev)  # (F, 3)
    A = torch.as_tensor(mesh.areas, dtype=dtype, device=dev)
    cd = torch.as_tensor(mesh.cd, dtype=dtype, device=dev)
    cs = torch.as_tensor(mesh.cs, dtype=dtype, device=dev)
    sun_t = sun_t.to(dtype)
    F = len(mesh)
    if visible is not None:
        visible = torch.as_tensor(visible, device=dev)
        if tuple(visible.shape) != (T, F):
            raise FieldError("visible", f"expected shape ({T}, {F}), got {tuple(visible.shape)}")
    out = torch.empty(T, F, dtype=dtype, device=dev)
    cos_win = math.cos(math.radians(specular_window_deg))
    step = max(1, (1 << 24) // max(F, 1))  # bound the (views, facets) temporaries
    if brdf is not None:
        brdf, materials = _brdf_table(brdf, materials, F, mesh)
        step = max(1, (1 << 20) // max(F, 1))  # the BRDFs broadcast (views, facets, 3)
    for s in range(0, T, step):
        e = min(s + step, T)
        S, V = sun_t[s:e], obs_t[s:e]
        sn = S @ N.T  # (t, F) cos incidence
        vn = V @ N.T  # (t, F) cos emission
        front = (sn > 0) & (vn > 0)
        # mirror direction R = 2 (S·N) N − S; τ = 1 when angle(R, V) <= window
        tau = (2 * sn * vn - (S * V).sum(1, keepdim=True)) >= cos_win
        rs, rt, li = (x if x.shape[0] == 1 else x[s:e] for x in (r_sun, r_topo_m, lit))
        if brdf is None and glint == "physical":  # a mirror of reflectance cs reflecting the Sun's disk (top-hat)
            cos_disk = torch.sqrt(1 - (SUN_RADIUS_KM / rs) ** 2)  # (t or 1, 1): cos of the Sun's angular radius
            tau = (2 * sn * vn - (S * V).sum(1, keepdim=True)) >= cos_disk
            spec = cs * (rs / SUN_RADIUS_KM) ** 2 * tau * vn / sn.clamp_min(1e-300)
            val = irradiance * A / (math.pi * rt**2) * sn * (cd * vn + spec)
        elif brdf is None:
            spec = math.pi * cs * (rs / SUN_RADIUS_KM) ** 2 * tau
            val = irradiance * A / (math.pi * rt**2) * sn * (cd * vn + spec)
        else:
            f = torch.zeros_like(sn)
            for k, model in enumerate(brdf):
                cols = slice(None) if materials is None else torch.as_tensor(materials == k, device=dev)
                f[:, cols] = model.evaluate(N[cols][None], S[:, None], V[:, None])
            val = irradiance * A / rt**2 * sn * vn * f
        val = torch.where(front, val, torch.zeros_like(val)) * li
        if shadows:
            vis = shadow_mask(mesh, S, V, candidates=front & (li > 0), resolution_m=shadow_resolution_m)
            val = val * vis.to(device=dev, dtype=dtype)
        if visible is not None:
            val = val * visible[s:e].to(dtype)
        out[s:e] = val
    return out


#: the keyword arguments of facet_brightness / shadow_mask that hold one value per sample (or one for all)
_PER_SAMPLE = ("range_km", "sun_range_km", "sunlit", "visible", "candidates")


def _checked_light(sunlit: Any, shadows: bool, shadow_resolution_m: Any) -> None:
    """``sunlit`` in [0, 1]; ``shadow_resolution_m`` only with ``shadows`` (a FieldError)."""
    if shadow_resolution_m is not None and not shadows:
        raise FieldError("shadow_resolution_m", "resolves the cast shadows: give it with shadows=True (or leave it null)")
    sl = torch.as_tensor(sunlit, dtype=torch.float64)
    if not bool(torch.isfinite(sl).all()) or bool((sl < 0).any()) or bool((sl > 1).any()):
        raise FieldError("sunlit", "the sunlit fraction of the solar disk must be in [0, 1]")


def _per_pose(mesh: Mesh, sun: Any, observer: Any, fn: Any, kwargs: dict) -> Tensor:
    """``fn(posed mesh, sun[idx], observer[idx], **kwargs[idx])`` for each pose of an articulated
    mesh (:class:`cssat.scene.attitudes.ArticulatedMesh`: its pose follows the body-frame Sun),
    the rows put back in time order: ``(T, F)``."""
    sun_t = check_unit(sun, "sun")
    obs_t = check_unit(observer, "observer")
    T = sun_t.shape[0]
    if obs_t.shape[0] != T:
        raise FieldError("observer", f"{obs_t.shape[0]} directions for {T} Sun directions")
    out = None
    for idx, posed in mesh.poses(sun_t):
        sel = torch.as_tensor(idx)
        kw = {}
        for k, v in kwargs.items():
            if k in _PER_SAMPLE and v is not None and not isinstance(v, (int, float)):
                t = torch.as_tensor(v)
                if t.ndim and t.shape[0] == T:
                    v = t[sel.to(t.device)]
            kw[k] = v
        part = fn(posed, sun_t[sel.to(sun_t.device)], obs_t[sel.to(obs_t.device)], **kw)
        if out is None:
            out = torch.zeros((T,) + tuple(part.shape[1:]), dtype=part.dtype, device=part.device)
        out[sel.to(part.device)] = part
    return out


def _brdf_table(brdf: Any, materials: Any, F: int, mesh: Mesh) -> tuple[list, np.ndarray | None]:
    """``([BRDF, ...], materials (F,) or None)`` checked; a ``{part name: BRDF}`` mapping (and
    ``"default"`` for the parts it does not name) becomes the mesh's parts as materials."""
    if isinstance(brdf, dict):
        names = list(mesh.part_names) if mesh.part is not None else []
        missing = [n for n in names if n not in brdf] if "default" not in brdf else []
        if mesh.part is None or missing:
            raise FieldError("brdf", f"a BRDF per part needs the mesh's parts {names or '(it has none)'}; "
                                     f"missing {missing or 'parts'} (or give 'default')")
        brdf, materials = [brdf.get(n, brdf.get("default")) for n in names], mesh.part
    models = list(brdf) if isinstance(brdf, (list, tuple)) else [brdf]
    for i, m in enumerate(models):
        if not hasattr(m, "evaluate"):
            raise FieldError("brdf", f"expected BRDF objects (cssat.optics.brdf), got {type(m).__name__} at {i}")
    if len(models) == 1 and materials is None:
        return models, None
    mat = np.asarray(materials if materials is not None else np.zeros(F), dtype=np.int64)
    if mat.shape != (F,) or mat.min() < 0 or mat.max() >= len(models):
        raise FieldError("materials", f"expected {F} indices into the {len(models)} BRDFs, got shape {mat.shape}")
    return models, mat


def shadow_mask(
    mesh: Mesh,
    sun: Vectors,
    observer: Vectors,
    candidates: Tensor | np.ndarray | None = None,
    offset: float | None = None,
    engine: str = "auto",
    resolution_m: float | None = None,
) -> Tensor:
    """``(T, F)`` bool: facet ``i`` at step ``t`` is neither self-shadowed (the ray from its
    centroid towards the Sun hits the mesh) nor observer-shadowed (the ray towards the observer
    hits the mesh) — the paper's Fig. 2 (a) and (b). With ``resolution_m`` (m) instead ``(T, F)``
    float64 in [0, 1]: the facet's fraction lit and seen, from rays at the centroids of its
    sub-triangles of edges ≤ ``resolution_m`` (:mod:`cssat.optics.shadow_sampling`: a shadow
    edge then moves over a facet smoothly, not in one step).

    Rays start at the centroid moved by ``offset`` (m; default ``1e-5 ×`` the mesh radius, plus
    1 mm at most) along the facet normal, so a facet never hits itself or a coincident back facet.
    Only ``candidates`` (default: facets facing both directions) are cast; the others are False.
    All steps go in one batch through trimesh's ray engine: Embree (``embreex``) when installed,
    else trimesh's pure-Python intersector (``engine="triangle"``, ~100× slower).
    """
    mesh = as_mesh(mesh)
    if getattr(mesh, "joints", ()):  # articulated parts: the rays of each sample against its own pose
        return _per_pose(mesh, sun, observer, shadow_mask, dict(candidates=candidates, offset=offset, engine=engine,
                                                                 resolution_m=resolution_m))
    resolution_m = check_resolution(resolution_m)
    sun_t = check_unit(sun, "sun").double().cpu()
    obs_t = check_unit(observer, "observer").double().cpu()
    T, F = sun_t.shape[0], len(mesh)
    Nn = torch.as_tensor(mesh.normals)
    if candidates is None:
        cand = ((sun_t @ Nn.T) > 0) & ((obs_t @ Nn.T) > 0)
    else:
        cand = torch.as_tensor(candidates).cpu().bool()
        if tuple(cand.shape) != (T, F):
            raise FieldError("candidates", f"expected shape ({T}, {F}), got {tuple(cand.shape)}")
    out = torch.zeros(T, F, dtype=torch.bool if resolution_m is None else torch.float64)
    ti, fi = cand.nonzero(as_tuple=True)
    if len(ti) == 0:
        return out
    if offset is None:
        offset = min(1e-5 * mesh.radius, 1e-3) if mesh.radius > 0 else 1e-6
    if engine not in ("auto", "embree", "triangle"):
        raise FieldError("engine", f"expected 'auto', 'embree' or 'triangle', got {engine!r}")
    tm = mesh.to_trimesh()
    inter = None
    if engine != "triangle":
        try:
            from trimesh.ray.ray_pyembree import RayMeshIntersector  # heavy: embree (optional), only for ray casts

            inter = RayMeshIntersector(tm, scale_to_box=False)
        except Exception:
            if engine == "embree":
                raise
    if inter is None:
        from trimesh.ray.ray_triangle import RayMeshIntersector  # heavy: trimesh.ray, only for shadow_mask()

        inter = RayMeshIntersector(tm)
    threaded = "embree" in type(inter).__module__
    if resolution_m is not None:
        frac = sampled_visibility(mesh.vertices[mesh.faces], mesh.normals, ti.numpy(), fi.numpy(), sun_t.numpy(),
                                  obs_t.numpy(), resolution_m, offset, inter, threaded)
        out[ti, fi] = torch.as_tensor(frac)
        return out
    origins = mesh.centroids[fi.numpy()] + offset * mesh.normals[fi.numpy()]
    out[ti, fi] = torch.as_tensor(lit_and_seen(inter, origins, sun_t[ti].numpy(), obs_t[ti].numpy(), threaded))
    return out


def apparent_magnitude(flux_w_m2: Array | float, irradiance: float = SOLAR_IRRADIANCE_W_M2) -> Tensor:
    """Apparent visual magnitude of a flux (W/m²) relative to the Sun:
    ``m = m_Sun − 2.5 log10(flux / I₀)``, with ``m_Sun = −26.74``; ``+inf`` for zero flux."""
    f = torch.as_tensor(flux_w_m2, dtype=torch.float64)
    return SUN_MAGNITUDE_V - 2.5 * torch.log10(f / irradiance)
