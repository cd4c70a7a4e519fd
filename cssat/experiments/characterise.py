"""Characterise a measured light curve (``cssat experiment=characterise observations=<file>``,
issue 34, point 5): what a real track says, stage by stage, and why a stage was skipped.

Stages (each a key of ``stages``: ``auto`` runs it where the data allow and records why not
otherwise; ``on`` requires it — the run stops with exit 2 naming what is missing —; ``off``):

1. ``read``: :func:`cssat.data.read_light_curve` with the ``observed`` settings (format by
   content: MMT-9, SCORE, ALCDEF, ECSV/FITS, CSV); ``characterise.tracks`` keeps those tracks.
2. ``clean``: drops the samples flagged in penumbra (MMT's ``Penumbra``), refuses fewer than
   ``characterise.min_samples``; where the file gives each sample's range, apparent magnitudes
   are reduced to 1000 km (``characterise.normalise_range``: the pass's range trend is not
   the object's light curve).
3. ``period``: :func:`cssat.inversion.estimate_period` on the magnitudes (options under
   ``period``: its keyword arguments) — ``periodic``, ``period_s``, ``period_err_s``, ``fap``,
   ``alternatives``, ``chi2_per_sample``; compared with the file's published period if any.
4. ``tumbling``: :func:`cssat.inversion.estimate_tumbling_periods` when the curve holds enough
   samples for its 2-D series — the verdict ``tumbling`` and why.
5. ``spin``: the pole, sidereal period and convex shape (:func:`cssat.inversion.estimate_spin`,
   :func:`cssat.inversion.minkowski`): needs a periodic curve, the object's element set
   (``scenario.tle``, checked against the file's NORAD id and epoch) and at least
   ``characterise.min_nights`` nights; the scenario's range and phase angle are compared with
   the file's where both exist.

Outputs: ``metrics.json`` (every stage's verdict ``stage_<name>``: ``ok``, ``skipped: <why>``
or ``off``), ``arrays.npz`` (times, values, the fitted model and the periodogram),
``alternatives.csv``, ``tracks.csv`` (a file of several tracks: each one's own period and
verdict), ``shape.obj`` when the spin stage ran, and the figure
``characterise`` (the light curve with its gaps, the periodogram with the alternatives marked,
the phase-folded curve with the model, the residuals).
"""

from __future__ import annotations

import inspect
import logging
from typing import Any

import numpy as np

from cssat._checks import FieldError, bool_param, choice_param, int_param

log = logging.getLogger("cssat")

STAGES = ("period", "tumbling", "spin")
#: the spin stage's geometry must agree with the file's: median |Δrange| / range and |Δphase|
MAX_RANGE_MISMATCH = 0.05
MAX_PHASE_MISMATCH_DEG = 5.0
STAGE_MODES = ("auto", "on", "off")


def _opts(node: Any) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else dict(node or {})


def check(cfg: Any) -> dict[str, Any]:
    """Every setting of the experiment checked before any work (a FieldError with its full key)."""
    from cssat.inversion import estimate_period, estimate_tumbling_periods

    if not cfg.get("observations"):
        raise FieldError("observations", "characterise needs a light-curve file: observations=<path>")
    stages = _opts(cfg.get("stages"))
    for k in stages:
        if k not in STAGES:
            raise FieldError(f"stages.{k}", f"not a stage; the stages: {', '.join(STAGES)}")
    modes = {k: choice_param(stages.get(k, "auto"), f"stages.{k}", STAGE_MODES) for k in STAGES}
    for node, fn in (("period", estimate_period), ("tumbling", estimate_tumbling_periods)):
        allowed = [p for p in inspect.signature(fn).parameters if p not in ("times_s", "flux", "sigma", "segments")]
        for k in _opts(cfg.get(node)):
            if k not in allowed:
                raise FieldError(f"{node}.{k}", f"not an option of {fn.__name__}; its options: {', '.join(allowed)}")
    ch = _opts(cfg.get("characterise"))
    known = {"tracks", "min_samples", "drop_penumbra", "min_nights", "max_epoch_days", "figures", "normalise_range"}
    for k in ch:
        if k not in known:
            raise FieldError(f"characterise.{k}", f"not a setting; the settings: {', '.join(sorted(known))}")
    return {"modes": modes, "min_samples": int_param(ch.get("min_samples", 20), "characterise.min_samples", 12),
            "drop_penumbra": bool_param(ch.get("drop_penumbra", True), "characterise.drop_penumbra"),
            "min_nights": int_param(ch.get("min_nights", 2), "characterise.min_nights", 1),
            "max_epoch_days": float(ch.get("max_epoch_days", 14.0)), "tracks": ch.get("tracks"),
            "figures": bool_param(ch.get("figures", True), "characterise.figures"),
            "normalise_range": bool_param(ch.get("normalise_range", True), "characterise.normalise_range"),
            "period": {k: v for k, v in _opts(cfg.get("period")).items() if v is not None},
            "tumbling": {k: v for k, v in _opts(cfg.get("tumbling")).items() if v is not None}}


