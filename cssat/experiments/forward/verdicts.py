"""The verdicts of a measured light curve (:class:`~cssat.experiments.forward.observed.Observed`'s
``estimate`` stage): the period (the whole selection and each track apart), one period or two
(tumbling), and — where the data allow — the spin: pole, sidereal period and convex shape.

Each stage records its verdict ``stage_<name>`` in the metrics: ``ok``, ``skipped: <why>`` or
``off``; a stage set ``on`` that the data cannot serve is a :class:`~cssat._checks.FieldError`
naming ``stages.<name>``. Times are seconds from the first sample; periods in seconds.

The period's verdict is one word, ``verdict`` (:data:`VERDICTS`: ``periodic``, ``not periodic``,
``undetermined`` — the data cannot tell, e.g. too few cycles or the whole curve out of the
search's reach —, and ``failed`` for a run that stopped), with ``why`` (one sentence) beside it:
:func:`~cssat.inversion.estimate_period`'s own ``verdict``/``verdict_why`` where it gives them,
else its ``periodic`` and the FAP and repeat tests that made it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError
from cssat.experiments.context import Run
from cssat.experiments.scene import build_scenario, check_elements
from cssat.models.observed.config import VERDICT_STAGES, ObservedSettings

__all__ = ["VERDICT_STAGES", "VERDICTS", "MAX_RANGE_MISMATCH", "MAX_PHASE_MISMATCH_DEG", "TUMBLING_MIN_VARIATION",
           "period_verdict", "period_why", "variation_over_noise", "count_nights", "period_stage", "per_track",
           "tumbling_stage", "spin_stage", "compare_geometry", "fitted_model", "scenario_config"]

#: the words of the ``verdict`` metric (``failed``: the run stopped; its ``error`` says why)
VERDICTS = ("periodic", "not periodic", "undetermined", "failed")
#: ``stages.tumbling: auto`` runs the tumbling search on a curve the period stage did not call
#: periodic only when it varies: the rms of the curve less each track's offset and slope at
#: least this many times the noise's 1σ (``variation_over_noise``)
TUMBLING_MIN_VARIATION = 2.0
#: a new night after a gap longer than this, s (the spin stage's ``characterise.min_nights``)
NIGHT_GAP_S = 6 * 3600.0
#: estimate_period's arguments that are the data (its FieldErrors on them name ``observations``)
_DATA_ARGS = ("times_s", "flux", "sigma", "segments")
#: the spin stage's geometry must agree with the file's: median |Δrange| / range and |Δphase|
MAX_RANGE_MISMATCH = 0.05
MAX_PHASE_MISMATCH_DEG = 5.0


def period_verdict(res: dict[str, Any] | None) -> str:
    """The period result's verdict word: its own ``verdict`` where it gives one, else from
    ``periodic`` (``None``: undetermined); ``undetermined`` when there is no result."""
    if res is None:
        return "undetermined"
    v = res.get("verdict")
    if v is None:
        p = res.get("periodic")
        v = "undetermined" if p is None else "periodic" if p else "not periodic"
    return str(v)


def period_why(res: dict[str, Any], kw: dict[str, Any] | None = None) -> str:
    """One sentence: why the period result is periodic, not periodic or undetermined — its own
    ``verdict_why`` where it gives one, else the FAP and repeat tests against their thresholds
    (``kw``: the ``period`` options, ``fap_max`` 1e-3 and ``min_repeat`` 0.7 by default), else
    its ``why``."""
    if res.get("verdict_why"):
        return str(res["verdict_why"])
    kw = kw or {}
    fap, rep = res.get("fap"), res.get("repeat")
    fap_max, min_rep = float(kw.get("fap_max", 1e-3)), float(kw.get("min_repeat", 0.7))
    if fap is None or rep is None or not (np.isfinite(fap) and np.isfinite(rep)):
        return str(res.get("why") or "")
    v = period_verdict(res)
    if v == "periodic":
        return (f"the best period's false-alarm probability {fap:.2g} is under {fap_max:g} and its cycles repeat "
                f"(repeat {rep:.2f} ≥ {min_rep:g})")
    fails = ([f"the best period's false-alarm probability {fap:.2g} is over {fap_max:g}"] if fap > fap_max else []) + (
        [f"its cycles do not repeat (repeat {rep:.2f} < {min_rep:g})"] if rep < min_rep else [])
    return "; ".join(fails) if v == "not periodic" and fails else str(res.get("why") or v)


def variation_over_noise(t: np.ndarray, y: np.ndarray, sig: np.ndarray | None, tracks: np.ndarray) -> float:
    """How much the curve varies, in units of its noise: the rms of ``y`` less each track's
    offset and slope, over the noise's 1σ — the median of ``sig`` where given, else the
    point-to-point scatter within the tracks (1.4826 MAD(Δy)/√2). About 1 for noise alone; a
    signal faster than the cadence also scatters point to point and reads as noise. NaN when
    the noise is 0 or unknown."""
    resid, steps = np.empty_like(y, dtype=float), []
    for k in dict.fromkeys(tracks):
        on = tracks == k
        tk = t[on] - t[on].mean()
        X = np.stack([np.ones_like(tk), tk], 1) if on.sum() > 2 else np.ones((on.sum(), 1))
        coef, *_ = np.linalg.lstsq(X, y[on], rcond=None)
        resid[on] = y[on] - X @ coef
        steps.append(np.diff(y[on]))
    if sig is not None:
        noise = float(np.median(sig))
    else:
        d = np.concatenate(steps) if steps else np.empty(0)
        noise = float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2)) if d.size else float("nan")
    rms = float(np.sqrt(np.mean(resid ** 2)))
    return rms / noise if noise > 0 else float("nan")


def count_nights(t: np.ndarray) -> int:
    """The nights of ``t`` (s, sorted): :func:`cssat.data.observations.stretches` at least
    :data:`NIGHT_GAP_S` apart."""
    from cssat.data.observations import stretches  # heavy: cssat.data imports torch

    return int(len(np.unique(stretches(t, min_gap_s=NIGHT_GAP_S)))) if len(t) else 0


def _period_error(err: FieldError) -> FieldError:
    """An estimate_period FieldError with its config key: an option's ``period.<option>``, the
    data's ``observations``."""
    return FieldError("observations", err.detail) if err.field in _DATA_ARGS else err.within("period")


