"""Passbands, magnitude systems (AB, Vega) and the Sun's magnitude through each band.

cssat computes a satellite's brightness as a flux ``F`` in W/m² at the observer, for the Sun's
total irradiance ``I₀`` (:data:`cssat.optics.sun.SOLAR_IRRADIANCE_W_M2`). Its magnitude in a
band is that of the Sun dimmed by ``F / I₀``:

.. math::
    m_{band} = m_{\\odot, band} - 2.5 \\log_{10}(F / I_0)                                   (P1)

**Assumption: grey reflectance** by default — the surfaces reflect every wavelength alike, so the
object has the Sun's colours (real paints, solar cells and MLI are not grey; their colour indices
then differ from the Sun's by a few tenths of a magnitude). With ``spectral=True`` and a ``band``
(:func:`cssat.optics.facet_brightness`), each facet of a known material
(:data:`cssat.scene.materials.SPECTRA`) reflects its band-averaged albedo instead
(:func:`band_coefficients`): the flux ``F`` is then the band's, and Eq. P1 gives the object's
own colours.

``m_☉,band`` comes from the Sun's spectrum ``F_λ`` (:func:`sun_spectrum`) through the band's
throughput ``T(λ)``, in AB (Oke & Gunn 1983: ``m_AB = −2.5 log10(⟨f_ν⟩ / 3631 Jy)``) with

.. math::
    \\langle f_\\nu \\rangle = \\frac{\\int F_\\lambda T \\lambda^{k} d\\lambda}
                                {\\int T \\lambda^{k} (c / \\lambda^2) d\\lambda}              (P2)

``k = 1`` for a photon-counting response (the SDSS and Gaia curves), ``k = 0`` for an energy
response (Bessell 1990's UBVRI tables). Vega magnitudes are ``m_Vega = m_AB − m_AB(Vega)`` with
Vega's AB magnitude in the band from its flux density at the pivot wavelength in Willmer (2018,
ApJS 236, 47, Table 4) — Vega is 0 in every band. A measured filter file (:meth:`Passband.from_file`)
has no Vega zero point unless one is given (``vega_ab``).

Built-in bands (``cssat/optics/data/``, sources in ``PROVENANCE.md``): ``V``, ``R`` (Bessell 1990),
``g``, ``r``, ``i`` (SDSS, Doi et al. 2010), ``clear`` (an unfiltered CCD: the Gaia DR3 G passband,
Riello et al. 2021 — a stand-in for a camera's measured response; give yours with a file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, choice_param, float_param
from cssat.optics.sun import SOLAR_IRRADIANCE_W_M2

if TYPE_CHECKING:
    from cssat._types import Array

__all__ = ["Passband", "BANDS", "SYSTEMS", "passband", "sun_spectrum", "sun_magnitude", "magnitude", "flux_from_magnitude",
           "ab_magnitude_at", "std_magnitude", "lambert_sphere_phase", "resolve_band", "bessell_b", "spectral_factor",
           "band_coefficients"]

DATA = Path(__file__).parent / "data"
C_M_S = 299_792_458.0
AB_ZERO_W_M2_HZ = 3631e-26  # 3631 Jy (Oke & Gunn 1983)
BANDS = ("V", "R", "g", "r", "i", "clear")
SYSTEMS = ("AB", "Vega")
# Willmer (2018) Table 4: Vega's flux density (erg s⁻¹ cm⁻² Å⁻¹) at the pivot wavelength (µm) of
# Johnson V, Cousins R, SDSS g, r, i. Vega's AB magnitude there: −2.5 log10(f_λ λ_p² / c / 3631 Jy).
_WILLMER_VEGA = {"V": (3.62701e-9, 0.5511), "R": (2.13191e-9, 0.6582), "g": (5.52461e-9, 0.4702),
                 "r": (2.55856e-9, 0.6176), "i": (1.42903e-9, 0.749)}
_PHOTON = {"V": False, "R": False, "g": True, "r": True, "i": True, "clear": True}


def _vega_ab(flam_cgs: float, pivot_um: float) -> float:
    lam = pivot_um * 1e-6
    fnu = flam_cgs * 1e-7 * 1e4 * 1e10 * lam**2 / C_M_S  # erg/s/cm²/Å → W/m²/m, then f_ν in W/m²/Hz
    return -2.5 * math.log10(fnu / AB_ZERO_W_M2_HZ)


@dataclass(frozen=True)
class Passband:
    """A band's throughput: ``wavelength_nm (n,)`` increasing, ``throughput (n,)`` ≥ 0 (any scale).
    ``photon``: a photon-counting response (``k = 1`` in Eq. P2) or an energy one (``k = 0``);
    ``vega_ab``: Vega's AB magnitude in this band (``None``: Vega magnitudes refused)."""

    name: str
    wavelength_nm: np.ndarray = field(repr=False)
    throughput: np.ndarray = field(repr=False)
    photon: bool = True
    vega_ab: float | None = None

    def __post_init__(self):
        lam = np.asarray(self.wavelength_nm, dtype=np.float64)
        t = np.asarray(self.throughput, dtype=np.float64)
        if lam.ndim != 1 or lam.shape != t.shape or len(lam) < 2:
            raise FieldError("passband", f"{self.name}: expected two columns of equal length >= 2, got {lam.shape} and {t.shape}")
        if not (np.all(np.isfinite(lam)) and np.all(np.isfinite(t))) or np.any(np.diff(lam) <= 0):
            raise FieldError("passband", f"{self.name}: wavelengths must be finite and strictly increasing (nm)")
        if np.any(t < 0) or not np.any(t > 0):
            raise FieldError("passband", f"{self.name}: throughput must be >= 0 and not all zero")
        lo, hi = sun_spectrum()[0][[0, -1]]
        outside = (lam < lo) | (lam > hi)
        if outside.any():  # a tail past the solar table (a CCD's QE to 1200 nm): cut when it carries < 1 %
            share = 1 - np.trapezoid(np.where(outside, 0.0, t), lam) / np.trapezoid(t, lam)
            if share > 0.01:
                raise FieldError("passband", f"{self.name}: {100 * share:.1f} % of the throughput lies outside the "
                                             f"solar spectrum's {lo:.0f}-{hi:.0f} nm (at most 1 % is cut)")
            t = np.where(outside, 0.0, t)
        object.__setattr__(self, "wavelength_nm", lam)
        object.__setattr__(self, "throughput", t)

    @classmethod
    def from_file(cls, path: str | Path, name: str | None = None, *, photon: bool = True,
                  vega_ab: float | None = None) -> Passband:
        """A measured filter: a text file of two columns ``λ[nm] T`` (``#`` comments, any
        whitespace or commas); ``T`` in any scale (fraction or percent)."""
        p = Path(path)
        if not p.is_file():
            raise FieldError("passband", f"no filter file {str(p)!r}")
        rows = [ln.split("#")[0].replace(",", " ").split() for ln in p.read_text().splitlines()]
        try:
            d = np.array([[float(r[0]), float(r[1])] for r in rows if r], dtype=np.float64)
        except (ValueError, IndexError) as err:
            raise FieldError("passband", f"{p.name}: expected two numeric columns, wavelength_nm throughput ({err})") from None
        if d.ndim != 2 or len(d) < 2:
            raise FieldError("passband", f"{p.name}: expected at least two rows of wavelength_nm throughput")
        return cls(name or p.stem, d[:, 0], d[:, 1], photon, vega_ab)

    def mean_flux_density(self, wavelength_nm: np.ndarray, flux_w_m2_nm: np.ndarray) -> float:
        """``⟨f_ν⟩`` (W m⁻² Hz⁻¹) of a spectrum ``F_λ`` (W m⁻² nm⁻¹) through this band, Eq. P2, by
        the trapezoid rule on a 0.5 nm grid (both curves interpolated linearly, zero outside)."""
        lo, hi = self.wavelength_nm[0], self.wavelength_nm[-1]
        lam = np.linspace(lo, hi, max(2, int(round((hi - lo) / 0.5)) + 1))
        T = np.interp(lam, self.wavelength_nm, self.throughput, left=0.0, right=0.0)
        F = np.interp(lam, wavelength_nm, flux_w_m2_nm, left=0.0, right=0.0) * 1e9  # per m
        L = lam * 1e-9
        w = L if self.photon else np.ones_like(L)
        return float(np.trapezoid(F * T * w, L) / np.trapezoid(T * w * C_M_S / L**2, L))