def run(cfg: Any, out_dir: Any) -> dict[str, Any]:
    """Run the characterisation ``cfg`` into ``out_dir`` and return its metrics."""
    from cssat.experiments.context import Run
    from cssat.experiments.scene import read_observations

    run_ = Run.from_config(cfg, out_dir)
    with run_.stage("check"):
        opt = check(cfg)
    m: dict[str, Any] = {"psnr": None}
    with run_.stage("read"):
        lc = read_observations(cfg)
        if opt["tracks"] is not None:
            try:
                lc = lc.select(list(opt["tracks"]) if not isinstance(opt["tracks"], (str, int)) else [opt["tracks"]])
            except FieldError as err:
                raise FieldError("characterise.tracks", err.detail) from None
        if cfg.scenario.get("tle") is not None:  # an element set given is the file's object's, near its dates
            from cssat.experiments.scene import check_elements

            check_elements(cfg, lc, opt["max_epoch_days"])
        meta = lc.meta
        m.update(object_id=meta.get("object_id"), object_name=meta.get("name"), file_format=meta.get("format"),
                 file_variability=meta.get("variability"), published_period_s=meta.get("published_period_s"),
                 magnitude_system=lc.magnitude_system, n_rows=len(lc))
    with run_.stage("clean"):
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
        if opt["normalise_range"] and lc.kind == "magnitude" and lc.ranges_km is not None and lc.magnitude_system == "apparent":
            y = y - 5.0 * np.log10(lc.ranges_km / 1000.0)  # the range's inverse square out, to 1000 km (MMT's StdMag's)
            m["period_magnitudes"] = "apparent, reduced to a range of 1000 km"
        m.update(n_samples=len(lc), n_tracks=len(set(tracks)), span_s=float(t[-1]), start_utc=str(lc.times_utc[0]))
    res = _period(run_, opt, t, y, sig, tracks, m)
    _tumbling(run_, opt, t, y, sig, res, m)
    _spin(run_, cfg, opt, lc, t, res, m)
    with run_.stage("files"):
        _write(run_, opt, lc, t, y, res, m)
    m.pop("_tracks", None)
    m.update(run_.timings())
    log.info("characterise: %s", _headline(m))
    return m


def _headline(m: dict[str, Any]) -> str:
    """One line: the verdict and the period, or why there is none, and the skipped stages."""
    name = " ".join(str(x) for x in (m.get("object_id"), m.get("object_name")) if x) or "the light curve"
    if m.get("periodic"):
        head = (f"{name}: periodic, P = {m['period_s']:.6g} ± {m['period_err_s']:.2g} s (FAP {m['fap']:.2g}, "
                f"χ²/N {m['chi2_per_sample']:.3g})")
    elif m.get("stage_period") == "ok":
        head = f"{name}: not periodic (FAP {m['fap']:.2g}, repeat {m['repeat']:.2g})"
    else:
        head = f"{name}: {m.get('stage_period')}"
    if m.get("n_tracks_periodic") is not None:
        head += f"; {m['n_tracks_periodic']} of {m['n_tracks']} tracks periodic on their own (tracks.csv)"
    skipped = [k for k in STAGES if str(m.get(f"stage_{k}", "")).startswith("skipped")]
    return head + (f"; skipped: {', '.join(skipped)} (why: metrics.json)" if skipped else "")


