"""A measured light curve as a forward model (``forward: observed``; ``cssat experiment=characterise
observations=<file>``, issue 34, point 5): what a real track says, stage by stage, and why a stage
was skipped. Nothing is simulated: the light curve is the file's, and the verdicts are what is
estimated from it.

Stages of :class:`Observed` (run by :func:`~cssat.experiments.forward.base.run_model`; the
``seconds_<name>`` timings in brackets):

``plan`` (``setup``)
    every setting checked before any work, each refusal a :class:`~cssat._checks.FieldError` with
    its full key: ``observations`` given, ``observed.*`` (the arguments of
    :func:`cssat.data.read_light_curve`), ``stages.*`` (``auto`` runs a stage where the data allow
    and records why not otherwise; ``on`` requires it — the run stops with exit 2 naming what is
    missing —; ``off``; ``stages.spin=on`` without ``scenario.tle`` is refused here, with fewer
    nights than ``characterise.min_nights`` at ``clean``), the options under ``period`` and ``tumbling`` (those of
    :func:`cssat.inversion.estimate_period` and :func:`cssat.inversion.estimate_tumbling_periods`)
    and ``characterise.*``;
``measure`` (``read``, ``clean``)
    ``read``: :func:`cssat.data.read_light_curve` with the ``observed`` settings (format by
    content: MMT-9, SCORE, ALCDEF, ECSV/FITS, CSV); ``characterise.tracks`` keeps those tracks;
    a ``scenario.tle`` given must be the file's object's, near its dates. ``clean``: drops the
    samples flagged in penumbra (MMT's ``Penumbra``), refuses fewer than
    ``characterise.min_samples``; where the file gives each sample's range, apparent magnitudes
    are reduced to 1000 km (``characterise.normalise_range``: the pass's range trend is not the
    object's light curve);
``estimate`` (``period``, ``tumbling``, ``spin``)
    the verdicts (:mod:`cssat.experiments.forward.verdicts`): the period on the magnitudes —
    ``verdict`` (one word: ``periodic``, ``not periodic``, ``undetermined``; ``failed`` is a
    failed run's), ``why`` (one sentence), ``periodic`` (true, false, null: undetermined),
    ``period_s``, ``period_err_s``, ``fap``, ``alternatives``, ``chi2_per_sample``,
    ``warnings`` (one string, ``; ``-joined), compared with the file's published period if any
    —; ``tumbling`` when the curve holds enough samples for the 2-D series and (``auto``) the
    period stage asks for it: a curve not called periodic that varies over twice its noise
    (``variation_over_noise``), or a period whose model misfits; ``spin`` — the pole, sidereal period and
    convex shape (:func:`cssat.inversion.estimate_spin`, :func:`cssat.inversion.minkowski`) — from
    a periodic curve, the object's element set (``scenario.tle``, checked against the file's
    NORAD id and epoch) and at least ``characterise.min_nights`` nights, the scenario's range and
    phase angle compared with the file's where both exist;
``solve``
    nothing: the verdicts are the answer;
``score``
    the metrics, a catalogue row (summary.csv keeps every scalar): the file's ``object_id``
    (NORAD), ``object_name``, ``track`` (its track ids, ``;``-joined), ``start_utc``, ``band``,
    ``period_magnitudes`` (which magnitudes were searched), ``n_nights``, the verdicts above and
    every stage's ``stage_<name>``: ``ok``, ``skipped: <why>`` or ``off``;
``write``
    ``arrays.npz`` (times s, values, the fitted model and trend, the periodogram),
    ``alternatives.csv``, ``tracks.csv`` (a file of several tracks: each one's own period and
    verdict), ``shape.obj`` when the spin stage ran (written by it), and the figure
    ``characterise`` (the light curve with its gaps, the periodogram with the alternatives
    marked, the phase-folded curve with the model, the residuals).
"""

from __future__ import annotations

import contextlib
import inspect
from typing import Any, Iterator

import numpy as np

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param
from cssat.experiments.build import settings
from cssat.experiments.context import Run
from cssat.experiments.files import write_csv, write_npz
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.verdicts import (VERDICT_STAGES, count_nights, fitted_model, period_stage, spin_stage,
                                                tumbling_stage, variation_over_noise)
from cssat.experiments.scene import check_elements, read_observations
from cssat.plots import save_figure

__all__ = ["Observed", "observed_settings", "STAGE_MODES"]

