"""The wavelengths a photon-counting telescope sees a star's shadow in (issue 37, point 2): the
star's spectrum through a passband, as quadrature nodes and weights for
:func:`~cssat.occultation.shadow` (whose pattern is then the photon-weighted mean of the
monochromatic ones, Eq. S1).

    ``I(x) = ∫ I_λ(x) N(λ) dλ / ∫ N(λ) dλ``,   ``N(λ) = T(λ) B_λ(T_eff) λ / (h c)``      (S1)

``T(λ)`` the band's throughput (:func:`cssat.optics.passbands.passband`: V, R, g, r, i, clear or a
measured filter), ``B_λ`` Planck's law at the star's effective temperature (a blackbody: no
absorption lines or Balmer jump, which move a band's photon centroid by a few nm at most),
``λ/(hc)`` the photons per joule. The band is cut where the photon spectrum falls below 0.1 %
of its peak and split into ``n`` bins of equal width; each node sits at its bin's photon centroid
and weighs the bin's photons (a midpoint rule in the centroid: exact for a pattern linear in λ
across a bin)."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.optics.passbands import C_M_S, passband

__all__ = ["band_wavelengths", "teff_from_bv", "photon_spectrum"]

H_J_S = 6.62607015e-34
K_J_K = 1.380649e-23


def teff_from_bv(bv: float) -> float:
    """A star's effective temperature (K) from its ``B − V`` colour (mag) by Ballesteros (2012,
    EPL 97, 34008): ``T = 4600 [1/(0.92 (B−V) + 1.7) + 1/(0.92 (B−V) + 0.62)]``, a blackbody fit to
    main-sequence and giant colours, good to a few % for −0.3 ≤ B − V ≤ 2 (refused outside)."""
    b = float_param(bv, "star.bv", -0.4, 2.2)
    return 4600.0 * (1.0 / (0.92 * b + 1.7) + 1.0 / (0.92 * b + 0.62))


def photon_spectrum(band: Any, teff_k: float, step_nm: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """``N(λ)`` of Eq. S1 on a ``step_nm`` grid over ``band``'s table: ``(wavelength_nm (n,),
    photons (n,))``, in arbitrary units (the weights are normalised where used)."""
    pb = passband(band)
    T = float_param(teff_k, "star.teff_k", 1000.0, 60000.0)
    lo, hi = float(pb.wavelength_nm[0]), float(pb.wavelength_nm[-1])
    lam = np.linspace(lo, hi, max(2, int(round((hi - lo) / step_nm)) + 1))
    thr = np.interp(lam, pb.wavelength_nm, pb.throughput, left=0.0, right=0.0)
    L = lam * 1e-9
    planck = 1.0 / (L ** 5 * np.expm1(H_J_S * C_M_S / (L * K_J_K * T)))
    return lam, thr * planck * L


def band_wavelengths(band: Any, teff_k: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature nodes ``wavelength_m (n,)`` and weights ``(n,)`` (summing to 1) of Eq. S1 for a
    star of ``teff_k`` (K) through ``band`` (a name or a :class:`~cssat.optics.passbands.Passband`):
    the support where the photons exceed 0.1 % of their peak, cut into ``n`` equal bins, each
    node its bin's photon centroid, each weight its bin's share of the photons. ``n = 1`` is the
    band's photon centroid alone: a monochromatic pattern at the effective wavelength."""
    k = int_param(n, "optics.n_wavelengths", 1, 64)
    lam, N = photon_spectrum(band, teff_k)
    keep = N >= 1e-3 * N.max()
    lo, hi = lam[keep][0], lam[keep][-1]
    if not hi > lo:
        raise FieldError("optics.band", "the band passes no photons of this star")
    edges = np.linspace(lo, hi, k + 1)
    nodes, weights = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (lam >= a) & (lam <= b)
        x, y = lam[sel], N[sel]
        if len(x) < 2:  # a bin narrower than the table's step: its interpolated ends
            x = np.array([a, b])
            y = np.interp(x, lam, N)
        w = float(np.trapezoid(y, x))
        nodes.append(float(np.trapezoid(y * x, x) / w) if w > 0 else 0.5 * (a + b))
        weights.append(w)
    wts = np.array(weights)
    if not wts.sum() > 0:
        raise FieldError("optics.band", "the band passes no photons of this star")
    return np.array(nodes) * 1e-9, wts / wts.sum()
