"""A measured light curve as a forward model (``forward: observed``; ``cssat experiment=characterise
observations=<file>``): what a real track says, stage by stage, and why a stage
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
    :func:`cssat.inversion.estimate_period` and :func:`cssat.inversion.estimate_tumbling_periods`;
    ``period.method`` another registered period method, :func:`cssat.inversion.period_methods`)
    and ``characterise.*`` — each group a typed dataclass of :mod:`cssat.models.observed.config`
    (its one set of defaults), the whole handed on as an
    :class:`~cssat.models.observed.config.ObservedSettings`;
``measure`` (``read``, ``clean``; hands on an :class:`ObservedMeasured`)
    ``read``: :func:`cssat.data.read_light_curve` with the ``observed`` settings (format by
    content: MMT-9, SCORE, ALCDEF, ECSV/FITS, CSV); ``characterise.tracks`` keeps those tracks;
    a ``scenario.tle`` given must be the file's object's, near its dates. ``clean``: drops the
    samples flagged in penumbra (MMT's ``Penumbra``), refuses fewer than
    ``characterise.min_samples``; where the file gives each sample's range, apparent magnitudes
    are reduced to 1000 km (``characterise.normalise_range``: the pass's range trend is not the
    object's light curve);
``estimate`` (``period``, ``tumbling``, ``spin``; hands on the :class:`ObservedVerdicts`)
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
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from cssat._checks import FieldError
from cssat.experiments.context import Run
from cssat.experiments.files import write_csv, write_npz
from cssat.experiments.forward.base import ForwardModel
from cssat.experiments.forward.verdicts import (VERDICT_STAGES, count_nights, fitted_model, period_stage,
                                                scenario_config, spin_stage, tumbling_stage, variation_over_noise)
from cssat.experiments.scene import check_elements, read_observations
from cssat.models.observed.config import STAGE_MODES, ObservedSettings
from cssat.plots import save_figure

__all__ = ["Observed", "ObservedMeasured", "ObservedVerdicts", "observed_settings", "STAGE_MODES"]


def observed_settings(cfg: Any) -> ObservedSettings:
    """Every setting of the experiment checked before any work (a FieldError with its full key):
    the typed groups of :class:`~cssat.models.observed.config.ObservedSettings`, the ``observed``
    keys against :func:`cssat.data.read_light_curve`'s, ``stages.spin=on`` against a missing
    ``scenario.tle``."""
    s = ObservedSettings.from_config(cfg)
    read_observations({"observations": s.observations, "observed": _read_options(s)}, check_only=True)
    if s.stages.spin == "on" and s.tle is None:
        raise FieldError("stages.spin", "the spin stage needs the object's element set: give scenario.tle (or "
                                        "stages.spin=auto records the stage as skipped)")
    return s


def _read_options(s: ObservedSettings) -> dict[str, Any]:
    """The ``observed`` group as :func:`cssat.data.read_light_curve`'s keyword arguments."""
    from dataclasses import asdict  # local: one call

    return asdict(s.observed)


@dataclass
class ObservedMeasured:
    """What ``measure`` hands on: the file's light curve read and cleaned.

    ``lc``: the :class:`~cssat.data.ObservedLightCurve` (its tracks selected, penumbra dropped);
    ``t (T,)``: s from the first sample; ``y (T,)``: magnitudes (reduced to 1000 km where so set)
    or fluxes; ``sig (T,)``: their 1σ (``None``: not given); ``tracks (T,)``: each sample's track;
    ``metrics``: the file's description (``object_id``, ``object_name``, ``track``, ``band``,
    ``n_samples``, ``n_nights``, ``span_s``, ``start_utc``, ``period_magnitudes``, …)."""

    lc: Any
    t: np.ndarray
    y: np.ndarray
    sig: np.ndarray | None
    tracks: np.ndarray
    metrics: dict[str, Any] = field(default_factory=dict)


@dataclass
class ObservedVerdicts:
    """What ``estimate`` hands on: the verdicts.

    ``period``: :func:`~cssat.inversion.estimate_period`'s result (``None``: the stage off, or
    the whole curve out of the search's reach); ``per_track``: one row per track (a file of
    several tracks: ``tracks.csv``; ``None``: one track); ``metrics``: the measurement's and
    every verdict stage's (``verdict``, ``why``, ``period_s``, ``stage_<name>``, …)."""

    period: Any
    per_track: list[dict[str, Any]] | None
    metrics: dict[str, Any] = field(default_factory=dict)