#: the modes of each stage of ``stages``
STAGE_MODES = ("auto", "on", "off")
#: the settings of the ``characterise`` group
CHARACTERISE_KEYS = {"tracks", "min_samples", "drop_penumbra", "min_nights", "max_epoch_days", "figures", "normalise_range"}



def observed_settings(cfg: Any) -> dict[str, Any]:
    """Every setting of the experiment checked before any work (a FieldError with its full key)."""
    from cssat.inversion import estimate_period, estimate_tumbling_periods  # heavy: cssat.inversion imports torch

    if not cfg.get("observations"):
        raise FieldError("observations", "characterise needs a light-curve file: observations=<path>")
    read_observations(cfg, check_only=True)  # the observed.* keys: read_light_curve's arguments
    stages = settings(cfg.get("stages"))
    for k in stages:
        if k not in VERDICT_STAGES:
            raise FieldError(f"stages.{k}", f"not a stage; the stages: {', '.join(VERDICT_STAGES)}")
    modes = {k: choice_param(stages.get(k, "auto"), f"stages.{k}", STAGE_MODES) for k in VERDICT_STAGES}
    for node, fn in (("period", estimate_period), ("tumbling", estimate_tumbling_periods)):
        allowed = [p for p in inspect.signature(fn).parameters if p not in ("times_s", "flux", "sigma", "segments")]
        for k in settings(cfg.get(node)):
            if k not in allowed:
                raise FieldError(f"{node}.{k}", f"not an option of {fn.__name__}; its options: {', '.join(allowed)}")
    tum = settings(cfg.get("tumbling"))  # checked here: stages.tumbling auto runs the search on few curves
    if tum.get("aperiodic_threshold") is not None:
        float_param(tum["aperiodic_threshold"], "tumbling.aperiodic_threshold", 0.0, 1.0, open_lo=True)
    for key in ("window_s", "min_period_s", "max_period_s"):
        if tum.get(key) is not None:
            float_param(tum[key], f"tumbling.{key}", 0.0, open_lo=True)
    if tum.get("order") is not None:
        int_param(tum["order"], "tumbling.order", 1, 10)
    if tum.get("n_peaks") is not None:
        int_param(tum["n_peaks"], "tumbling.n_peaks", 2, 50)
    if tum.get("samples_per_peak") is not None:
        int_param(tum["samples_per_peak"], "tumbling.samples_per_peak", 1)
    ch = settings(cfg.get("characterise"))
    for k in ch:
        if k not in CHARACTERISE_KEYS:
            raise FieldError(f"characterise.{k}", f"not a setting; the settings: {', '.join(sorted(CHARACTERISE_KEYS))}")
    if modes["spin"] == "on" and modes["period"] == "off":  # known before the file is read
        raise FieldError("stages.spin", "the spin stage needs the period stage's periodic verdict, and stages.period is "
                                        "off")
    if modes["spin"] == "on" and (cfg.get("scenario") or {}).get("tle") is None:
        raise FieldError("stages.spin", "the spin stage needs the object's element set: give scenario.tle (or "
                                        "stages.spin=auto records the stage as skipped)")
    return {"modes": modes, "min_samples": int_param(ch.get("min_samples", 20), "characterise.min_samples", 12),
            "drop_penumbra": bool_param(ch.get("drop_penumbra", True), "characterise.drop_penumbra"),
            "min_nights": int_param(ch.get("min_nights", 2), "characterise.min_nights", 1),
            "max_epoch_days": float_param(ch.get("max_epoch_days", 14.0), "characterise.max_epoch_days", 0.0,
                                          open_lo=True), "tracks": ch.get("tracks"),
            "figures": bool_param(ch.get("figures", True), "characterise.figures"),
            "normalise_range": bool_param(ch.get("normalise_range", True), "characterise.normalise_range"),
            "period": {k: v for k, v in settings(cfg.get("period")).items() if v is not None},
            "tumbling": {k: v for k, v in settings(cfg.get("tumbling")).items() if v is not None}}


def _plain(v: Any) -> Any:
    """A metric as JSON's own type: numpy booleans, integers and floats as Python's."""
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


