"""Earthshine: sunlight reflected by the Earth onto the satellite, then by the satellite to the observer.

**Model and assumptions.**

* The Earth is a sphere of radius ``R⊕`` (6378.137 km) with a **Lambertian surface of uniform
  albedo** ``A`` (default 0.3, the Earth's Bond albedo is ≈ 0.29–0.31; lumos-sat's Lambertian
  Earth BRDF has the same form, ``A/π``). No clouds, oceans' glint, atmosphere or limb effects.
* The Sun is a point at ``sun_km`` (its rays parallel across the Earth at 1 AU to 4·10⁻⁵ rad).
* The cap of the Earth visible from the satellite (polar angle ``θ ≤ arccos(R⊕/r)`` about the
  sub-satellite point) is cut into patches: Gauss–Legendre nodes in ``cos θ`` times uniform
  azimuths. A patch of area ``dA`` at ``p`` with normal ``n`` sends the satellite the irradiance

  .. math::
      dE = I_0 \\frac{A}{\\pi} (n\\cdot s)^+ \\frac{(n\\cdot d)\\, dA}{|x - p|^2}            (E1)

  from the direction ``l = (p − x)/|p − x|`` (``s`` the unit vector to the Sun, ``d = −l``, ``x``
  the satellite). Each patch is a point source for the satellite's facets: facet ``i`` sends the
  observer ``dE · A_i f_i(N_i, l, V) (N_i·l)^+ (N_i·V)^+ / r_topo²`` — the same BRDF as sunlight.
  With the paper's Eq. 8–9 (``brdf=None``) only the diffuse term ``C_d/π`` is used: the glint
  window of Eq. 9 is normalised to the solar disk and has no meaning for an extended Earth.
* Facet self-shadowing is not cast for earthshine; the Earth is not eclipsed by the Moon.

Closed form for a far satellite (the test's reference): a Lambert sphere's irradiance at distance
``D ≫ R⊕`` is ``(2/3) A I₀ (R⊕/D)² p(α)`` with ``p`` the Lambert-sphere phase function and ``α``
the Sun–Earth–satellite angle (:func:`cssat.optics.passbands.lambert_sphere_phase`).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, float_param, int_param
from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2, facet_brightness
from cssat.scene.mesh import Mesh, as_mesh

if TYPE_CHECKING:
    from cssat._types import Array

__all__ = ["EARTH_RADIUS_KM", "EARTH_ALBEDO", "earth_patches", "earthshine_irradiance", "earthshine_brightness"]

EARTH_RADIUS_KM = 6378.137
EARTH_ALBEDO = 0.3


def _positions(x, name: str, T: int | None = None) -> Tensor:
    t = torch.as_tensor(x, dtype=torch.float64)
    t = t[None] if t.ndim == 1 else t
    if t.ndim != 2 or t.shape[1] != 3 or not bool(torch.isfinite(t).all()):
        raise FieldError(name, f"expected finite positions (T, 3) or (3,) in km, got shape {tuple(t.shape)}")
    if T is not None and t.shape[0] not in (1, T):
        raise FieldError(name, f"expected 1 or {T} positions, got {t.shape[0]}")
    return t if T is None else t.expand(T, 3)


def earth_patches(sat_km: Array, n_theta: int = 32, n_phi: int = 64,
                  earth_radius_km: float = EARTH_RADIUS_KM) -> tuple[Tensor, Tensor]:
    """The Earth's cap visible from each satellite position: ``(normals (T, K, 3), areas_km2 (T, K))``
    with ``K = n_theta · n_phi`` (Gauss–Legendre in ``cos θ`` on ``[R⊕/r, 1]``, midpoint in azimuth).
    The areas sum to the cap's ``2π R⊕² (1 − R⊕/r)``."""
    n_theta, n_phi = int_param(n_theta, "n_theta", 2), int_param(n_phi, "n_phi", 4)
    x = _positions(sat_km, "sat_km")
    r = torch.linalg.vector_norm(x, dim=1)
    if bool((r <= earth_radius_km).any()):
        raise FieldError("sat_km", f"satellite inside the Earth (|x| <= {earth_radius_km} km)")
    z = x / r[:, None]
    dev = x.device
    helper = torch.where((z[:, 2].abs() < 0.9)[:, None], torch.tensor([0.0, 0.0, 1.0], dtype=x.dtype, device=dev),
                         torch.tensor([1.0, 0.0, 0.0], dtype=x.dtype, device=dev))
    e1 = torch.linalg.cross(helper, z)
    e1 = e1 / torch.linalg.vector_norm(e1, dim=1, keepdim=True)
    e2 = torch.linalg.cross(z, e1)
    g, w = np.polynomial.legendre.leggauss(n_theta)
    u0 = (earth_radius_km / r)[:, None]  # (T, 1) cos θ_max
    u = u0 + (1 - u0) * torch.as_tensor((g + 1) / 2, dtype=x.dtype, device=dev)  # (T, n_theta)
    wu = (1 - u0) * torch.as_tensor(w / 2, dtype=x.dtype, device=dev)
    psi = (torch.arange(n_phi, dtype=x.dtype, device=dev) + 0.5) * (2 * np.pi / n_phi)
    sin_t = (1 - u**2).clamp_min(0).sqrt()
    cp, sp = torch.cos(psi), torch.sin(psi)
    n = (u[:, :, None, None] * z[:, None, None, :]
         + (sin_t[:, :, None] * cp)[..., None] * e1[:, None, None, :]
         + (sin_t[:, :, None] * sp)[..., None] * e2[:, None, None, :])
    area = (wu[:, :, None] * (2 * np.pi / n_phi) * earth_radius_km**2).expand(-1, -1, n_phi)
    T = x.shape[0]
    return n.reshape(T, -1, 3), area.reshape(T, -1)