def _plain(v: Any) -> Any:
    """A metric as JSON's own type: numpy booleans, integers and floats as Python's."""
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


@contextlib.contextmanager
def _failure(metrics: dict[str, Any]) -> Iterator[None]:
    """An exception raised inside carries ``metrics`` so far as ``partial_metrics`` (scalars
    only, ``verdict: "failed"`` and ``why``: the error's one line)."""
    try:
        yield
    except Exception as err:
        part = {k: _plain(v) for k, v in metrics.items()
                if not k.startswith("_") and (v is None or isinstance(v, (str, int, float, bool, np.generic)))}
        part.update(verdict="failed", why=str(err))
        try:
            err.partial_metrics = part  # type: ignore[attr-defined]
        except AttributeError:  # an exception type without a __dict__
            pass
        raise


class Observed(ForwardModel):
    """A measured light curve and its verdicts (the module's docstring has the stages): ``plan``
    returns the typed :class:`~cssat.models.observed.config.ObservedSettings`, ``measure`` an
    :class:`ObservedMeasured`, ``estimate`` the :class:`ObservedVerdicts`; ``score`` and
    ``write`` read them with ``run.result(stage)``.

    A stage that fails leaves what was known on the exception as ``partial_metrics`` (the
    file's object, track, … and ``verdict: "failed"``, ``why``: the error), for a catalogue row
    of a failed job."""

    name = "observed"
    timed_inside = ("measure", "estimate", "solve")
    #: the verdicts (estimate) from the cleaned curve (measure) are the answer: nothing is solved
    needs = {"measure": ("plan",), "estimate": ("plan", "measure"), "score": ("measure", "estimate"),
             "write": ("plan", "measure", "estimate", "score")}

    def plan(self, cfg: Any, run: Run) -> ObservedSettings:
        """Every setting checked (:func:`observed_settings`); nothing read yet."""
        with _failure({"psnr": None}):
            return observed_settings(cfg)

    def measure(self, run: Run) -> ObservedMeasured:
        """The file read (``read``) and cleaned (``clean``)."""
        s: ObservedSettings = run.result("plan")
        m: dict[str, Any] = {"psnr": None}
        with _failure(m):
            with run.stage("read"):
                lc = _read(s, m)
            with run.stage("clean"):
                return _clean(s, lc, m)

    def estimate(self, run: Run) -> ObservedVerdicts:
        """The verdicts, each timed under its own name: ``period``, ``tumbling``, ``spin``;
        ``variation_over_noise`` first (what ``stages.tumbling: auto`` asks of the period stage)."""
        s: ObservedSettings = run.result("plan")
        d: ObservedMeasured = run.result("measure")
        m = dict(d.metrics)
        with _failure(m):
            m["variation_over_noise"] = variation_over_noise(d.t, d.y, d.sig, d.tracks)
            res = period_stage(run, s, d.t, d.y, d.sig, d.tracks, m, d.lc.channels)
            tumbling_stage(run, s, d.t, d.y, d.sig, res, m)
            spin_stage(run, s, d.lc, d.t, res, m)
        per_track = m.pop("_tracks", None)
        return ObservedVerdicts(period=res, per_track=per_track, metrics=m)

    def solve(self, run: Run) -> None:
        """Nothing to solve: the verdicts are the answer (and nothing is timed)."""

    def score(self, run: Run) -> dict[str, Any]:
        """The metrics (numpy scalars as JSON's booleans and numbers)."""
        v: ObservedVerdicts = run.result("estimate")
        return {k: _plain(x) for k, x in v.metrics.items()}

    def write(self, run: Run, metrics: dict[str, Any]) -> None:
        """``tracks.csv``, ``alternatives.csv``, ``arrays.npz`` and the ``characterise`` figure."""
        s: ObservedSettings = run.result("plan")
        d: ObservedMeasured = run.result("measure")
        v: ObservedVerdicts = run.result("estimate")
        t, y, res, lc = d.t, d.y, v.period, d.lc
        arrays: dict[str, Any] = {"times_s": t, "values": y}
        if v.per_track:
            write_csv(run.out_dir / "tracks.csv", v.per_track)
        if res is not None:
            detrend = s.period.detrend if s.period.detrend is not None else 2
            model, trend = fitted_model(t, y, res, int(detrend), lc.track_ids(), lc.channels)
            arrays.update(model=model, trend=trend, frequency_hz=res["periodogram"]["frequency_hz"],
                          power=res["periodogram"]["power"])
            write_csv(run.out_dir / "alternatives.csv", res["alternatives"] or [{"relation": "none"}])
        write_npz(run.out_dir / "arrays.npz", **arrays)
        if s.characterise.figures:
            from cssat.plots.characterise import characterise_figure, figure_labels  # heavy: matplotlib

            labels = figure_labels(lc.meta, metrics, lc.kind, metrics.get("band"))
            save_figure(characterise_figure(t, y, lc.magnitude_errors() if lc.kind == "magnitude" else lc.errors, res,
                                            arrays.get("model"), lc.kind, trend=arrays.get("trend"), labels=labels,
                                            verdict=metrics.get("verdict")), run.figure("characterise"))

    def headline(self, metrics: dict[str, Any], run: Run) -> str:
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