def period_stage(run_: Run, s: ObservedSettings, t: np.ndarray, y: np.ndarray, sig: np.ndarray | None,
                 tracks: np.ndarray, m: dict[str, Any], channels: np.ndarray | None = None) -> dict[str, Any] | None:
    """The period stage: the whole selection (its tracks' offsets and slopes fitted), and, when
    it holds several tracks, each track apart (``tracks.csv``); the whole may be out of reach
    (tracks days apart: too many trial frequencies), the tracks then answer alone. Records
    ``verdict`` (:data:`VERDICTS`), ``why``, ``periodic`` (true, false or null: undetermined),
    the period and its 1σ (s), ``fap``, ``repeat``, ``warnings`` (one string, ``; ``-joined) and
    ``period_choice`` (why this period and not its multiples). estimate_period's FieldErrors
    name their key: ``period.<option>`` or ``observations``. ``channels (T,)``: each sample's
    camera channel (its own zero point); ``period.convention`` null: by the object's name
    (:func:`~cssat.inversion.period.convention_for`: the full turn of a rocket body). Returns
    :func:`~cssat.inversion.estimate_period`'s result (``None``: off or out of reach); ``period.method``
    another registered period method (:func:`~cssat.inversion.period_method`)."""
    from cssat.inversion import period_method  # heavy: cssat.inversion imports torch

    if s.stages.period == "off":
        m.update(stage_period="off", verdict="undetermined", why="the period stage is off (stages.period=off)")
        return None
    from cssat.inversion.period import convention_for  # heavy: cssat.inversion imports torch

    kw = s.period.options()
    method = s.period.method
    estimate_period = period_method(method, field="period.method")
    kw.setdefault("convention", convention_for(m.get("object_name")))
    m["period_convention"] = kw["convention"]
    if channels is not None and len(set(np.asarray(channels).tolist())) > 1:
        kw["zero_points"] = np.asarray(channels)
    res, why_not = None, None
    with run_.stage("period"):
        try:
            res = estimate_period(t, y, sigma=sig, segments=tracks, **kw)
        except FieldError as err:
            if "trial frequencies" not in err.detail or len(set(tracks)) < 2:
                raise _period_error(err) from None
            why_not = err.detail
        rows = per_track(t, y, sig, tracks, kw, s.characterise.min_samples, method) if len(set(tracks)) > 1 else []
    if rows:
        m["n_tracks_periodic"] = sum(r["verdict"] == "periodic" for r in rows)
        m["track_periods_s"] = [r["period_s"] for r in rows if r["verdict"] == "periodic"]
        m["_tracks"] = rows  # tracks.csv, written with the other files
    found = [r["period_s"] for r in rows if r["verdict"] == "periodic"]
    p0 = float(np.median(found)) if found else None
    if p0 is not None and not {"min_period_s", "max_period_s"} & set(kw) and (
            res is None or not res["model_fits"] or abs(res["best_period_s"] / p0 - 1) > 0.02):
        # the tracks have a period the whole curve missed (tracks hours or days apart: the cycle count
        # between them is ambiguous on a full grid): the whole curve searched about it, kept if it fits better
        with run_.stage("period"):
            try:
                near = estimate_period(t, y, sigma=sig, segments=tracks, min_period_s=0.7 * p0, max_period_s=1.45 * p0, **kw)
            except FieldError as err:
                near, why_not = None, err.detail
        if near is not None and (res is None or near["chi2_per_sample"] < res["chi2_per_sample"]):
            res = near
            m["period_search"] = f"about the tracks' median period {p0:.6g} s (0.7x to 1.45x)"
    if res is None:
        m.update(periodic=None, period_s=None, verdict="undetermined",
                 why=f"the whole curve is out of the period search's reach ({why_not}); its tracks are analysed apart "
                     "(tracks.csv)",
                 stage_period=f"skipped (whole curve): {why_not} (set period.min_period_s and period.max_period_s); "
                              "see tracks.csv")
        return None
    keys = ("periodic", "period_s", "period_err_s", "fap", "fap_all", "fap_white", "repeat", "best_period_s",
            "best_period_err_s", "photometric_period_s", "n_maxima", "chi2_per_sample", "model_fits", "n_harmonics",
            "n_cycles", "min_period_s", "max_period_s", "cadence_s", "variation_snr")
    m.update({k: res.get(k) for k in keys})
    verdict = period_verdict(res)
    m.update(verdict=verdict, why=period_why(res, kw), period_choice=res.get("why"))
    m["alternatives"] = res["alternatives"]
    m["warnings"] = "; ".join(str(w) for w in res["warnings"])
    pub = m.get("published_period_s")
    if pub and verdict == "periodic":
        m["period_vs_published"] = float(res["period_s"] / pub - 1.0)
    m["stage_period"] = "ok"
    if s.stages.period == "on" and verdict != "periodic":
        if verdict == "undetermined":
            raise FieldError("stages.period", f"the period is undetermined: {m['why']}; stages.period=auto records that "
                                              "as the answer")
        raise FieldError("stages.period", f"no significant period (fap {res['fap']:.3g}, repeat {res['repeat']:.3g}); "
                                          "stages.period=auto records that as the answer")
    return res