def _period(run_, opt, t, y, sig, tracks, m) -> dict[str, Any] | None:
    """The period stage: the whole selection (its tracks' offsets and slopes fitted), and, when
    it holds several tracks, each track apart (``tracks.csv``); the whole may be out of reach
    (tracks days apart: too many trial frequencies), the tracks then answer alone."""
    from cssat.inversion import estimate_period

    if opt["modes"]["period"] == "off":
        m["stage_period"] = "off"
        return None
    kw = dict(opt["period"])
    res, why_not = None, None
    with run_.stage("period"):
        try:
            res = estimate_period(t, y, sigma=sig, segments=tracks, **kw)
        except FieldError as err:
            if "trial frequencies" not in err.detail or len(set(tracks)) < 2:
                raise
            why_not = err.detail
        per_track = _per_track(t, y, sig, tracks, kw, opt["min_samples"]) if len(set(tracks)) > 1 else []
    if per_track:
        m["n_tracks_periodic"] = sum(bool(r["periodic"]) for r in per_track)
        m["track_periods_s"] = [r["period_s"] for r in per_track if r["periodic"]]
        m["_tracks"] = per_track  # tracks.csv, written with the other files
    found = [r["period_s"] for r in per_track if r["periodic"]]
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
        m.update(periodic=False, period_s=None, stage_period=f"skipped (whole curve): {why_not} (set period.min_period_s "
                                                             "and period.max_period_s); see tracks.csv")
        return None
    keys = ("periodic", "period_s", "period_err_s", "fap", "repeat", "best_period_s", "best_period_err_s", "chi2_per_sample",
            "model_fits", "n_harmonics", "n_cycles", "min_period_s", "max_period_s", "why")
    m.update({k: res[k] for k in keys})
    m["alternatives"] = res["alternatives"]
    m["warnings"] = list(res["warnings"])
    pub = m.get("published_period_s")
    if pub and res["periodic"]:
        m["period_vs_published"] = float(res["period_s"] / pub - 1.0)
    m["stage_period"] = "ok"
    if opt["modes"]["period"] == "on" and not res["periodic"]:
        raise FieldError("stages.period", f"no significant period (fap {res['fap']:.3g}, repeat {res['repeat']:.3g}); "
                                          "stages.period=auto records that as the answer")
    return res


def _per_track(t, y, sig, tracks, kw, min_samples) -> list[dict[str, Any]]:
    """One row per track: its own period analysis (or why none: too few samples)."""
    from cssat.inversion import estimate_period

    rows = []
    for k in dict.fromkeys(tracks):
        on = tracks == k
        row: dict[str, Any] = {"track": k, "n_samples": int(on.sum()), "span_s": float(np.ptp(t[on]))}
        if on.sum() < min_samples:
            row.update(status="skipped: too few samples", periodic=False, period_s=None)
        else:
            try:
                r = estimate_period(t[on], y[on], sigma=None if sig is None else sig[on], **kw)
            except FieldError as err:
                row.update(status=f"failed: {err}", periodic=False, period_s=None)
            else:
                row.update(status="ok", periodic=r["periodic"], period_s=r["period_s"], period_err_s=r["period_err_s"],
                           best_period_s=r["best_period_s"], fap=r["fap"], repeat=r["repeat"],
                           chi2_per_sample=r["chi2_per_sample"])
        rows.append(row)
    return rows


def _tumbling(run_, opt, t, y, sig, res, m) -> None:
    from cssat.inversion import estimate_tumbling_periods

    mode = opt["modes"]["tumbling"]
    if mode == "off":
        m["stage_tumbling"] = "off"
        return
    order = int(opt["tumbling"].get("order", 3))
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
    with run_.stage("tumbling"):
        try:
            tp = estimate_tumbling_periods(t, y, sigma=sig, **opt["tumbling"])
        except FieldError as err:
            if "trial frequencies" not in err.detail or mode == "on":
                raise err.within("tumbling") from None
            m["stage_tumbling"] = f"skipped: {err.detail}"
            return
    m.update(tumbling=bool(tp["tumbling"]), tumbling_delta_bic=tp["delta_bic"], tumbling_why=tp.get("why"))
    if tp["tumbling"]:
        m["tumbling_periods_s"] = [float(p) for p in tp["periods_s"]]
    m["stage_tumbling"] = "ok"