@lru_cache(maxsize=1)
def sun_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """The Sun's spectral irradiance at 1 AU: ``(wavelength_nm (n,), W m⁻² nm⁻¹ (n,))``, 300–1100 nm
    in 5 nm bins (ASTM G173-03 extraterrestrial column scaled to 1361 W/m²; ``data/PROVENANCE.md``)."""
    d = np.loadtxt(DATA / "sun_astm_g173_etr_5nm.txt")
    return d[:, 0].copy(), d[:, 1].copy()


@lru_cache(maxsize=None)
def _builtin(name: str) -> Passband:
    d = np.loadtxt(DATA / f"band_{name}.txt")
    vega = _vega_ab(*_WILLMER_VEGA[name]) if name in _WILLMER_VEGA else None
    return Passband(name, d[:, 0], d[:, 1], _PHOTON[name], vega)


@lru_cache(maxsize=1)
def bessell_b() -> Passband:
    """Johnson–Cousins B (Bessell 1990, energy response), with Vega's AB magnitude from Willmer
    (2018, Table 4: Johnson B, 6.33795e-9 erg s⁻¹ cm⁻² Å⁻¹ at 0.4396 µm). Not one of the named
    :data:`BANDS`: pass this object where a band is taken."""
    d = np.loadtxt(DATA / "band_B.txt")
    return Passband("B", d[:, 0], d[:, 1], False, _vega_ab(6.33795e-9, 0.4396))