def per_track(t: np.ndarray, y: np.ndarray, sig: np.ndarray | None, tracks: np.ndarray, kw: dict[str, Any],
              min_samples: int, method: str | None = None) -> list[dict[str, Any]]:
    """One row per track: its own period analysis — ``verdict`` (:data:`VERDICTS`), ``why``,
    ``periodic``, the period and its 1σ (s), FAP, repeat — or why none (too few samples)."""
    from cssat.inversion import period_method  # heavy: cssat.inversion imports torch

    estimate_period = period_method(method, field="period.method")

    rows = []
    for k in dict.fromkeys(tracks):
        on = tracks == k
        row: dict[str, Any] = {"track": k, "n_samples": int(on.sum()), "span_s": float(np.ptp(t[on]))}
        if on.sum() < min_samples:
            row.update(status="skipped: too few samples", verdict="undetermined", periodic=None, period_s=None,
                       why=f"{int(on.sum())} samples, under characterise.min_samples ({min_samples})")
        else:
            try:
                kw_on = {**kw, "zero_points": kw["zero_points"][on]} if "zero_points" in kw else kw
                r = estimate_period(t[on], y[on], sigma=None if sig is None else sig[on], **kw_on)
            except FieldError as err:
                row.update(status=f"failed: {_period_error(err)}", verdict="undetermined", periodic=None, period_s=None,
                           why=str(_period_error(err)))
            else:
                row.update(status="ok", verdict=period_verdict(r), why=period_why(r, kw), periodic=r["periodic"],
                           period_s=r["period_s"], period_err_s=r["period_err_s"], best_period_s=r["best_period_s"],
                           fap=r["fap"], repeat=r["repeat"], chi2_per_sample=r["chi2_per_sample"])
        rows.append(row)
    return rows


