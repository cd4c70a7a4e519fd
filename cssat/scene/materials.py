"""Surface materials real satellites carry: each a diffuse albedo ``cd`` and a specular
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
→ 0.29 after 1000 h UV). By default no wavelength dependence (cssat's passbands use one albedo
for all: the object has the Sun's colours).

**Spectral reflectance** (:data:`SPECTRA`, used when a passband integrates the flux with
``spectral=True``: :func:`cssat.optics.passbands.band_coefficients`). Each material's spectral
reflectance ``R(λ)`` at :data:`SPECTRA_NM` (300–1100 nm) gives the SHAPE; the level stays the
broadband ``cd``, ``cs`` above: ``cd(λ) = cd R(λ)/⟨R⟩☉``, ``cs(λ) = cs R(λ)/⟨R⟩☉`` with ``⟨R⟩☉``
the Sun-weighted mean of ``R`` over 300–1100 nm (the diffuse and the specular part share the
shape: an ASSUMPTION). The values are read off published curves or computed from published
optical constants at normal incidence, rounded to 0.01 — representative, not a measurement of any
one satellite's surfaces:

==================  ==========================================================================
``solar_cell``      ASSUMED shape of an AR-coated triple-junction cell under cover glass: a
                    reflectance minimum at 500–700 nm rising to the blue (the AR coating's edge)
                    and beyond ~850 nm (the GaAs band gap); cf. the laboratory spectra of solar
                    cells in Jorgensen et al. 2004, Adv. Space Res. 34, 1021
``mli``             aluminised Kapton, Kapton outside (amber): the polyimide's absorption edge
                    (transmission of a 25 µm film ~0 below 450 nm, ~0.85 beyond 700 nm: DuPont
                    Kapton HN data sheet) passed twice over the aluminium, plus the ~7 % front
                    surface; cf. Jorgensen et al. 2004 (Kapton spectra)
``mli_gold``        gold, normal-incidence reflectance from the optical constants of Johnson &
                    Christy 1972, Phys. Rev. B 6, 4370 (the ~500 nm edge)
``osr``             silver behind cerium-doped glass: the silver reflectance of Johnson & Christy
                    1972 above 400 nm, the glass cutting the UV below ~350 nm (Gilmore, *Spacecraft
                    Thermal Control Handbook*, 2002, ch. 4)
``white_paint``     zinc-oxide silicate paint (Z-93 type): flat ~0.9 above 420 nm, the ZnO band
                    edge at ~380 nm (Gilmore 2002, ch. 4, spectral reflectance of white paints)
``aluminium``       aluminium from the optical constants of Rakić 1995, Appl. Opt. 34, 4755 (flat
                    0.92, the interband dip to 0.87 near 830 nm)
``ge_kapton``       ASSUMED a thick germanium film: bulk Ge at normal incidence from the optical
                    constants of Aspnes & Studna 1983, Phys. Rev. B 27, 985 (0.4–0.5, bluish)
``black_paint``     flat (grey): Aeroglaze Z306-type black is spectrally flat in the visible
``panel_back``      flat (grey), ASSUMED (bare CFRP)
``uniform``         flat (grey): the paper's single material
==================  ==========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cssat._checks import FieldError
from cssat.scene.mesh import Mesh

if TYPE_CHECKING:
    from typing import Sequence

__all__ = ["MATERIALS", "Material", "SPECTRA", "SPECTRA_NM", "paint"]


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

#: the wavelengths (nm) of the spectral reflectance tables :data:`SPECTRA`
SPECTRA_NM = (300.0, 350.0, 400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0, 800.0, 900.0, 1000.0, 1100.0)

#: each material's spectral reflectance R(λ) at :data:`SPECTRA_NM` (its shape; the level is the
#: broadband cd, cs of :data:`MATERIALS`) and its source (module docstring)
SPECTRA: dict[str, tuple[tuple[float, ...], str]] = {
    "solar_cell": ((0.10, 0.12, 0.10, 0.08, 0.06, 0.05, 0.05, 0.05, 0.06, 0.07, 0.10, 0.12, 0.14),
                   "assumption: AR-coated triple-junction cell under cover glass (cf. Jorgensen+ 2004 ASR 34, 1021)"),
    "mli": ((0.06, 0.06, 0.07, 0.09, 0.20, 0.42, 0.58, 0.66, 0.70, 0.74, 0.76, 0.77, 0.78),
            "Kapton HN absorption edge (DuPont data sheet) twice over aluminium (cf. Jorgensen+ 2004)"),
    "mli_gold": ((0.33, 0.35, 0.38, 0.39, 0.48, 0.79, 0.91, 0.95, 0.96, 0.97, 0.98, 0.98, 0.98),
                 "gold, Johnson & Christy 1972 optical constants, normal incidence"),
    "osr": ((0.05, 0.50, 0.88, 0.92, 0.93, 0.94, 0.94, 0.95, 0.95, 0.95, 0.95, 0.95, 0.95),
            "silver (Johnson & Christy 1972) behind cerium-doped glass (Gilmore 2002)"),
    "white_paint": ((0.08, 0.10, 0.78, 0.86, 0.88, 0.89, 0.89, 0.90, 0.90, 0.90, 0.89, 0.88, 0.87),
                    "ZnO silicate paint, Z-93 type (Gilmore 2002)"),
    "aluminium": ((0.92, 0.92, 0.92, 0.92, 0.92, 0.915, 0.91, 0.90, 0.89, 0.87, 0.89, 0.93, 0.94),
                  "aluminium, Rakic 1995 optical constants, normal incidence"),
    "ge_kapton": ((0.50, 0.52, 0.47, 0.46, 0.48, 0.49, 0.49, 0.48, 0.46, 0.43, 0.41, 0.40, 0.39),
                  "assumption: bulk germanium, Aspnes & Studna 1983 optical constants"),
    "black_paint": ((0.05,) * 13, "flat (grey): Aeroglaze Z306-type black"),
    "panel_back": ((0.08,) * 13, "assumption: flat (grey) bare CFRP"),
    "uniform": ((1.0,) * 13, "flat (grey): the paper's single material"),
}

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