def _spin(run_, cfg, opt, lc, t, res, m) -> None:
    mode = opt["modes"]["spin"]
    if mode == "off":
        m["stage_spin"] = "off"
        return
    from cssat.inversion.fourier import stretches

    nights = len(np.unique(stretches(t, min_gap_s=6 * 3600.0)))
    missing = []
    if res is None or not res["periodic"]:
        missing.append("a periodic light curve")
    if cfg.scenario.get("tle") is None:
        missing.append("the object's element set (scenario.tle)")
    if nights < opt["min_nights"]:
        missing.append(f"{opt['min_nights']} nights (the file holds {nights}: one pass does not constrain a pole)")
    if missing:
        why = "needs " + ", ".join(missing)
        if mode == "on":
            raise FieldError("stages.spin", why)
        m["stage_spin"] = f"skipped: {why}"
        return
    from cssat.experiments.scene import build_scenario, check_elements
    from cssat.inversion import estimate_spin, minkowski
    from cssat.optics.photometry import SOLAR_IRRADIANCE_W_M2

    with run_.stage("spin"):
        check_elements(cfg, lc, opt["max_epoch_days"])
        sc = build_scenario(cfg, lc.times_utc, lc.sites)  # the file's observer of each sample, where it gives them
        _compare_geometry(sc, lc, m)
        rel = m.get("range_diff_km_median", 0.0) / float(np.median(lc.ranges_km)) if lc.ranges_km is not None else 0.0
        if rel > MAX_RANGE_MISMATCH or m.get("phase_diff_deg_median", 0.0) > MAX_PHASE_MISMATCH_DEG:
            raise FieldError("scenario.tle", f"the element set and observer put the object {m.get('range_diff_km_median', 0):.0f} "
                                             f"km and {m.get('phase_diff_deg_median', 0):.1f}° of phase from the file's own "
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


def _compare_geometry(sc, lc, m) -> None:
    """The scenario's range and phase angle less the file's (median |difference|)."""
    if lc.ranges_km is not None:
        m["range_diff_km_median"] = float(np.median(np.abs(sc.range_km - lc.ranges_km)))
    if lc.phase_deg is not None:
        ph = np.degrees(np.arccos(np.clip((sc.sun_dir * sc.obs_dir).sum(1), -1, 1)))
        m["phase_diff_deg_median"] = float(np.median(np.abs(ph - lc.phase_deg)))


def _write(run_, opt, lc, t, y, res, m) -> None:
    from cssat.experiments.files import write_csv, write_npz

    arrays: dict[str, Any] = {"times_s": t, "values": y}
    per_track = m.pop("_tracks", None)
    if per_track:
        write_csv(run_.out_dir / "tracks.csv", per_track)
    if res is not None:
        model, trend = _model(t, y, res, int(opt["period"].get("detrend", 1)), lc.track_ids())
        arrays.update(model=model, trend=trend, frequency_hz=res["periodogram"]["frequency_hz"], power=res["periodogram"]["power"])
        write_csv(run_.out_dir / "alternatives.csv", res["alternatives"] or [{"relation": "none"}])
    write_npz(run_.out_dir / "arrays.npz", **arrays)
    if opt["figures"]:
        from cssat.plots import save_figure
        from cssat.plots.characterise import characterise_figure

        save_figure(characterise_figure(t, y, lc.magnitude_errors() if lc.kind == "magnitude" else lc.errors, res,
                                        arrays.get("model"), lc.kind, trend=arrays.get("trend")), run_.figure("characterise"))


def _model(t: np.ndarray, y: np.ndarray, res: dict[str, Any], detrend: int,
           tracks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The chosen Fourier series with each track's offset and trend at ``t``, and that offset
    and trend alone (the fold shows the curve less it)."""
    from cssat.inversion.fourier import _Curve, _design

    if not np.isfinite(res["best_period_s"]):
        flat = np.full_like(y, np.mean(y))
        return flat, flat
    cv = _Curve(t, y, np.ones_like(y), np.unique(tracks, return_inverse=True)[1].reshape(-1), detrend, False)
    X = np.concatenate([cv.Q, _design(t, 1.0 / res["best_period_s"], res["n_harmonics"])], 1)
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return X @ coef, cv.Q @ coef[:cv.q]