def _tumbling_not_asked(m: dict[str, Any], res: dict[str, Any] | None) -> str | None:
    """Why ``stages.tumbling: auto`` does not run the tumbling search (``None``: the period
    stage asks for it — a curve not called periodic that varies over
    :data:`TUMBLING_MIN_VARIATION` times its noise, or a period whose model does not fit; or
    there is no period result to ask: the stage off)."""
    if res is None:
        return None
    v, var = m.get("verdict"), m.get("variation_over_noise")
    if v == "periodic":
        if res.get("model_fits"):
            return (f"one period fits (periodic, χ²/N {res['chi2_per_sample']:.3g}): the period stage asks for no "
                    "second period (stages.tumbling=on runs it)")
        return None
    if not res.get("model_fits", True):
        return None
    if var is not None and np.isfinite(var) and var >= TUMBLING_MIN_VARIATION:
        return None
    return (f"{v} and the curve varies no more than its noise (rms {var:.2g}× the noise's 1σ, under "
            f"{TUMBLING_MIN_VARIATION:g}×): nothing for two periods to explain (stages.tumbling=on runs it)")


def tumbling_stage(run_: Run, s: ObservedSettings, t: np.ndarray, y: np.ndarray, sig: np.ndarray | None,
                   res: dict[str, Any] | None, m: dict[str, Any]) -> None:
    """The tumbling stage: :func:`~cssat.inversion.estimate_tumbling_periods`'s verdict when the
    curve holds enough samples (and cycles) for its 2-D series of order ``tumbling.order`` and —
    ``stages.tumbling: auto`` — when the period stage asks for it (:func:`_tumbling_not_asked`;
    the search costs several times the period's). ``tumbling`` (bool), ``tumbling_periods_s``."""
    from cssat.inversion import estimate_tumbling_periods  # heavy: cssat.inversion imports torch

    mode = s.stages.tumbling
    if mode == "off":
        m["stage_tumbling"] = "off"
        return
    order = int(s.tumbling.order if s.tumbling.order is not None else 3)
    need = 2 * (2 * len([1 for j in range(order + 1) for k in range(-order, order + 1) if 0 < j + abs(k) <= order]) + 1)
    why = None
    if str(m.get("stage_period", "")).startswith("skipped (whole curve)"):
        why = "the whole curve is out of the period search's reach (its tracks are analysed apart: tracks.csv)"
    elif len(t) < need:
        why = f"{len(t)} samples, the 2-D series of order {order} needs {need}"
    elif res is not None and res["n_cycles"] < 4:
        why = f"the track holds {res['n_cycles']:.2g} cycles; two periods need several of each"
    if why is not None:
        if mode == "on":
            raise FieldError("stages.tumbling", why)
        m["stage_tumbling"] = f"skipped: {why}"
        return
    if mode == "auto":
        why = _tumbling_not_asked(m, res)
        if why is not None:
            m["stage_tumbling"] = f"skipped: {why}"
            return
    with run_.stage("tumbling"):
        try:
            tp = estimate_tumbling_periods(t, y, sigma=sig, **s.tumbling.options())
        except FieldError as err:
            if "trial frequencies" not in err.detail or mode == "on":
                raise err.within("tumbling") from None
            m["stage_tumbling"] = f"skipped: {err.detail}"
            return
    m.update(tumbling=bool(tp["tumbling"]), tumbling_delta_bic=tp["delta_bic"], tumbling_aperiodic=tp["aperiodic"],
             tumbling_why=tp.get("why"))
    if tp["tumbling"]:
        m["tumbling_periods_s"] = [float(p) for p in tp["periods_s"]]
    m["stage_tumbling"] = "ok"