def _band_average(pb: Passband, weight: np.ndarray | None) -> float:
    """``∫ S T R w dλ / ∫ S T w dλ`` on the solar table's 0.5 nm grid (``R = weight``; None: 1)."""
    wl, sp = sun_spectrum()
    lam = np.linspace(wl[0], wl[-1], int(round((wl[-1] - wl[0]) / 0.5)) + 1)
    S = np.interp(lam, wl, sp)
    T = np.interp(lam, pb.wavelength_nm, pb.throughput, left=0.0, right=0.0)
    w = lam if pb.photon else np.ones_like(lam)
    R = np.ones_like(lam) if weight is None else weight
    return float(np.trapezoid(S * T * R * w, lam) / np.trapezoid(S * T * w, lam))


def spectral_factor(material: str, band: str | Passband) -> float:
    """The factor a material's broadband ``cd``, ``cs`` take in ``band``: its spectral reflectance
    ``R(λ)`` (:data:`cssat.scene.materials.SPECTRA`) averaged over the Sun's light through the band,
    over its Sun-weighted mean on 300–1100 nm, ``⟨R⟩_band / ⟨R⟩☉``. Exactly 1 for a grey (flat)
    material and for a name without a table."""
    from cssat.scene.materials import SPECTRA, SPECTRA_NM  # local: the materials' spectra, only for colours

    if material not in SPECTRA or len(set(SPECTRA[material][0])) == 1:
        return 1.0
    pb = passband(band)
    wl, sp = sun_spectrum()
    lam = np.linspace(wl[0], wl[-1], int(round((wl[-1] - wl[0]) / 0.5)) + 1)
    R = np.interp(lam, SPECTRA_NM, SPECTRA[material][0])
    S = np.interp(lam, wl, sp)
    solar_mean = float(np.trapezoid(S * R, lam) / np.trapezoid(S, lam))
    return _band_average(pb, R) / solar_mean


def band_coefficients(mesh: Any, band: str | Passband) -> Any:
    """``mesh`` (any :class:`cssat.scene.Mesh`, its joints kept) with each facet's ``cd``, ``cs``
    multiplied by :func:`spectral_factor` of its part's material in ``band`` (parts named by
    :data:`cssat.scene.materials.MATERIALS`, as ``material="satellite"`` models are; other facets
    and grey materials unchanged). Where a factor would make ``cd + cs`` exceed 1, both are scaled
    down to a sum of 1."""
    import dataclasses  # local: only to copy a passband

    if mesh.part is None or not len(mesh):
        return mesh
    factors = np.array([spectral_factor(n, band) for n in mesh.part_names])[mesh.part]
    if np.all(factors == 1.0):
        return mesh
    cd, cs = mesh.cd * factors, mesh.cs * factors
    over = np.maximum(cd + cs, 1.0)
    return dataclasses.replace(mesh, cd=cd / over, cs=cs / over, _cache={})


