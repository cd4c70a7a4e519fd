"""The EGI forward model (``forward: egi``; ``cssat experiment=inversion``): a satellite's
extended Gaussian image measured as its light curve through a scene and an attitude — compressed
sensing whose sensing matrix is known and real (:mod:`cssat.inversion`).

Stages: ``plan`` — every setting of ``nights``, ``inversion`` (its ``tumbling`` options too),
``model``, ``attitude``, ``brdf``, ``noise`` and the measured file checked, the scenario's size
and memory estimated; ``measure`` — the ``model`` in the ``attitude`` over ``nights.n`` nights of
the ground station (``scenario``: the samples where the Sun is below ``nights.sun_alt_max_deg``,
the object above ``nights.min_elevation_deg`` and fully sunlit), its light curve with the
``brdf`` group's surface and ``shadows``, photometric noise (``noise``); or the measured light
curve ``observations=<file>`` (read with the ``observed`` settings; its time stamps give the
scenario; the ``scenario.tle`` must be the object's), its nights split by gaps over 6 h; the
first ``nights.fit`` nights fitted (null: all but the last), the others held out; ``estimate``
— the attitude, whose frames make the EGI operator (``inversion.spin``: ``search`` — the pole and
sidereal period by :func:`~cssat.inversion.estimate_spin` —, ``tumbling`` — the torque-free state
by :func:`~cssat.inversion.estimate_tumbling` —, ``known`` — the true attitude, an **oracle** —,
or ``auto``: search for a ``spin`` attitude or a measured file, tumbling for a ``tumbling``
attitude, known otherwise); ``solve`` — the EGI on ``inversion.n_normals`` normals and its
convex shape (:func:`~cssat.inversion.invert_convex`) — or with ``inversion.shape=parametric`` a
shadowed box-wing fitted from it (:mod:`~cssat.experiments.forward.egi_parametric`) —, the held-out nights predicted, the
observability of the fitted geometry; ``score`` — against the truth (none for a file);
``write`` — ``arrays.npz``, ``shape.obj`` (metres), ``egi.csv``, ``lightcurve.csv`` and the
figures ``inversion_lightcurve``, ``inversion_egi``, ``inversion_shapes``,
``inversion_observability``.

Assumptions: those of :func:`~cssat.inversion.egi_operator` (no shadowing in the model, single
scattering, one BRDF shape) and of the attitude searched (a principal-axis spin, or torque-free
rotation); the simulated truth has shadows when ``shadows`` is true.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param
from cssat.experiments.build import build, build_model, build_solver, settings, validate_solver
from cssat.experiments.context import Run, as_field
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.egi_parametric import check_shape_settings, score_parametric, solve_parametric, write_parametric
from cssat.experiments.forward.egi_score import (EGI_MATCH_DEG, EGI_WEIGHT_SHARE, egi_recovered_share, score_truth, solve_egi,
                                                 write_egi)
from cssat.experiments.forward.nights import (check_constrained, check_search, check_size, night_index, night_mask,
                                              nights_settings, span_seconds)
from cssat.experiments.scene import build_scenario, check_elements, read_observations
from cssat.inversion import estimate_spin, estimate_tumbling, estimate_tumbling_periods
from cssat.inversion.tumble import check_tumbling_options
from cssat.optics.lightcurve import simulate_light_curve
from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2
from cssat.scene.attitude import nadir_pointing_frame, to_body
from cssat.scene.attitudes import Spin, Tumbling

__all__ = ["EGILightCurve", "egi_recovered_share", "EGI_WEIGHT_SHARE", "EGI_MATCH_DEG"]

log = logging.getLogger("cssat")

#: the EGI solve's settings that are the ``solver`` group's (``solver=nntv solver.lam=...``)
MOVED_TO_SOLVER = ("method", "lam", "n_nonzero", "tv_neighbours")
#: the spin search's settings read from the ``inversion`` group
SEARCH_KEYS = ("n_poles", "n_starts", "n_refine", "coarse_normals", "coarse_samples", "max_samples", "min_period_s",
               "max_period_s", "split_nights")



class EGILightCurve(ForwardModel):
    """The EGI through a scene and an attitude (the module's docstring has the stages)."""

    name = "egi"
    timed_inside = ("measure", "estimate", "solve")
    #: the samples and nights (measure) → the periods and the attitude's frames on the fitted nights
    #: (estimate) → the EGI from those frames with plan's solver (solve) → the truth's errors
    #: (score: the true frames of measure) → arrays and figures
    needs = {"measure": ("plan",), "estimate": ("plan", "measure"), "solve": ("plan", "measure", "estimate"),
             "score": ("measure", "estimate", "solve"), "write": ("measure", "solve", "score")}

    def plan(self, cfg: Any, run: Run) -> None:
        self.cfg = cfg
        self.n_nights, self.n_fit, self.sun_alt, self.min_el = nights_settings(cfg)
        inv = self.inv = cfg.get("inversion") or {}
        spin_mode = choice_param(inv.get("spin", "auto"), "inversion.spin", ("auto", "search", "tumbling", "known"))
        self.tumble = {k: v for k, v in settings(inv.get("tumbling")).items() if v is not None}
        with as_field("inversion.tumbling"):  # every option of the tumbling search, before any work
            check_tumbling_options(**self.tumble)
        self.n_normals = int_param(inv.get("n_normals", 2000), "inversion.n_normals", 16, 20000)
        self.search_normals = int_param(inv.get("search_normals", 1000), "inversion.search_normals", 16, 20000)
        for key in MOVED_TO_SOLVER:
            if key in inv:
                raise FieldError(f"inversion.{key}", "the EGI's solve is the solver group's: solver=nnls|nnomp|nnl1|nntv "
                                                     "(e.g. solver=nntv solver.lam=discrepancy)")
        self.solver = build_solver(cfg.solver, None, self.n_normals)  # its size-dependent settings once the samples are known
        if getattr(self.solver, "unknown", "any") == "image":
            raise FieldError("solver", f"{getattr(self.solver, 'name', 'this solver')} works on images; the EGI is areas on "
                                       "the sphere's normals: solver=nnls|nnomp|nnl1|nntv (nntv: TV on the sphere)")
        self.closure = float_param(inv.get("closure", 1.0), "inversion.closure", 0.0)
        self.shape_opts = check_shape_settings(inv)
        self.search = {k: inv[k] for k in SEARCH_KEYS if inv.get(k) is not None}
        self.mesh = build_model(cfg.model)
        self.attitude = build(cfg.attitude, "attitude") if cfg.get("attitude") is not None else None
        self.observed = read_observations(cfg)
        # the spin search's settings, before any work, with their full keys; the longest period against a
        # simulation's span here, against a measured file's once its usable nights are known (measure)
        check_search(self.search, span_seconds(cfg, None, self.n_nights) if self.observed is None else None)
        self.auto = spin_mode == "auto"
        self.spin_mode = self._resolve(spin_mode)
        check_size(cfg, self.n_nights, len(self.mesh.faces) if hasattr(self.mesh, "faces") else 0, self.spin_mode != "known",
                   self.n_normals)
        self.shadows = bool_param(cfg.get("shadows", True), "shadows")
        self.brdf = build(cfg.brdf, "brdf") if cfg.get("brdf") is not None and cfg.brdf.get("_target_") else None
        # the surface the inversion assumes, whatever the truth's (a real satellite's materials are unknown):
        # Lambert, an EGI per scattering lobe (diffuse + Blinn–Phong lobes: glints, mixed materials), or the
        # simulated one — the in-class oracle
        assumed = choice_param(inv.get("brdf", "lambert"), "inversion.brdf", ["lambert", "lobes", "simulated"])
        lobes = inv.get("lobes", [100.0])
        if assumed == "lobes":
            from cssat.inversion.egi import Lobes  # heavy: cssat.inversion.egi imports torch

            try:
                self.model_brdf = Lobes(list(lobes) if not isinstance(lobes, (int, float, str)) else lobes)
            except (FieldError, TypeError, ValueError) as e:
                raise FieldError("inversion.lobes", f"expected a list of Blinn–Phong exponents in [1, 1e5] (e.g. [100]), "
                                                    f"got {lobes!r}") from e
        else:
            self.model_brdf = self.brdf if assumed == "simulated" else None
        self.noise = build(cfg.get("noise"), "noise")
        if self.observed is not None:
            check_elements(cfg, self.observed)
        self.metrics: dict[str, Any] = {"psnr": None, "ssim": None, "model": self.mesh.name, "seed": run.seed}
        if self.observed is None:  # what the truth had and what the inversion assumed: in class only when both agree
            self.metrics.update(truth_brdf=self.brdf.name if self.brdf is not None else "mesh", truth_shadows=self.shadows,
                                inversion_brdf=self.model_brdf.name if self.model_brdf is not None else "lambert")

    def _resolve(self, spin_mode: str) -> str:
        """``auto``: a spin attitude is searched as one, a tumbling one as one, a file as a spin (the
        2-D series' BIC also prefers two periods for a spinner seen over changing geometry: a file's
        tumbling search is asked for, ``inversion.spin=tumbling``, not guessed); else known."""
        if spin_mode != "auto":
            return spin_mode
        if isinstance(self.attitude, Tumbling):
            return "tumbling"
        return "search" if self.observed is not None or isinstance(self.attitude, Spin) else "known"

    def measure(self, run: Run) -> None:
        with run.stage("scene"):
            self._scene()
        with run.stage("light_curve"):
            self._light_curve(run)

    def _scene(self) -> None:
        """The scenario and its observable samples: the file's time stamps, or ``nights.n`` days."""
        cfg, observed = self.cfg, self.observed
        if observed is not None:
            scenario = build_scenario(cfg, observed.times_utc)
            keep = np.isfinite(observed.fluxes()) & (scenario.sunlit > 0)
        else:
            from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

            step = float_param(cfg.scenario.step_s, "scenario.step_s", 0.0, open_lo=True)
            cfg2 = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
            with open_dict(cfg2):
                cfg2.scenario.n_steps = int(round(self.n_nights * 86400.0 / step))
                cfg2.scenario.times = None
            scenario = build_scenario(cfg2)
            keep = night_mask(scenario, self.sun_alt, self.min_el)
        if not keep.any():
            raise FieldError("nights", "no sample is observable (night, elevation, sunlit): widen nights.* or check scenario.*")
        seconds_all = (scenario.times - scenario.times[0]) / np.timedelta64(1, "s")
        self.t = t = seconds_all[keep]
        self.night = night = night_index(t)
        self.scenario, self.keep = scenario, keep
        self.metrics.update(n_samples=int(keep.sum()), n_nights_observed=int(night.max() + 1))
        validate_solver(self.solver, int(keep.sum()), self.n_normals)
        if observed is not None:
            check_constrained(observed, t, night)
            if self.spin_mode != "known":
                check_search(self.search, span_seconds(cfg, observed, self.n_nights))
            if observed.ranges_km is not None:  # the file's own range against the element set's
                self.metrics["range_diff_km_median"] = float(np.median(np.abs(scenario.range_km - observed.ranges_km)[keep]))

    def _light_curve(self, run: Run) -> None:
        """The light curve per unit irradiance and range, its 1σ, the fitted and held-out nights."""
        sc, keep, noise, observed = self.scenario, self.keep, self.noise, self.observed
        self.unit = unit = ((sc.range_km * 1e3) ** 2 / SOLAR_IRRADIANCE_W_M2)[keep]  # W/m² → per unit irradiance and range
        self.sun_in, self.obs_in = sc.sun_dir[keep], sc.obs_dir[keep]
        self.true_frames = None
        if self.attitude is not None or observed is None:
            frames_all = self.attitude.frames(sc) if self.attitude is not None else nadir_pointing_frame(sc.r_sat, sc.v_sat)
            self.true_frames = frames_all[keep]
        if observed is not None:
            flux_w = observed.fluxes()[keep]
            err = observed.flux_errors()
            sigma_w = err[keep] if err is not None else None
            clean_w = None
        else:
            lc = simulate_light_curve(self.mesh, sc, shadows=self.shadows, attitude=self.attitude, brdf=self.brdf)
            clean_w = lc.flux.numpy()[keep]
            gen = torch.Generator().manual_seed(run.seed)
            y = torch.as_tensor(clean_w, dtype=torch.float64)[None]
            ref = y.mean(-1) if getattr(noise, "magnitude", None) is not None else None
            flux_w = noise(y, gen, flux=ref)[0].numpy() if ref is not None else noise(y, gen)[0].numpy()
            var = noise.variance(torch.as_tensor(flux_w)[None], flux=ref)[0].numpy() if hasattr(noise, "variance") else None
            sigma_w = np.sqrt(var) if var is not None and np.all(var > 0) else None
        self.flux_w, self.sigma_w, self.clean_w = flux_w, sigma_w, clean_w
        self.y = y_unit = flux_w * unit
        self.sigma = sigma = sigma_w * unit if sigma_w is not None else None
        n_fit = max(int(self.night.max()), 1) if self.n_fit is None else self.n_fit
        self.fit = self.night < n_fit
        self.held = ~self.fit
        self.metrics.update(n_fit=int(self.fit.sum()), n_heldout=int(self.held.sum()), **noise.describe())
        if sigma is not None:
            self.metrics["noise_relative_median"] = float(np.median(sigma / np.maximum(np.abs(y_unit), 1e-300)))

    def estimate(self, run: Run) -> None:
        with run.stage("spin"):
            self._two_periods()
            self._attitude()

    def _two_periods(self) -> None:
        """One period or two: a tumbling (non-principal-axis) light curve has two fundamental frequencies."""
        fit, sigma, inv = self.fit, self.sigma, self.inv
        try:
            tp = estimate_tumbling_periods(self.t[fit], self.y[fit], sigma=None if sigma is None else sigma[fit],
                                           min_period_s=float(inv.get("min_period_s") or 60.0),
                                           max_period_s=float(inv.get("max_period_s") or 86400.0))
            self.metrics.update(lc_tumbling=tp["tumbling"], lc_delta_bic=tp["delta_bic"], lc_aperiodic=tp["aperiodic"],
                                lc_periods_s=[float(p) for p in tp["periods_s"]], lc_single_period_s=tp["single_period_s"])
            if tp["tumbling"] and self.spin_mode == "search" and (not self.auto or self.observed is not None):
                log.warning("inversion: no single period folds the light curve (aperiodic fraction %.3f; two periods "
                            "%.1f s, %.1f s): it looks tumbling, and the spin search assumes a principal-axis rotation "
                            "(inversion.spin=tumbling searches a torque-free tumbling state)", tp["aperiodic"], *tp["periods_s"])
        except FieldError as e:  # too few samples or no second frequency: the period analysis is skipped
            log.info("inversion: no two-period analysis (%s)", e)

    def _attitude(self) -> None:
        """The frames of the fitted attitude, and the body-frame Sun and observer: the EGI operator's geometry."""
        fit, sigma, spin_mode = self.fit, self.sigma, self.spin_mode
        if spin_mode == "known" and self.true_frames is None:
            raise FieldError("inversion.spin", "'known' needs an attitude model (attitude=...) for a measured light curve")
        args = (self.t[fit], self.y[fit], self.sun_in[fit], self.obs_in[fit])
        kw = dict(sigma=None if sigma is None else sigma[fit], brdf=self.model_brdf, frame=getattr(self.attitude, "frame", "ecliptic"))
        self.sol = sol = None
        held = self.held if sigma is not None and self.held.any() else None  # the nights held out test the model
        heldout = None if held is None else (self.t[held], self.y[held], self.sun_in[held], self.obs_in[held], sigma[held])
        if spin_mode == "search":
            self.sol = sol = estimate_spin(*args, **kw, n_normals=self.search_normals, heldout=heldout, **self.search)
            frames = sol.frames(self.t)
            self.metrics.update(sol.describe())
            # the synodic period the search started from (the period search's best candidate, whatever its verdict)
            self.metrics["spin_synodic_period_s"] = float(sol.synodic.get("best_period_s", sol.synodic["period_s"]))
            self.metrics["spin_synodic_verdict"] = sol.synodic.get("verdict", "given")
        elif spin_mode == "tumbling":
            self.sol = sol = estimate_tumbling(*args, **kw, heldout=heldout, **self.tumble)
            frames = sol.frames(self.t)
            self.metrics.update(sol.describe())
        else:
            frames = self.true_frames
        if sol is not None and sol.get("verdict") == "unreliable":
            log.warning("inversion: unreliable — %s", sol["verdict_why"])
        elif sol is not None and sol.model_fits is False:
            kind, what, err = (("spin", "the pole's", sol.pole_err_deg) if spin_mode == "search"
                               else ("tumbling", "the angular momentum's", sol.errors["L_err_deg"]))
            log.warning("inversion: the %s model misses the light curve by more than its noise (reduced χ² %.3g): "
                        "shadows, glints or materials it does not have; %s 1σ (%.2g°) counts that misfit as white "
                        "noise and can miss the truth by many times itself", kind, sol.reduced_chi2, what, err)
        self.frames = frames
        self.metrics.update(spin=spin_mode, attitude_known=spin_mode == "known")
        self.sun_b, self.obs_b = to_body(frames, self.sun_in), to_body(frames, self.obs_in)

    def solve(self, run: Run) -> None:
        with run.stage("invert"):
            solve_egi(self)
            if self.shape_opts["shape"] == "parametric":
                solve_parametric(self)

    def score(self, run: Run) -> dict[str, Any]:
        self.truth = score_truth(self) if self.observed is None and self.true_frames is not None else {}
        if self.truth:
            score_parametric(self, self.frames[0] @ self.true_frames[0].T)
        return self.metrics

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        write_egi(self, run)
        write_parametric(self, run.out_dir)

    def headline(self, metrics: dict[str, Any]) -> str:
        typ = metrics.get("heldout_typical_over_noise")
        return ("inversion: {} samples over {} nights, {}{}, EGI {} normals, held-out rms {}× noise{}".format(
            metrics["n_samples"], metrics["n_nights_observed"],
            repr(self.sol) if self.sol is not None else "attitude known (oracle)",
            f", pole error {metrics['pole_error_deg']:.2f}°" if "pole_error_deg" in metrics else "",
            metrics["egi_n_normals"], f"{metrics['heldout_rms_over_noise']:.2f}" if metrics.get("heldout_rms_over_noise") else "-",
            f" (typical sample {typ:.2f}×)" if typ is not None else ""))