def spin_stage(run_: Run, s: ObservedSettings, lc: Any, t: np.ndarray, res: dict[str, Any] | None,
               m: dict[str, Any]) -> None:
    """The spin stage: the pole, sidereal period and convex shape (``shape.obj``, written here)
    from a periodic curve over ``characterise.min_nights`` nights and the object's element set,
    whose range and phase angle must agree with the file's (``MAX_RANGE_MISMATCH``,
    ``MAX_PHASE_MISMATCH_DEG``)."""
    mode = s.stages.spin
    if mode == "off":
        m["stage_spin"] = "off"
        return
    nights = count_nights(t)
    missing = []
    verdict = period_verdict(res)
    if verdict != "periodic":
        missing.append(f"a periodic light curve (the period is {verdict})")
    if s.tle is None:
        missing.append("the object's element set (scenario.tle)")
    min_nights = s.characterise.min_nights
    if nights < min_nights:
        missing.append(f"{min_nights} nights (the file holds {nights}: one pass does not constrain a pole)")
    if missing:
        why = "needs " + ", ".join(missing)
        if mode == "on":
            raise FieldError("stages.spin", why)
        m["stage_spin"] = f"skipped: {why}"
        return
    from cssat.inversion import estimate_spin, minkowski  # heavy: cssat.inversion imports torch
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2  # heavy: cssat.optics.photometry imports torch

    cfg = scenario_config(s)
    with run_.stage("spin"):
        check_elements(cfg, lc, s.characterise.max_epoch_days)
        sc = build_scenario(cfg, lc.times_utc, lc.sites)  # the file's observer of each sample, where it gives them
        compare_geometry(sc, lc, m)
        rel = m.get("range_diff_km_median", 0.0) / float(np.median(lc.ranges_km)) if lc.ranges_km is not None else 0.0
        if rel > MAX_RANGE_MISMATCH or m.get("phase_diff_deg_median", 0.0) > MAX_PHASE_MISMATCH_DEG:
            raise FieldError("scenario.tle", "the element set and observer put the object "
                                             f"{m.get('range_diff_km_median', 0):.0f} km and "
                                             f"{m.get('phase_diff_deg_median', 0):.1f}° of phase from the file's own "
                                             "range and phase angle (median): check scenario.tle and scenario.observer")
        unit = (sc.range_km * 1e3) ** 2 / SOLAR_IRRADIANCE_W_M2
        flux = lc.fluxes() * unit
        err = lc.flux_errors()
        sol = estimate_spin(t, flux, sc.sun_dir, sc.obs_dir, sigma=None if err is None else err * unit,
                            period_s=res["period_s"], frame="equatorial")
        m.update(sol.describe())
        mesh, info = minkowski(sol.normals, sol.areas)
        mesh.export(run_.out_dir / "shape.obj")
        m["shape_converged"] = bool(info.get("converged"))
    m["stage_spin"] = "ok"


def scenario_config(s: ObservedSettings) -> Any:
    """The ``scenario`` node of ``s`` as a config of its own (``cfg.scenario``: what
    :func:`~cssat.experiments.scene.build_scenario` and :func:`~cssat.experiments.scene.check_elements`
    read)."""
    from omegaconf import OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    node = s.scenario
    node = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else dict(node or {})
    return OmegaConf.create({"scenario": node})


def compare_geometry(sc: Any, lc: Any, m: dict[str, Any]) -> None:
    """The scenario's range (km) and phase angle (°) less the file's (median |difference|)."""
    if lc.ranges_km is not None:
        m["range_diff_km_median"] = float(np.median(np.abs(sc.range_km - lc.ranges_km)))
    if lc.phase_deg is not None:
        ph = np.degrees(np.arccos(np.clip((sc.sun_dir * sc.obs_dir).sum(1), -1, 1)))
        m["phase_diff_deg_median"] = float(np.median(np.abs(ph - lc.phase_deg)))


def fitted_model(t: np.ndarray, y: np.ndarray, res: dict[str, Any], detrend: int,
                 tracks: np.ndarray, channels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The chosen Fourier series (at its photometric period, the one its harmonics count) with
    each track's trend and each channel's zero point at ``t``, and that trend and offset alone
    (the fold shows the curve less it)."""
    from cssat.inversion.fourier import Curve, design  # heavy: cssat.inversion.fourier imports torch

    P = res.get("photometric_period_s", res["best_period_s"])
    if not np.isfinite(P):
        flat = np.full_like(y, np.mean(y))
        return flat, flat
    zp = None if channels is None or len(set(np.asarray(channels).tolist())) < 2 else np.asarray(channels)
    cv = Curve(t, y, np.ones_like(y), np.unique(tracks, return_inverse=True)[1].reshape(-1), detrend, False, zp)
    X = np.concatenate([cv.Q, design(t, 1.0 / P, res["n_harmonics"])], 1)
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return X @ coef, cv.Q @ coef[:cv.q]