def earthshine_irradiance(sat_km: Array, sun_km: Array, *, albedo: float = EARTH_ALBEDO, irradiance: float = SOLAR_IRRADIANCE_W_M2,
                          n_theta: int = 32, n_phi: int = 64,
                          earth_radius_km: float = EARTH_RADIUS_KM) -> tuple[Tensor, Tensor]:
    """Eq. E1 for every visible patch: ``(directions (T, K, 3), irradiance (T, K))`` — unit vectors
    from the satellite to each patch (the frame of ``sat_km``, e.g. GCRS) and the irradiance in W/m²
    each patch gives a surface facing it (float64, on the device of ``sat_km``). Their sum is the
    irradiance on a sphere's cross-section."""
    albedo = float_param(albedo, "albedo", 0.0, 1.0)
    x = _positions(sat_km, "sat_km")
    T = x.shape[0]
    s = _positions(sun_km, "sun_km", T).to(x.device)
    n, dA = earth_patches(x, n_theta, n_phi, earth_radius_km)
    p = n * earth_radius_km
    sun_dir = s[:, None, :] - p
    sun_dir = sun_dir / torch.linalg.vector_norm(sun_dir, dim=2, keepdim=True)
    to_sat = x[:, None, :] - p
    dist = torch.linalg.vector_norm(to_sat, dim=2)
    d = to_sat / dist[..., None]
    lit = (n * sun_dir).sum(2).clamp_min(0)
    emit = (n * d).sum(2).clamp_min(0)
    E = irradiance * albedo / np.pi * lit * emit * dA / dist**2  # km² / km²: W/m²
    return -d, E


def earthshine_brightness(mesh: Mesh, sat_km: Array, sun_km: Array, observer_km: Array, *, rotation: Array | None = None, albedo: float = EARTH_ALBEDO,
                          irradiance: float = SOLAR_IRRADIANCE_W_M2, brdf: Any = None, materials: Any = None,
                          n_theta: int = 32, n_phi: int = 64, earth_radius_km: float = EARTH_RADIUS_KM) -> Tensor:
    """Earthshine each facet sends the observer, ``(T, F)`` W/m² (sum over facets: the total).

    ``sat_km``, ``sun_km``, ``observer_km``: positions ``(T, 3)`` (or ``(3,)``) in one inertial frame
    (GCRS km); ``rotation (T, 3, 3)`` or ``(3, 3)`` takes that frame's vectors to the mesh's body frame
    (``None``: the body frame is that frame). ``brdf``/``materials`` as in
    :func:`cssat.optics.photometry.facet_brightness` (``None``: Eq. 8's diffuse ``C_d`` term only)."""
    mesh = as_mesh(mesh)
    x = _positions(sat_km, "sat_km")
    T = x.shape[0]
    obs = _positions(observer_km, "observer_km", T).to(x.device)
    dirs, E = earthshine_irradiance(x, sun_km, albedo=albedo, irradiance=irradiance, n_theta=n_theta, n_phi=n_phi,
                                    earth_radius_km=earth_radius_km)
    v = obs - x
    rng = torch.linalg.vector_norm(v, dim=1)
    if bool((rng <= 0).any()):
        raise FieldError("observer_km", "the observer is at the satellite")
    v = v / rng[:, None]
    if rotation is not None:
        Rm = torch.as_tensor(rotation, dtype=torch.float64, device=x.device)
        Rm = Rm[None] if Rm.ndim == 2 else Rm
        if Rm.shape[-2:] != (3, 3) or Rm.shape[0] not in (1, T):
            raise FieldError("rotation", f"expected (3, 3) or ({T}, 3, 3), got {tuple(Rm.shape)}")
        dirs = torch.einsum("tij,tkj->tki", Rm.expand(T, 3, 3), dirs)
        v = torch.einsum("tij,tj->ti", Rm.expand(T, 3, 3), v)
    if brdf is None:
        mesh = dataclasses.replace(mesh, cs=np.zeros(len(mesh)))
    out = torch.zeros(T, len(mesh), dtype=torch.float64, device=x.device)
    posed = None
    if getattr(mesh, "joints", ()):  # articulated parts: posed by the Sun's direction in the body frame
        s = _positions(sun_km, "sun_km", T).to(x.device)
        sun_body = (s - x) / torch.linalg.vector_norm(s - x, dim=1, keepdim=True)
        if rotation is not None:
            sun_body = torch.einsum("tij,tj->ti", Rm.expand(T, 3, 3), sun_body)
        posed = {int(t): m for idx, m in mesh.poses(sun_body) for t in idx}
    for t in range(T):
        keep = E[t] > 0
        if not bool(keep.any()):
            continue
        k = int(keep.sum())
        b = facet_brightness(mesh if posed is None else posed[t], dirs[t][keep], v[t].expand(k, 3), range_km=rng[t], irradiance=1.0,
                             brdf=brdf, materials=materials)
        out[t] = (E[t][keep][:, None] * b).sum(0)
    return out