def _read(s: ObservedSettings, m: dict[str, Any]) -> Any:
    """The light curve of ``observations`` with the ``observed`` settings, its tracks selected,
    a given element set checked against it; the file's own description into ``m``:
    ``object_id`` (the NORAD id), ``object_name``, ``track`` (the file's track ids, ``;``-joined;
    null when it names none), ``band`` (the magnitudes' filter, e.g. MMT's ``Clear``)."""
    lc = read_observations({"observations": s.observations, "observed": _read_options(s)})
    tracks = s.characterise.track_list()
    if tracks is not None:
        try:
            lc = lc.select(tracks)
        except FieldError as err:
            raise FieldError("characterise.tracks", err.detail) from None
    meta = lc.meta
    band = s.observed.band or None
    if (band is None or band == "file") and lc.filters is not None:
        band = "/".join(dict.fromkeys(str(f) for f in lc.filters))
    m.update(object_id=meta.get("object_id"), object_name=meta.get("name"), file_format=meta.get("format"),
             track=";".join(dict.fromkeys(str(x) for x in lc.tracks)) if lc.tracks is not None else None,
             file_variability=meta.get("variability"), published_period_s=meta.get("published_period_s"),
             magnitude_system=lc.magnitude_system, band=None if band is None else str(band), n_rows=len(lc))
    if s.tle is not None:  # an element set given is the file's object's, near its dates
        check_elements(scenario_config(s), lc, s.characterise.max_epoch_days)
    return lc


def _clean(s: ObservedSettings, lc: Any, m: dict[str, Any]) -> ObservedMeasured:
    """Penumbra dropped, too few samples refused, apparent magnitudes reduced to 1000 km;
    ``stages.spin=on`` refused here, before any search, when the file holds fewer than
    ``characterise.min_nights`` nights. ``period_magnitudes`` into ``m``: what the period
    stage's values are (``apparent``, ``apparent, reduced to a range of 1000 km``, MMT StdMag's
    ``normalised: 1000 km, phase 90°``, or ``flux``)."""
    ch = s.characterise
    if ch.drop_penumbra and lc.penumbra is not None and lc.penumbra.any():
        m["n_penumbra_dropped"] = int(lc.penumbra.sum())
        lc = lc.rows(~lc.penumbra)
    if len(lc) < ch.min_samples:
        raise FieldError("observations", f"{len(lc)} usable samples; characterise needs at least {ch.min_samples} "
                                         "(characterise.min_samples)")
    t = lc.times_s()
    y = lc.magnitudes() if lc.kind == "magnitude" else lc.values
    sig = lc.magnitude_errors() if lc.kind == "magnitude" else lc.errors
    tracks = lc.track_ids()
    m["period_magnitudes"] = lc.magnitude_system if lc.kind == "magnitude" else "flux"
    if ch.normalise_range and lc.kind == "magnitude" and lc.ranges_km is not None and lc.magnitude_system == "apparent":
        y = y - 5.0 * np.log10(lc.ranges_km / 1000.0)  # the range's inverse square out, to 1000 km (MMT's StdMag's)
        m["period_magnitudes"] = "apparent, reduced to a range of 1000 km"
    nights = count_nights(t)
    m.update(n_samples=len(lc), n_tracks=len(set(tracks)), n_nights=nights, span_s=float(t[-1]),
             start_utc=str(lc.times_utc[0]))
    if s.stages.spin == "on" and nights < ch.min_nights:
        raise FieldError("stages.spin", f"the spin stage needs {ch.min_nights} nights (characterise.min_nights); "
                                        f"the file holds {nights}: one pass does not constrain a pole")
    return ObservedMeasured(lc=lc, t=t, y=y, sig=sig, tracks=tracks, metrics=m)