def passband(band: str | Passband) -> Passband:
    """A built-in band by name (``V R g r i clear``; ``Clear`` and ``C`` alias ``clear``) or ``band``
    itself when it is a :class:`Passband`."""
    if isinstance(band, Passband):
        return band
    key = {"Clear": "clear", "C": "clear", "CLEAR": "clear", "CR": "clear"}.get(str(band), str(band))
    if key not in BANDS:
        raise FieldError("band", f"expected one of {list(BANDS)} (or a Passband from a measured file), got {band!r}")
    return _builtin(key)


def sun_magnitude(band: str | Passband = "V", system: str = "Vega") -> float:
    """The Sun's apparent magnitude at 1 AU in ``band`` and ``system`` (``AB`` or ``Vega``), Eq. P2."""
    system = choice_param(system, "system", SYSTEMS)
    pb = passband(band)
    m_ab = -2.5 * math.log10(pb.mean_flux_density(*sun_spectrum()) / AB_ZERO_W_M2_HZ)
    if system == "AB":
        return m_ab
    if pb.vega_ab is None:
        raise FieldError("system", f"band {pb.name!r} has no Vega zero point: use system='AB' or give the "
                                   "Passband's vega_ab (Vega's AB magnitude in the band)")
    return m_ab - pb.vega_ab


def _irr(irradiance: float | None) -> float:
    return SOLAR_IRRADIANCE_W_M2 if irradiance is None else float_param(irradiance, "irradiance", 0.0, None, open_lo=True)


def magnitude(flux_w_m2: Array | float, band: str | Passband = "V", system: str = "Vega", irradiance: float | None = None) -> Tensor:
    """Magnitude (Eq. P1) of a flux in W/m² (any shape; float64 tensor, ``+inf`` for zero flux)
    computed for a Sun of total irradiance ``irradiance`` (default 1361 W/m²)."""
    f = torch.as_tensor(flux_w_m2, dtype=torch.float64)
    return sun_magnitude(band, system) - 2.5 * torch.log10(f / _irr(irradiance))


def flux_from_magnitude(mag: Array | float, band: str | Passband = "V", system: str = "Vega", irradiance: float | None = None) -> Tensor:
    """The inverse of :func:`magnitude`: ``I₀ 10^(−0.4 (m − m_☉,band))`` in W/m²."""
    m = torch.as_tensor(mag, dtype=torch.float64)
    return _irr(irradiance) * 10.0 ** (-0.4 * (m - sun_magnitude(band, system)))


def ab_magnitude_at(flux_w_m2: Array | float, wavelength_nm: float, convention: str = "sun", irradiance: float | None = None) -> Tensor:
    """AB magnitude at one wavelength (a monochromatic band).

    ``convention="sun"``: the Sun's ``f_ν(λ)`` scaled by ``F / I₀`` (grey reflectance, Eq. P1).
    ``convention="bolometric"``: the whole flux taken as ``ν f_ν`` at ``λ``, ``f_ν = F λ / c`` —
    lumos-sat's ``intensity_to_ab_mag`` (532 nm there), which is 0.3 mag brighter than the Sun's
    colours give at 532 nm."""
    convention = choice_param(convention, "convention", ("sun", "bolometric"))
    lam_nm = float_param(wavelength_nm, "wavelength_nm", 300.0, 1100.0)
    f = torch.as_tensor(flux_w_m2, dtype=torch.float64)
    if convention == "bolometric":
        return -2.5 * torch.log10(f * lam_nm * 1e-9 / C_M_S / AB_ZERO_W_M2_HZ)
    wl, sp = sun_spectrum()
    fnu_sun = float(np.interp(lam_nm, wl, sp)) * 1e9 * (lam_nm * 1e-9) ** 2 / C_M_S
    return -2.5 * math.log10(fnu_sun / AB_ZERO_W_M2_HZ) - 2.5 * torch.log10(f / _irr(irradiance))


def lambert_sphere_phase(phase_deg: Array | float) -> Tensor:
    """A Lambertian sphere's phase function normalised to 1 at full phase,
    ``p(φ) = (sin φ + (π − φ) cos φ) / π`` (φ the Sun–object–observer angle; Vallerie 1963)."""
    phi = torch.deg2rad(torch.as_tensor(phase_deg, dtype=torch.float64))
    return (torch.sin(phi) + (math.pi - phi) * torch.cos(phi)) / math.pi


