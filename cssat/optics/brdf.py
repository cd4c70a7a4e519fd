"""BRDF families: the paper's and the standard analytic models, batched and device-following.

Every model is an object with ``evaluate(normal, to_light, to_viewer) -> f`` for unit vectors
``(..., 3)`` (broadcast together; torch tensors or arrays), returning the BRDF in sr⁻¹ with the
input's dtype and device; it is 0 where the light or the viewer is below the surface. A facet of
area ``A`` lit by irradiance ``E`` and seen from range ``r`` then sends
``E A f (n·l)(n·v) / r²`` (W/m²) to the observer.

=====================  =========================================================================
``Lambert(albedo)``    ``albedo/π``
``Phong``              ``kd/π + ks (n + 2)/(2π) max(0, r·v)ⁿ``, ``r`` the mirror of ``l``
                       (the energy-normalised "modified" Phong of Lafortune & Willems 1994)
``BlinnPhong``         ``kd/π + ks (n + 8)/(8π) (n·h)ⁿ``, ``h`` the half vector
                       (normalisation of Akenine-Möller et al., *Real-Time Rendering*)
``CookTorrance``       ``kd/π + ks D G F / (4 (n·l)(n·v))``: GGX ``D`` (Walter et al. 2007),
                       separable Smith–GGX ``G``, Schlick's ``F`` (normal reflectance ``f0``)
``AshikhminShirley``   Ashikhmin & Shirley (2000), isotropic (``nu = nv = n``): the Fresnel-
                       weighted lobe ``(n + 1)/(8π) (n·h)ⁿ / ((h·l) max(n·l, n·v)) F(h·l)`` and
                       their coupled diffuse ``28 rd/(23π) (1 − rs)(1 − (1 − n·l/2)⁵)(1 − (1 − n·v/2)⁵)``
``PaperBRDF(cd, cs)``  the paper's Eq. 8–9: ``cd/π`` and a mirror glint of ``cs (r_Sun/a_Sun)²/(n·v)``
                       inside ``window_deg`` of the mirror direction (``glint="paper"``: the paper's
                       Eq. 9, ≈11× a flat mirror's energy over the Sun's disk), or
                       ``cs (r_Sun/a_Sun)²/(π (n·l))`` inside the Sun's disk (``glint="physical"``:
                       a real mirror of reflectance ``cs``)
=====================  =========================================================================

Assumptions: opaque, isotropic surfaces (no transmission, no polarisation), a point light (the
Sun's disk only in the paper's window), single scattering.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from cssat._checks import FieldError, float_param
from cssat.optics.photometry import SUN_RADIUS_KM, check_glint

__all__ = ["BRDF", "Lambert", "Phong", "BlinnPhong", "CookTorrance", "AshikhminShirley", "PaperBRDF", "BRDFS"]


def _dot(a: Tensor, b: Tensor) -> Tensor:
    return (a * b).sum(-1)


def _vectors(normal: Any, to_light: Any, to_viewer: Any) -> tuple[Tensor, Tensor, Tensor]:
    ref = next((x for x in (normal, to_light, to_viewer) if isinstance(x, Tensor)), None)
    dtype = ref.dtype if ref is not None and ref.is_floating_point() else torch.float64
    device = ref.device if ref is not None else None
    out = []
    for name, x in (("normal", normal), ("to_light", to_light), ("to_viewer", to_viewer)):
        t = torch.as_tensor(x, dtype=dtype, device=device)
        if t.shape[-1:] != (3,):
            raise FieldError(name, f"expected unit vectors (..., 3), got shape {tuple(t.shape)}")
        out.append(t)
    n, l, v = torch.broadcast_tensors(*out)
    return n, l, v


class BRDF:
    """A BRDF: :meth:`evaluate` in sr⁻¹. Subclasses give :meth:`_f` for front-facing inputs."""

    name = "brdf"

    def evaluate(self, normal: Any, to_light: Any, to_viewer: Any) -> Tensor:
        """``f(n, l, v)`` (sr⁻¹), ``(...)`` for unit vectors ``(..., 3)``; 0 unless ``n·l > 0`` and
        ``n·v > 0``."""
        n, l, v = _vectors(normal, to_light, to_viewer)
        nl, nv = _dot(n, l), _dot(n, v)
        front = (nl > 0) & (nv > 0)
        val = self._f(n, l, v, nl.clamp_min(1e-12), nv.clamp_min(1e-12))
        return torch.where(front, val, torch.zeros_like(val))

    __call__ = evaluate

    def _f(self, n: Tensor, l: Tensor, v: Tensor, nl: Tensor, nv: Tensor) -> Tensor:  # pragma: no cover
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        return {"brdf": self.name, **{f"brdf_{k}": v for k, v in vars(self).items() if isinstance(v, (int, float))}}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v:g}" for k, v in vars(self).items() if isinstance(v, (int, float)))
        return f"{type(self).__name__}({args})"


def _fraction(x: float, name: str) -> float:
    return float_param(x, name, 0.0, 1.0)


def _half(l: Tensor, v: Tensor) -> Tensor:
    h = l + v
    return h / h.norm(dim=-1, keepdim=True).clamp_min(1e-300)


class Lambert(BRDF):
    """``albedo/π``: a perfectly diffuse surface."""

    name = "lambert"

    def __init__(self, albedo: float = 0.5):
        self.albedo = _fraction(albedo, "albedo")

    def _f(self, n, l, v, nl, nv):
        return torch.full_like(nl, self.albedo / math.pi)


def _lobe_sum(kd: float, ks: float, names: tuple[str, str] = ("kd", "ks")) -> None:
    """Energy: a diffuse and a specular fraction that add up to at most 1 (all the light)."""
    if kd + ks > 1 + 1e-12:
        raise FieldError(names[1], f"{names[0]} + {names[1]} = {kd + ks:g} > 1 reflects more light than arrives "
                                   f"(their sum must be at most 1)")


class Phong(BRDF):
    """``kd/π + ks (n + 2)/(2π) max(0, r·v)ⁿ`` (``kd + ks ≤ 1``, ``n = shininess ≥ 0``)."""

    name = "phong"

    def __init__(self, kd: float = 0.5, ks: float = 0.3, shininess: float = 20.0):
        self.kd, self.ks = _fraction(kd, "kd"), _fraction(ks, "ks")
        self.shininess = float_param(shininess, "shininess", 0.0, 1e6)
        _lobe_sum(self.kd, self.ks)

    def _f(self, n, l, v, nl, nv):
        r = 2 * nl[..., None] * n - l
        rv = _dot(r, v).clamp_min(0)
        return self.kd / math.pi + self.ks * (self.shininess + 2) / (2 * math.pi) * rv ** self.shininess


class BlinnPhong(BRDF):
    """``kd/π + ks (n + 8)/(8π) (n·h)ⁿ``."""

    name = "blinn_phong"

    def __init__(self, kd: float = 0.5, ks: float = 0.3, shininess: float = 50.0):
        self.kd, self.ks = _fraction(kd, "kd"), _fraction(ks, "ks")
        self.shininess = float_param(shininess, "shininess", 0.0, 1e6)
        _lobe_sum(self.kd, self.ks)

    def _f(self, n, l, v, nl, nv):
        nh = _dot(n, _half(l, v)).clamp_min(0)
        return self.kd / math.pi + self.ks * (self.shininess + 8) / (8 * math.pi) * nh ** self.shininess


class CookTorrance(BRDF):
    """``kd/π + ks D G F / (4 (n·l)(n·v))`` with GGX ``D`` of ``roughness`` α, separable
    Smith–GGX ``G`` and Schlick's ``F`` of normal reflectance ``f0``."""

    name = "cook_torrance"

    def __init__(self, kd: float = 0.3, ks: float = 0.7, roughness: float = 0.3, f0: float = 0.9):
        self.kd, self.ks = _fraction(kd, "kd"), _fraction(ks, "ks")
        self.roughness = float_param(roughness, "roughness", 1e-3, 1.0)
        self.f0 = _fraction(f0, "f0")
        _lobe_sum(self.kd, self.ks)

    def _f(self, n, l, v, nl, nv):
        a2 = self.roughness ** 2
        h = _half(l, v)
        nh, vh = _dot(n, h).clamp_min(0), _dot(v, h).clamp(0, 1)
        D = a2 / (math.pi * (nh * nh * (a2 - 1) + 1) ** 2)

        def g1(x):
            return 2 * x / (x + torch.sqrt(a2 + (1 - a2) * x * x))

        F = self.f0 + (1 - self.f0) * (1 - vh) ** 5
        return self.kd / math.pi + self.ks * D * g1(nl) * g1(nv) * F / (4 * nl * nv)