class Observed(ForwardModel):
    """A measured light curve and its verdicts (the module's docstring has the stages).

    A stage that fails leaves what was known on the exception as ``partial_metrics`` (the
    file's object, track, … and ``verdict: "failed"``, ``why``: the error), for a catalogue row
    of a failed job."""

    name = "observed"
    timed_inside = ("measure", "estimate", "solve")
    #: the verdicts (estimate) from the cleaned curve (measure) are the answer: nothing is solved
    needs = {"measure": ("plan",), "estimate": ("plan", "measure"), "score": ("measure", "estimate"),
             "write": ("plan", "measure", "estimate", "score")}

    def plan(self, cfg: Any, run: Run) -> None:
        """Every setting checked (:func:`observed_settings`); nothing read yet."""
        self.cfg = cfg
        self.metrics: dict[str, Any] = {"psnr": None}
        self.res: dict[str, Any] | None = None
        self.per_track: list[dict[str, Any]] | None = None
        with self._failure():
            self.opt = observed_settings(cfg)

    @contextlib.contextmanager
    def _failure(self) -> Iterator[None]:
        """An exception raised inside carries the metrics so far as ``partial_metrics`` (scalars
        only, ``verdict: "failed"`` and ``why``: the error's one line)."""
        try:
            yield
        except Exception as err:
            part = {k: _plain(v) for k, v in self.metrics.items()
                    if not k.startswith("_") and (v is None or isinstance(v, (str, int, float, bool, np.generic)))}
            part.update(verdict="failed", why=str(err))
            try:
                err.partial_metrics = part  # type: ignore[attr-defined]
            except AttributeError:  # an exception type without a __dict__
                pass
            raise

    def measure(self, run: Run) -> None:
        """The file read (``read``) and cleaned (``clean``): ``t`` (s from the first sample), ``y``
        (magnitudes, range-reduced where so set, or fluxes), ``sig`` (their 1σ) and ``tracks``."""
        with self._failure():
            with run.stage("read"):
                self._read()
            with run.stage("clean"):
                self._clean()

    def _read(self) -> None:
        """The light curve of ``observations`` with the ``observed`` settings, its tracks selected,
        a given element set checked against it; the file's own description in the metrics:
        ``object_id`` (the NORAD id), ``object_name``, ``track`` (the file's track ids, ``;``-joined;
        null when it names none), ``band`` (the magnitudes' filter, e.g. MMT's ``Clear``)."""
        cfg, opt, m = self.cfg, self.opt, self.metrics
        lc = read_observations(cfg)
        if opt["tracks"] is not None:
            try:
                lc = lc.select(list(opt["tracks"]) if not isinstance(opt["tracks"], (str, int)) else [opt["tracks"]])
            except FieldError as err:
                raise FieldError("characterise.tracks", err.detail) from None
        meta = lc.meta
        band = (settings(cfg.get("observed")).get("band") or None)
        if (band is None or band == "file") and lc.filters is not None:
            band = "/".join(dict.fromkeys(str(f) for f in lc.filters))
        m.update(object_id=meta.get("object_id"), object_name=meta.get("name"), file_format=meta.get("format"),
                 track=";".join(dict.fromkeys(str(x) for x in lc.tracks)) if lc.tracks is not None else None,
                 file_variability=meta.get("variability"), published_period_s=meta.get("published_period_s"),
                 magnitude_system=lc.magnitude_system, band=None if band is None else str(band), n_rows=len(lc))
        if cfg.scenario.get("tle") is not None:  # an element set given is the file's object's, near its dates
            check_elements(cfg, lc, opt["max_epoch_days"])
        self.lc = lc

    def _clean(self) -> None:
        """Penumbra dropped, too few samples refused, apparent magnitudes reduced to 1000 km;
        ``stages.spin=on`` refused here, before any search, when the file holds fewer than
        ``characterise.min_nights`` nights. ``period_magnitudes``: what the period stage's values
        are (``apparent``, ``apparent, reduced to a range of 1000 km``, MMT StdMag's
        ``normalised: 1000 km, phase 90°``, or ``flux``)."""
        lc, opt, m = self.lc, self.opt, self.metrics
        if opt["drop_penumbra"] and lc.penumbra is not None and lc.penumbra.any():
            m["n_penumbra_dropped"] = int(lc.penumbra.sum())
            lc = lc.rows(~lc.penumbra)
        if len(lc) < opt["min_samples"]:
            raise FieldError("observations", f"{len(lc)} usable samples; characterise needs at least {opt['min_samples']} "
                                             "(characterise.min_samples)")
        t = lc.times_s()
        y = lc.magnitudes() if lc.kind == "magnitude" else lc.values
        sig = lc.magnitude_errors() if lc.kind == "magnitude" else lc.errors
        tracks = lc.track_ids()
        m["period_magnitudes"] = lc.magnitude_system if lc.kind == "magnitude" else "flux"
        if opt["normalise_range"] and lc.kind == "magnitude" and lc.ranges_km is not None and lc.magnitude_system == "apparent":
            y = y - 5.0 * np.log10(lc.ranges_km / 1000.0)  # the range's inverse square out, to 1000 km (MMT's StdMag's)
            m["period_magnitudes"] = "apparent, reduced to a range of 1000 km"
        nights = count_nights(t)
        m.update(n_samples=len(lc), n_tracks=len(set(tracks)), n_nights=nights, span_s=float(t[-1]),
                 start_utc=str(lc.times_utc[0]))
        if opt["modes"]["spin"] == "on" and nights < opt["min_nights"]:
            raise FieldError("stages.spin", f"the spin stage needs {opt['min_nights']} nights (characterise.min_nights); "
                                            f"the file holds {nights}: one pass does not constrain a pole")
        self.lc, self.t, self.y, self.sig, self.tracks = lc, t, y, sig, tracks

    def estimate(self, run: Run) -> None:
        """The verdicts, each timed under its own name: ``period``, ``tumbling``, ``spin``;
        ``variation_over_noise`` first (what ``stages.tumbling: auto`` asks of the period stage)."""
        with self._failure():
            self.metrics["variation_over_noise"] = variation_over_noise(self.t, self.y, self.sig, self.tracks)
            self.res = period_stage(run, self.opt, self.t, self.y, self.sig, self.tracks, self.metrics, self.lc.channels)
            tumbling_stage(run, self.opt, self.t, self.y, self.sig, self.res, self.metrics)
            spin_stage(run, self.cfg, self.opt, self.lc, self.t, self.res, self.metrics)

    def solve(self, run: Run) -> None:
        """Nothing to solve: the verdicts are the answer (and nothing is timed)."""

    def score(self, run: Run) -> dict[str, Any]:
        """The metrics (numpy scalars as JSON's booleans and numbers); the per-track rows kept
        aside for ``tracks.csv``."""
        self.per_track = self.metrics.pop("_tracks", None)
        self.metrics = {k: _plain(v) for k, v in self.metrics.items()}
        return self.metrics

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        """``tracks.csv``, ``alternatives.csv``, ``arrays.npz`` and the ``characterise`` figure."""
        t, y, res, lc = self.t, self.y, self.res, self.lc
        arrays: dict[str, Any] = {"times_s": t, "values": y}
        if self.per_track:
            write_csv(run.out_dir / "tracks.csv", self.per_track)
        if res is not None:
            model, trend = fitted_model(t, y, res, int(self.opt["period"].get("detrend", 2)), lc.track_ids(), lc.channels)
            arrays.update(model=model, trend=trend, frequency_hz=res["periodogram"]["frequency_hz"],
                          power=res["periodogram"]["power"])
            write_csv(run.out_dir / "alternatives.csv", res["alternatives"] or [{"relation": "none"}])
        write_npz(run.out_dir / "arrays.npz", **arrays)
        if self.opt["figures"]:
            from cssat.plots.characterise import characterise_figure, figure_labels  # heavy: matplotlib

            labels = figure_labels(lc.meta, metrics, lc.kind, metrics.get("band"))
            save_figure(characterise_figure(t, y, lc.magnitude_errors() if lc.kind == "magnitude" else lc.errors, res,
                                            arrays.get("model"), lc.kind, trend=arrays.get("trend"), labels=labels,
                                            verdict=metrics.get("verdict")), run.figure("characterise"))

    def headline(self, metrics: dict[str, Any]) -> str:
        """One line: the verdict and the period, or why there is none, and the skipped stages."""
        m = metrics
        name = " ".join(str(x) for x in (m.get("object_id"), m.get("object_name")) if x) or "the light curve"
        verdict = m.get("verdict")
        if verdict == "periodic":
            head = (f"{name}: periodic, P = {m['period_s']:.6g} ± {m['period_err_s']:.2g} s (FAP {m['fap']:.2g}, "
                    f"χ²/N {m['chi2_per_sample']:.3g})")
        elif m.get("stage_period") == "ok":
            head = f"{name}: {verdict} (FAP {m['fap']:.2g}, repeat {m['repeat']:.2g}): {m.get('why')}"
        else:
            head = f"{name}: {verdict}: {m.get('stage_period')}"
        if m.get("n_tracks_periodic") is not None:
            head += f"; {m['n_tracks_periodic']} of {m['n_tracks']} tracks periodic on their own (tracks.csv)"
        skipped = [k for k in VERDICT_STAGES if str(m.get(f"stage_{k}", "")).startswith("skipped")]
        return "characterise: " + head + (f"; skipped: {', '.join(skipped)} (why: metrics.json)" if skipped else "")
