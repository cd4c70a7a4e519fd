"""Surface materials real satellites carry (issue 36): each a diffuse albedo ``cd`` and a specular
fraction ``cs`` — the paper's Eq. 8–9 coefficients a facet carries (:class:`cssat.scene.Mesh`) —
and a microfacet ``roughness`` (GGX α, for :class:`cssat.optics.CookTorrance` per part).

Sources. The total solar reflectance of an opaque surface is ``1 − α``, ``α`` its solar absorptance
from Fortescue, Swinerd & Stark (eds.), *Spacecraft Systems Engineering*, 4th ed., Wiley 2011,
Table 11.3 (the values of Gilmore's *Spacecraft Thermal Control Handbook*, App. A, agree: OSR
α = 0.07). How that reflectance splits into a diffuse and a specular part is not in those tables:
the split and every roughness are ASSUMPTIONS (ranges below), except the solar cells' specular
reflectance, 0.04–0.125 (DOE/ER-0081, *Satellite Power System Brightness Due to Reflected
Sunlight*, Boeing for the US DOE, 1980; Space Solar Power Review 1(3), 1980).

==================  =====  ====  ====  =====  =============================================
material            α      cd    cs    rough  source / assumption
==================  =====  ====  ====  =====  =============================================
``solar_cell``      0.88   0.05  0.07  0.05   α of GaAs cells (Table 11.3); cs in the DOE
                                              0.04–0.125; cd = 1 − α − cs (range 0.03–0.1)
``panel_back``      —      0.08  0.02  0.5    ASSUMPTION: bare CFRP face sheet, near black
                                              (cd 0.05–0.15, cs 0–0.05)
``mli``             0.40   0.25  0.35  0.3    α of aluminised Kapton, Kapton outside (the
                                              amber blankets); split ASSUMED (crinkled foil:
                                              cd 0.15–0.35)
``mli_gold``        0.25   0.30  0.45  0.3    α of goldized Kapton; split ASSUMED as ``mli``
``osr``             0.07   0.03  0.90  0.02   α of optical solar reflectors (second-surface
                                              mirrors on radiators): a mirror, cd ASSUMED
                                              0.01–0.1
``white_paint``     0.12   0.85  0.03  0.8    α of silicate white paint (Z-93-like, diffuse
                                              by design); cs ASSUMED 0–0.05
``ge_kapton``       —      0.15  0.35  0.2    ASSUMPTION: germanium-coated black Kapton, the
                                              sunshield membranes "often used on the reflector
                                              antenna of satellites" (Dey et al. 2015, Surf.
                                              Interface Anal., doi:10.1002/sia.5867); a
                                              glossy semiconductor film, α 0.4–0.6 assumed
``aluminium``       0.24   0.16  0.60  0.1    α of polished aluminium; split ASSUMED
                                              (cs 0.4–0.7)
``black_paint``     0.95   0.04  0.01  0.6    α of black epoxy paint
``uniform``         —      0.8   0.2   0.3    the paper's single material (its Eq. 8 values)
==================  =====  ====  ====  =====  =============================================

Assumptions: one broadband (solar-weighted) reflectance per material, beginning of life (UV and
contamination darken white paint and MLI on orbit: Table 11.3 gives silicone white paint α 0.26
→ 0.29 after 1000 h UV), no wavelength dependence (cssat's passbands use one albedo for all).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cssat._checks import FieldError
from cssat.scene.mesh import Mesh

if TYPE_CHECKING:
    from typing import Sequence

__all__ = ["MATERIALS", "Material", "paint"]


@dataclass(frozen=True)
class Material:
    """A surface: diffuse albedo ``cd`` and specular fraction ``cs`` (Eq. 8; ``cd + cs ≤ 1``),
    GGX ``roughness`` α, its solar absorptance ``alpha`` (None: not tabulated) and ``source``."""

    name: str
    cd: float
    cs: float
    roughness: float
    alpha: float | None
    source: str


#: the materials by name (module docstring: values and sources)
MATERIALS: dict[str, Material] = {m.name: m for m in (
    Material("solar_cell", 0.05, 0.07, 0.05, 0.88, "Fortescue+ 2011 Tab. 11.3 (GaAs); DOE/ER-0081 1980 (cs)"),
    Material("panel_back", 0.08, 0.02, 0.5, None, "assumption: bare CFRP (cd 0.05-0.15)"),
    Material("mli", 0.25, 0.35, 0.3, 0.40, "Fortescue+ 2011 Tab. 11.3 (aluminised Kapton); split assumed"),
    Material("mli_gold", 0.30, 0.45, 0.3, 0.25, "Fortescue+ 2011 Tab. 11.3 (goldized Kapton); split assumed"),
    Material("osr", 0.03, 0.90, 0.02, 0.07, "Fortescue+ 2011 Tab. 11.3 (OSR); split assumed"),
    Material("white_paint", 0.85, 0.03, 0.8, 0.12, "Fortescue+ 2011 Tab. 11.3 (silicate white paint)"),
    Material("ge_kapton", 0.15, 0.35, 0.2, None, "assumption: Ge-coated black Kapton sunshield (Dey+ 2015); alpha 0.4-0.6"),
    Material("aluminium", 0.16, 0.60, 0.1, 0.24, "Fortescue+ 2011 Tab. 11.3 (polished aluminium); split assumed"),
    Material("black_paint", 0.04, 0.01, 0.6, 0.95, "Fortescue+ 2011 Tab. 11.3 (black epoxy paint)"),
    Material("uniform", 0.8, 0.2, 0.3, None, "the paper's Eq. 8 values, one material for every facet"),
)}

#: how a procedural model's facets are dressed: per-part real materials, or every facet one ``cd``/``cs``
MATERIAL_CHOICES = ("satellite", "uniform")


def check_material(material: str | None) -> str | None:
    """``material`` if it is one of :data:`MATERIAL_CHOICES` or None, else a FieldError."""
    if material is not None and material not in MATERIAL_CHOICES:
        raise FieldError("material", f"expected one of {list(MATERIAL_CHOICES)} (or null), got {material!r}")
    return material


def paint(mesh: Mesh, names: str | Sequence[str]) -> Mesh:
    """``mesh`` with every facet's ``cd``/``cs`` those of its material and its ``part`` the
    material's name: ``names`` one material name or ``(F,)`` names (one per facet)."""
    F = len(mesh)
    per = np.broadcast_to(np.asarray(names, dtype=object), (F,))
    labels = list(dict.fromkeys(per.tolist()))
    for n in labels:
        if n not in MATERIALS:
            raise FieldError("material", f"expected one of {sorted(MATERIALS)}, got {n!r}")
    part = np.array([labels.index(n) for n in per], dtype=np.int64)
    cd = np.array([MATERIALS[n].cd for n in labels])[part]
    cs = np.array([MATERIALS[n].cs for n in labels])[part]
    return Mesh(mesh.vertices, mesh.faces, cd, cs, name=mesh.name, part=part, part_names=tuple(labels))
