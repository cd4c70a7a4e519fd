"""The shadow forward model (``forward: shadow``; ``cssat experiment=occultation``): a GEO
satellite's silhouette measured as the Fresnel shadow it casts on a star, recorded by a line of
telescopes on the ground, inverted with nothing handed over but what an observer knows.

Its settings are typed: the groups ``star``, ``optics``, ``event``, ``array``, ``silhouette`` and
``invert`` are the dataclasses of :mod:`cssat.models.shadow.config` (one set of defaults, each
value checked with its full key when the settings are built, :class:`~cssat.models.shadow.config.ShadowSettings`).
Each stage hands on a typed result, read by the later stages with ``run.result(stage)`` (declared
in :attr:`Shadow.needs`); the model keeps no state of a run.

Stages: ``plan`` (:class:`ShadowPlan`) — the settings, the ``solver`` for the linearised model,
the ``model`` and its ``attitude`` built; ``measure``
(:class:`~cssat.experiments.forward.shadow_measure.ShadowMeasured`) — the ``scenario`` at
``scenario.start_utc``, the star (``star.ra_deg``/``dec_deg``; null: exactly behind the satellite
then), the fundamental plane, the shadow's predicted velocity and the distance
(:func:`~cssat.occultation.shadow_track`), the star's altitude (airmass ``1/sin alt``), the
telescopes on level ground along the horizontal line whose projection is across the track, one
every ``array.spacing_m`` *ground* metres (null: one aperture in the plane), a seeded
``array.fill`` of the slots, projected into the plane along the starlight (stage ``geometry``);
the truth — the ``model``'s silhouette in its ``attitude`` (or ``silhouette.target: bars``) on a
grid ``silhouette.truth_oversample`` × finer than the inversion's, its polychromatic shadow
(``optics.band`` × a blackbody of the star's ``star.bv`` colour, ``optics.n_wavelengths`` nodes,
:func:`~cssat.occultation.band_wavelengths`; ``band: null`` — monochromatic at
``optics.wavelength_m``) averaged over the aperture, the exposure's smear and the true star's
limb-darkened disk (stage ``shadow``); the event as it happens — the shadow late by a time offset
drawn within ±``event.time_error_s``, off its predicted path by a cross-track offset
(``event.path_offset_m``; null: drawn where the array still spans the silhouette), its speed off
by ``event.speed_error`` (relative 1σ), each telescope's frozen scintillation gain and the white
rest (``array.scintillation: frozen``; ``white``: independent per exposure, the old model;
``none``), photon and read noise; the recording window the predicted passage ± the time error
(stage ``record``); ``solve`` (:class:`~cssat.experiments.forward.shadow_score.ShadowSolved`) —
:func:`~cssat.occultation.invert_event` (the offsets, speed, gains and the star's diameter
estimated with the silhouette; ``event.oracle: true`` hands them over: the labelled oracle row),
the prior (``invert.prior``; pixels, or shapes kept when held-out telescopes prefer them);
``score`` (the metrics) and ``write`` (:mod:`cssat.experiments.forward.shadow_score`).

Assumptions: Fresnel diffraction of a thin opaque screen (Babinet) at the satellite's distance;
a point-like line of sight per telescope averaged over its aperture and exposure; the shadow's
velocity constant over the event; level ground, the local vertical the geocentric one (≤ 0.2°
from the geodetic); scintillation as in :mod:`cssat.occultation.nuisance`; the photon count
from cssat's V zero point for the star's magnitude in the band.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from cssat.experiments.build import build, build_model, build_solver
from cssat.experiments.context import Run
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.shadow_measure import MAX_EXPOSURES, ShadowMeasured, measure_event
from cssat.experiments.forward.shadow_score import ShadowSolved, score_event, solve_event, write_event
from cssat.models.shadow.config import ShadowSettings
from cssat.occultation import teff_from_bv

__all__ = ["Shadow", "ShadowPlan", "MAX_EXPOSURES"]

log = logging.getLogger("cssat")


@dataclass
class ShadowPlan:
    """What the shadow model's ``plan`` stage hands on: the typed settings and the objects built
    from the other groups, checked before any work."""

    settings: ShadowSettings  #: the model's own groups (``star``, ``optics``, ``event``, ``array``, ``silhouette``, ``invert``)
    scenario_cfg: Any  #: the config ``build_scenario`` reads: 3 one-second steps from ``scenario.start_utc``
    mesh: Any  #: the ``model`` group's mesh
    attitude: Any  #: the ``attitude`` group's object (``None``: nadir)
    solver: Any  #: the ``solver`` group's solver for the linear route (``None``: ``invert.init: empty``)
    teff: float  #: the star's effective temperature (K) from ``star.bv``
    metrics: dict[str, Any]  #: the plan's metrics (the model, the seed, the row's label)


def _scenario_cfg(cfg: Any) -> Any:
    """``cfg`` resolved, its ``scenario`` set to 3 one-second steps around the occultation."""
    from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

    cfg2 = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    with open_dict(cfg2):
        cfg2.scenario.n_steps, cfg2.scenario.step_s, cfg2.scenario.times = 3, 1.0, None
    return cfg2


class Shadow(ForwardModel):
    """A silhouette through Fresnel diffraction onto an array of telescopes (the module's
    docstring has the stages): ``plan`` returns a :class:`ShadowPlan`, ``measure`` a
    :class:`~cssat.experiments.forward.shadow_measure.ShadowMeasured`, ``solve`` a
    :class:`~cssat.experiments.forward.shadow_score.ShadowSolved`, ``score`` the metrics; the
    later stages read them with ``run.result(stage)``."""

    name = "shadow"
    timed_inside = ("measure", "solve")
    #: the nuisances are estimated with the silhouette (solve) from the recorded series (measure)
    needs = {"measure": ("plan",), "solve": ("plan", "measure"), "score": ("plan", "measure", "solve"),
             "write": ("plan", "measure", "solve", "score")}

    def plan(self, cfg: Any, run: Run) -> ShadowPlan:
        s = ShadowSettings.from_config(cfg)
        teff = teff_from_bv(s.star.bv)
        solver = build_solver(cfg.solver, None, s.size_inv ** 2) if s.invert.init == "linear" else None
        mesh = build_model(cfg.model)
        attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": mesh.name, "seed": run.seed, "row": s.row}
        return ShadowPlan(s, _scenario_cfg(cfg), mesh, attitude, solver, teff, metrics)

    def measure(self, run: Run) -> ShadowMeasured:
        return measure_event(run.result("plan"), run)

    def solve(self, run: Run) -> ShadowSolved:
        return solve_event(run.result("plan"), run.result("measure"), run)

    def score(self, run: Run) -> dict[str, Any]:
        return score_event(run.result("plan"), run.result("measure"), run.result("solve"))

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        write_event(run.result("plan"), run.result("measure"), run.result("solve"), run, metrics)

    def headline(self, metrics: dict[str, Any], run: Run) -> str:
        return (f"occultation ({metrics['row']}): {metrics['model']} at {metrics['distance_km']:.0f} km, "
                f"shadow {metrics['shadow_speed_km_s']:.2f} km/s; "
                f"{metrics['n_telescopes']} of {metrics['n_slots']} telescopes; IoU {metrics['iou']:.3f} registered "
                f"({metrics['iou_placed']:.3f} where the fit placed it); time offset {metrics['time_offset_s'] * 1e3:+.3f} ms "
                f"(true {metrics['time_offset_true_s'] * 1e3:+.3f}), path {metrics['path_offset_m']:+.2f} m "
                f"(true {metrics['path_offset_true_m']:+.2f})")