class AshikhminShirley(BRDF):
    """Ashikhmin & Shirley's model, isotropic: diffuse ``rd``, specular ``rs`` (the normal
    reflectance of its Schlick Fresnel), exponent ``n``."""

    name = "ashikhmin_shirley"

    def __init__(self, rd: float = 0.4, rs: float = 0.3, n: float = 100.0):
        self.rd, self.rs = _fraction(rd, "rd"), _fraction(rs, "rs")
        self.n = float_param(n, "n", 0.0, 1e6)

    def _f(self, nn, l, v, nl, nv):
        h = _half(l, v)
        nh, hl = _dot(nn, h).clamp_min(0), _dot(h, l).clamp(1e-12, 1)
        F = self.rs + (1 - self.rs) * (1 - hl) ** 5
        spec = (self.n + 1) / (8 * math.pi) * nh ** self.n / (hl * torch.maximum(nl, nv)) * F
        diff = 28 * self.rd / (23 * math.pi) * (1 - self.rs) * (1 - (1 - nl / 2) ** 5) * (1 - (1 - nv / 2) ** 5)
        return diff + spec


class PaperBRDF(BRDF):
    """The paper's Eq. 8–9 as a BRDF: ``cd/π`` plus a glint whose brightness
    :func:`cssat.optics.facet_brightness` documents (``sun_range_km``: the object–Sun distance).

    ``glint`` (None: :data:`cssat.optics.photometry.DEFAULT_GLINT`):

    * ``"paper"``: the paper's Eq. 9 (≈11× a flat mirror's energy over the Sun's disk):
      ``cs (r_Sun/a_Sun)²/(n·v)`` when the mirror direction of the Sun lies within
      ``window_deg`` of the viewer. Not reciprocal (the window and the ``1/(n·v)`` are the paper's).
    * ``"physical"``: a mirror of reflectance ``cs`` reflecting the Sun's disk (a top-hat, uniform
      disk): ``cs (r_Sun/a_Sun)²/(π (n·l))`` when the viewer lies within the Sun's angular radius
      ``asin(a_Sun/r_Sun)`` of the mirror direction (``window_deg`` unused); over the viewing
      directions it reflects ``cs`` of the incident flux."""

    name = "paper"

    def __init__(self, cd: float = 0.8, cs: float = 0.2, window_deg: float = 0.5, sun_range_km: float = 149_597_870.7,
                 glint: str | None = None):
        self.cd, self.cs = _fraction(cd, "cd"), _fraction(cs, "cs")
        _lobe_sum(self.cd, self.cs, ("cd", "cs"))
        self.window_deg = float_param(window_deg, "window_deg", 0.0, 180.0)
        self.sun_range_km = float_param(sun_range_km, "sun_range_km", 1e3, open_lo=True)
        self.glint = check_glint(glint)

    def _f(self, n, l, v, nl, nv):
        r = 2 * nl[..., None] * n - l
        if self.glint == "physical":
            sin_a = SUN_RADIUS_KM / self.sun_range_km
            tau = _dot(r, v) >= math.sqrt(1 - sin_a**2)
            return self.cd / math.pi + tau * self.cs / (math.pi * sin_a**2 * nl)
        tau = _dot(r, v) >= math.cos(math.radians(self.window_deg))
        return self.cd / math.pi + tau * self.cs * (self.sun_range_km / SUN_RADIUS_KM) ** 2 / nv


#: the BRDF classes by name (the ``brdf`` config group's options)
BRDFS = {c.name: c for c in (Lambert, Phong, BlinnPhong, CookTorrance, AshikhminShirley, PaperBRDF)}