def std_magnitude(mag: Array | float, range_km: Array | float, phase_deg: Array | float | None = None, *, ref_range_km: float = 1000.0, ref_phase_deg: float = 90.0,
                  phase_function: str = "lambert_sphere") -> Tensor:
    """A magnitude reduced to ``ref_range_km`` (1000 km) and phase ``ref_phase_deg`` (90°), the
    "standard magnitude" of satellite observers (MMT's ``StdMag``):

    ``m_std = m − 5 log10(r / r_ref) + 2.5 log10(p(φ) / p(φ_ref))``

    with ``p`` the Lambert-sphere phase function (``phase_function="lambert_sphere"``) or no phase
    term (``"none"``, range only; ``phase_deg`` may then be None). ASSUMPTION: which phase law MMT
    applies is not verified here; the Lambert sphere is the conventional one. Phases where
    ``p = 0`` (180°) give ``-inf``."""
    phase_function = choice_param(phase_function, "phase_function", ("lambert_sphere", "none"))
    m = torch.as_tensor(mag, dtype=torch.float64)
    r = torch.as_tensor(range_km, dtype=torch.float64)
    if bool((r <= 0).any()) or not bool(torch.isfinite(r).all()):
        raise FieldError("range_km", "must be finite and > 0")
    out = m - 5.0 * torch.log10(r / float_param(ref_range_km, "ref_range_km", 0.0, None, open_lo=True))
    if phase_function == "none":
        return out
    if phase_deg is None:
        raise FieldError("phase_deg", "needed for phase_function='lambert_sphere' (or use phase_function='none')")
    ph = torch.as_tensor(phase_deg, dtype=torch.float64)
    if bool((ph < 0).any()) or bool((ph > 180).any()) or not bool(torch.isfinite(ph).all()):
        raise FieldError("phase_deg", "must be in [0, 180] degrees")
    ref = float(lambert_sphere_phase(float_param(ref_phase_deg, "ref_phase_deg", 0.0, 180.0, open_lo=True)))
    return out + 2.5 * torch.log10(lambert_sphere_phase(ph) / ref)


_FILTER_NAMES = {"V": "V", "R": "R", "RC": "R", "G": "g", "G'": "g", "SDSS_G": "g", "R'": "r", "SDSS_R": "r", "I": "i",
                 "I'": "i", "SDSS_I": "i", "CLEAR": "clear", "C": "clear", "CR": "clear", "CLR": "clear", "W": "clear"}


def resolve_band(band: str | Passband | None, system: str = "Vega", filters: np.ndarray | None = None,
                 field: str = "band") -> tuple[Passband, str] | None:
    """A config's ``band`` and ``system`` checked before any work: ``None`` (cssat's legacy V with
    ``m_☉ = −26.74``), a built-in band name, a path to a measured filter file (two columns λ[nm] T,
    photon-counting), or ``"file"``: the one band a light curve's filter column names (``filters``;
    ``V R Rc g r i`` — SDSS's ``g r i`` are lower case — ``Clear C CR``). Returns ``(Passband, system)``."""
    if band is None:
        return None
    system = choice_param(system, f"{field}_system" if field != "band" else "system", SYSTEMS)
    if isinstance(band, str) and band == "file":
        names = sorted({str(f).strip() for f in (filters if filters is not None else [])} - {""})
        if len(names) != 1:
            raise FieldError(field, f"band 'file' needs one filter in the file's filter column, found {names or 'none'}"
                                    f" (name the band instead, one of {list(BANDS)})")
        key = names[0] if names[0] in ("g", "r", "i") else _FILTER_NAMES.get(names[0].upper())
        if key is None:
            raise FieldError(field, f"the file's filter {names[0]!r} is none of {sorted(_FILTER_NAMES)} (name the band, "
                                    "or give a measured filter file)")
        band = key
    if isinstance(band, (str, Path)) and str(band) not in BANDS and Path(str(band)).suffix:
        pb = Passband.from_file(band)
    else:
        try:
            pb = passband(band)
        except FieldError as err:
            raise FieldError(field, err.detail) from None
    if system == "Vega" and pb.vega_ab is None:
        raise FieldError(field, f"band {pb.name!r} has no Vega zero point: set its system to AB")
    return pb, system
