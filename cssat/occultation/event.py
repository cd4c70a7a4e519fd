"""A silhouette and the event's nuisances together, from nothing but what an observer knows
(issue 37, point 1): :func:`invert_event`.

Given: the series and their 1σ, the telescopes' positions in the fundamental plane (from their
ground positions, :func:`~cssat.occultation.geometry.ground_to_plane`), the predicted shadow
velocity and distance (the element set), the band's wavelengths and weights (the filter and the
star's catalogue colour, :func:`~cssat.occultation.spectrum.band_wavelengths`), the apertures
and the exposure. Not given: where the shadow passed (a time offset along the track, a path
offset across it), the speed's small error, each telescope's gain (frozen scintillation,
flat-field), the star's angular diameter (fixed at the mean of a stated prior range, below; the
limb darkening assumed, not fitted).

Block-coordinate: a first offset from the dips (:func:`~cssat.occultation.nuisance.dip_offset`);
then ``rounds`` times the silhouette on a grid centred on the current offset (the linear solver
first in round one, :func:`~cssat.occultation.invert_linear`; the non-linear fit,
:func:`~cssat.occultation.invert_silhouette`, the series divided by the current gains) and the
nuisances for that silhouette (:func:`~cssat.occultation.nuisance.fit_nuisances`). The offset
is reported for the silhouette's centroid (the silhouette's position and the offset are one
unknown): the grid's centre plus the mask's centroid, with a 1σ that adds in quadrature the χ²
curvature's, the grey pixels' (:func:`~cssat.occultation.nuisance.mask_centroid`) and, across
the track, the gaps between telescopes around the silhouette's edges
(:func:`~cssat.occultation.nuisance.gap_sigma`: rows between telescopes are interpolated, not
measured).
The star's diameter is *not measured* at the default array: its blur (a 2 mas star at GEO is a
0.37 m disk, 0.09 m rms) hides under the aperture's (0.125 m rms), the exposure's smear (0.16 m)
and the silhouette's own grey edges (a grey edge blurs the shadow as a larger star does: both are
convolutions, which commute with Fresnel propagation); the χ² profile over the diameter moves by
Δχ² ≈ 1–9 from 0 to 3 mas and the inversion's discretisation (0.2 m pixels, bilinear sampling)
shifts its minimum to the smallest star. So the diameter is **fixed at the prior's mean** — the
middle of the grid ``diameters_m`` (1.5 mas for the experiment's [0, 3] mas) — and *not*
marginalised: the silhouette and the offsets are those for that one star, and their 1σ carry no
share of the diameter's uncertainty (``diameter_sigma_m`` is 0; ``diameter_treatment`` says
"fixed at the prior's mean", ``diameter_prior_m`` the range). Marginalising for real — the
silhouette, nuisances and likelihood at every node of the prior, the results mixed by the
posterior weights — costs the whole fit once a node (8–16 fits a run) and was not taken. The
profile for the fitted silhouette and its minimum are kept as diagnostics (``diameter_profile``,
``diameter_profile_best_m``).
``known``: any nuisance handed over (the oracle), as ``offset_m``, ``speed_error``, ``gains``,
``diameter_m``.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from cssat._checks import FieldError, int_param
from cssat.occultation.invert import invert_silhouette
from cssat.occultation.linear import invert_linear
from cssat.occultation.nuisance import dip_offset, fit_nuisances, gap_sigma, mask_centroid
from cssat.occultation.record import pattern_kernel
from cssat.occultation.results import EventFit

__all__ = ["invert_event", "event_geometry"]


def event_geometry(series: Any, sigma: Any, shape: Sequence[int], pixel_m: float, wavelength_m: Any, distance_m: float,
                   positions_m: Any, velocity_m_s: Any, times_s: Any, *, offset_m: Any, gains: Any, speed_error: float,
                   diameter_m: float, aperture_m: float, exposure_s: float,
                   limb_darkening: float = 0.6) -> tuple[tuple, np.ndarray]:
    """The recording as the silhouette's fits see it for the given nuisances: ``(geo, kernel)``
    with ``geo`` the positional arguments of :func:`~cssat.occultation.invert_silhouette` —
    the series and 1σ divided by the ``gains (J,)``, the positions less the ``offset_m (2,)``, the
    velocity scaled by ``1 + speed_error`` — and the averaging kernel (aperture, the star of
    ``diameter_m``, the exposure's smear at that speed)."""
    v = np.asarray(velocity_m_s, dtype=np.float64).reshape(2)
    speed = float(np.linalg.norm(v))
    g = np.asarray(gains, dtype=np.float64).reshape(-1, 1)
    kernel = pattern_kernel(pixel_m, aperture_m=aperture_m, star_diameter_m=diameter_m, limb_darkening=limb_darkening,
                            smear_m=speed * (1 + speed_error) * exposure_s, smear_dir=v / speed)
    geo = (np.asarray(series, dtype=np.float64) / g, np.asarray(sigma, dtype=np.float64) / g, tuple(shape), pixel_m,
           wavelength_m, distance_m, np.asarray(positions_m, dtype=np.float64).reshape(-1, 2) - np.asarray(offset_m),
           v * (1 + speed_error), times_s)
    return geo, kernel


def invert_event(series: Any, sigma: Any, shape: Sequence[int], pixel_m: float, wavelength_m: Any, distance_m: float,
                 positions_m: Any, velocity_m_s: Any, times_s: Any, *, weights: Any = None, aperture_m: float,
                 exposure_s: float, limb_darkening: float = 0.6, diameters_m: Any = (0.0,), known: dict | None = None,
                 solver: Any = None, tv: float = 0.3, iters: int = 300, rounds: int = 2,
                 ground: Any = None, seed: int = 0) -> tuple[np.ndarray, EventFit]:
    """The silhouette ``(H, W)`` on a grid centred on the shadow's fitted offset, and the event's
    nuisances (the module's docstring): ``series (J, K)``, ``sigma`` as for
    :func:`~cssat.occultation.invert_silhouette`; ``positions_m (J, 2)`` relative to the
    predicted shadow centre's track (which passes the plane's origin at t = 0), ``velocity_m_s``
    the predicted one; ``diameters_m`` the star's diameter grid (m at the satellite's distance).
    Returns ``(mask, info)``, ``info`` an :class:`~cssat.occultation.results.EventFit` (a
    read-only mapping with attributes): ``grid_centre_m`` (east, north), ``offset_m`` and ``offset_cov``
    (the silhouette's centroid), ``speed_error`` (±σ), ``gains`` (±σ), ``diameter_m`` (fixed at the
    prior's mean: ``diameter_sigma_m`` 0, ``diameter_treatment``, the prior's range
    ``diameter_prior_m``; diagnostics ``diameter_profile``, ``diameter_profile_best_m``),
    ``chi2_per_sample``, the rounds' offsets and the linear solver's first estimate ``linear``
    (None without a ``solver``)."""
    y = np.asarray(series, dtype=np.float64)
    s = np.broadcast_to(np.asarray(sigma, dtype=np.float64), y.shape).copy()
    P = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(velocity_m_s, dtype=np.float64).reshape(2)
    speed = float(np.linalg.norm(v))
    if not speed > 0:
        raise FieldError("velocity_m_s", "the shadow does not move")
    rounds = int_param(rounds, "invert.rounds", 1, 20)
    known = dict(known or {})
    dias = np.atleast_1d(np.asarray(known.get("diameter_m", diameters_m), dtype=np.float64))
    est = {"offset_m": np.asarray(known["offset_m"], dtype=np.float64) if "offset_m" in known
           else dip_offset(y, s, P, v, times_s),
           "speed_error": float(known.get("speed_error", 0.0)),
           "gains": np.asarray(known["gains"], dtype=np.float64) if "gains" in known else np.median(y, axis=1),
           "diameter_m": float(0.5 * (dias.min() + dias.max()))}
    history = [est["offset_m"].copy()]
    mask, nui, linear = None, None, None

    def geometry():
        return event_geometry(y, s, shape, pixel_m, wavelength_m, distance_m, P, v, times_s, offset_m=est["offset_m"],
                              gains=est["gains"], speed_error=est["speed_error"], diameter_m=est["diameter_m"],
                              aperture_m=aperture_m, exposure_s=exposure_s, limb_darkening=limb_darkening)

    def nuisances(diameters):
        """The nuisances for the current silhouette and estimates (:func:`fit_nuisances`)."""
        v_r = v * (1 + est["speed_error"])
        return fit_nuisances(mask, y, s, pixel_m, wavelength_m, distance_m, P, v_r, times_s, offset_m=est["offset_m"],
                             weights=weights, ground=ground, aperture_m=aperture_m,
                             smear_m=float(np.linalg.norm(v_r)) * exposure_s, limb_darkening=limb_darkening,
                             diameters_m=diameters)

    for _ in range(rounds):
        geo, kernel = geometry()
        if mask is None and solver is not None:
            linear, _ = invert_linear(*geo, kernel=kernel, weights=weights, solver=solver, ground=ground)
        mask, info = invert_silhouette(*geo, kernel=kernel, weights=weights, tv=tv, iters=iters, seed=seed,
                                       init=mask if mask is not None else linear, ground=ground)
        if {"offset_m", "speed_error", "gains"} <= set(known):
            break  # nothing left to fit but the star
        nui = nuisances([est["diameter_m"]])
        if "offset_m" not in known:
            est["offset_m"] = nui["offset_m"]
        if "speed_error" not in known:
            est["speed_error"] = (1 + est["speed_error"]) * (1 + nui["speed_error"]) - 1
        if "gains" not in known:
            est["gains"] = nui["gains"]
        history.append(est["offset_m"].copy())
    dia = {"diameter_sigma_m": 0.0, "diameter_range2_m": [est["diameter_m"]] * 2, "diameter_profile": np.zeros(0),
           "diameter_profile_best_m": est["diameter_m"],
           "diameter_treatment": "given" if "diameter_m" in known else "fixed at the prior's mean",
           "diameter_prior_m": [float(dias.min()), float(dias.max())]}
    if "diameter_m" not in known and len(dias) > 1:
        # fixed at the prior's mean (not estimated: no σ of its own); the χ² profile for the fitted
        # silhouette is kept as a diagnostic (biased, the module's docstring)
        prof = nuisances(dias)
        dia.update(diameter_profile=prof["profile"], diameter_profile_best_m=prof["diameter_m"])
    c, c_sig = mask_centroid(mask, pixel_m)
    across = np.array([-v[1], v[0]]) / speed
    g_sig = gap_sigma(mask, pixel_m, (P - est["offset_m"]) @ across, across, aperture_m)
    cov = np.zeros((2, 2))
    if "offset_m" not in known:  # the χ² curvature's, the grey pixels' and the gaps'
        cov = (0.0 if nui is None else nui["offset_cov"]) + np.diag(c_sig ** 2) + g_sig ** 2 * np.outer(across, across)
    return mask, EventFit({"grid_centre_m": est["offset_m"], "offset_m": est["offset_m"] + c, "centroid_m": c, "offset_cov": cov,
                  "centroid_sigma_m": c_sig, "gap_sigma_m": g_sig, "speed_error": est["speed_error"],
                  "speed_error_sigma": 0.0 if nui is None or "speed_error" in known else nui["speed_error_sigma"],
                  "gains": est["gains"], "gains_sigma": np.zeros(len(P)) if nui is None or "gains" in known else nui["gains_sigma"],
                  "diameter_m": est["diameter_m"], **dia, "chi2_per_sample": info["chi2_per_sample"],
                  "chi2_per_dof_nuisances": math.nan if nui is None else nui["chi2_per_dof"],
                  "offsets_by_round": np.array(history), "known": sorted(known), "linear": linear})
