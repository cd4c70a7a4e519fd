"""The results of the occultation fits as objects (:class:`cssat.results.Result`: a read-only
mapping of the fit's keys with attributes, ``dict(r)`` the fit's dict): :class:`EventFit` —
:func:`~cssat.occultation.invert_event`'s nuisances and offsets — and :class:`SilhouetteFit` —
:func:`~cssat.occultation.invert_silhouette`'s loss. Both come second in the fits' ``(mask,
fit)`` pairs, as the dicts did."""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat.results import Result

__all__ = ["EventFit", "SilhouetteFit", "PriorChoice"]


class SilhouetteFit(Result):
    """What :func:`~cssat.occultation.invert_silhouette` says of its silhouette: ``loss`` (the
    objective at the kept start), ``chi2_per_sample`` (the weighted χ² over the samples) and
    ``losses`` (each start's final objective)."""

    required = ("loss", "chi2_per_sample")

    @property
    def loss(self) -> float:
        """The objective (½χ²/N plus the penalties) of the kept start."""
        return self._data["loss"]

    @property
    def chi2_per_sample(self) -> float:
        """The weighted χ² of the fit over the samples."""
        return self._data["chi2_per_sample"]


class EventFit(Result):
    """What :func:`~cssat.occultation.invert_event` fits besides the silhouette: ``grid_centre_m``
    (east, north; the silhouette's grid centre on the predicted track), ``offset_m (2,)`` and
    ``offset_cov (2, 2)`` (m, m²: the silhouette's centroid on the predicted track — the χ²
    curvature's, the grey pixels' and the aperture gaps' covariance), ``centroid_m``,
    ``centroid_sigma_m``, ``gap_sigma_m``, ``speed_error`` (the fractional error of the predicted
    shadow speed) ± ``speed_error_sigma``, ``gains (J,)`` ± ``gains_sigma`` (each telescope's
    frozen scintillation gain), ``diameter_m`` ± ``diameter_sigma_m`` (the star's diameter at the
    satellite's distance, m; ``diameter_range2_m``, ``diameter_profile``,
    ``diameter_profile_best_m`` its diagnostics), ``chi2_per_sample``, ``chi2_per_dof_nuisances``,
    ``offsets_by_round (R, 2)``, ``known`` (the nuisances given, not fitted) and ``linear`` (the
    linear solver's first silhouette, or None)."""

    required = ("offset_m", "offset_cov", "chi2_per_sample")
    array_keys = ("grid_centre_m", "offset_m", "offset_cov", "centroid_m", "centroid_sigma_m", "gains", "gains_sigma",
                  "diameter_profile", "offsets_by_round", "linear")

    @property
    def offset_m(self) -> np.ndarray:
        """``(2,)`` m (east, north): the silhouette's centroid relative to the predicted track."""
        return self._data["offset_m"]

    @property
    def offset_cov(self) -> np.ndarray:
        """``(2, 2)`` m²: the offset's covariance."""
        return self._data["offset_cov"]

    @property
    def offset_sigma_m(self) -> np.ndarray:
        """``(2,)`` m: the offset's 1σ (the covariance's diagonal, square-rooted)."""
        return np.sqrt(np.diag(np.asarray(self._data["offset_cov"], dtype=np.float64)))

    @property
    def speed_error(self) -> float:
        """The fractional error of the predicted shadow speed."""
        return self._data.get("speed_error")

    @property
    def gains(self) -> np.ndarray | None:
        """``(J,)`` each telescope's frozen scintillation gain."""
        return self._data.get("gains")

    @property
    def diameter_m(self) -> float | None:
        """The star's diameter at the satellite's distance, m."""
        return self._data.get("diameter_m")

    @property
    def chi2_per_sample(self) -> float:
        """The silhouette's weighted χ² over the samples."""
        return self._data["chi2_per_sample"]

    @property
    def linear(self) -> Any:
        """The linear solver's first silhouette ``(H, W)``, or None."""
        return self._data.get("linear")


class PriorChoice(Result):
    """What :func:`~cssat.occultation.prior.choose_prior` chose: ``used`` (``pixels`` or
    ``shapes``), ``params (K, 6)`` of the kept superellipses (None for pixels), ``n_shapes`` and
    ``start`` of the kept candidate (``kept_candidate`` its index), ``chi2_per_sample_shapes``,
    ``heldout_chi2_pixels``, ``heldout_chi2_shapes`` (summed over the two folds), ``candidates``
    (one dict per number of shapes and start: ``n_shapes``, ``start``, ``heldout_chi2``,
    ``chi2_per_sample``, ``area_m2``, ``centroid_east_m``, ``centroid_north_m``),
    ``candidate_masks (C, H, W)``, ``near_best`` (indices of the candidates within Δχ² = 4 of the
    lowest held-out χ²) and ``spread`` (their ranges: ``heldout_chi2``, ``area_m2``,
    ``centroid_east_m``, ``centroid_north_m`` as ``[min, max]``, ``n_near_best``, ``n_shapes``)."""

    required = ("used",)
    array_keys = ("params", "candidate_masks")

    @property
    def used(self) -> str:
        """The prior kept: ``pixels`` or ``shapes``."""
        return self._data["used"]

    def metrics(self) -> dict[str, Any]:
        """The choice as flat, JSON-ready metrics (no masks, no parameters)."""
        d = self._data
        out = {"prior_used": d["used"]}
        if d.get("heldout_chi2_pixels") is not None:
            out["heldout_chi2_pixels"] = d["heldout_chi2_pixels"]
            out["heldout_chi2_shapes"] = d["heldout_chi2_shapes"]
        if d.get("candidates"):
            out.update(n_shapes=d["n_shapes"], shape_start=d["start"], chi2_per_sample_shapes=d["chi2_per_sample_shapes"],
                       shape_candidates=[dict(c) for c in d["candidates"]], shape_spread=dict(d["spread"]))
        return out
