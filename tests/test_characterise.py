"""Issue 46, point 5: ``characterise`` and its outputs for a reader — the figure's title and axes,
the metrics of a catalogue row (``verdict``, ``track``, ``why``, ``warnings`` as one string), the
tumbling stage only where the period stage asks for it, and refusals that come early and name
their key. The model's stages are called directly (no Hydra run) to keep these fast."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cssat._checks import FieldError
from cssat.smoke import EXAMPLE_TRACK

REAL = Path(__file__).parent / "data" / "real"
STARLINK = REAL / "mmt_sat10288_starlink3535_track20416355.txt"  # header: "# satellite: 51722 STARLINK-3535"; Track 20416355
VERDICT_WORDS = ("periodic", "not periodic", "undetermined", "failed")
#: an element set (cssat's synthetic Astra 1KR, epoch 2020-04-01) as a command-line override
TLE = ("scenario.tle=['1 29055U 06012A   20092.00000000  .00000104  00000-0  00000-0 0  9998',"
       "'2 29055   0.0291 247.7716 0004915 319.3582   1.8831  1.00273365 24812']")


def _cfg(*overrides):
    from conftest import cfg_of

    return cfg_of("experiment=characterise", *overrides)


def _model(tmp_path, *overrides, stop="estimate"):
    """The characterise model planned and run up to ``stop`` (``measure``, ``estimate`` or
    ``write``) on the config of ``overrides``; returns ``(model, run)``: each stage's typed
    result in ``run.results``."""
    from cssat.experiments.context import Run
    from cssat.experiments.forward.base import STAGES, run_stages
    from cssat.experiments.forward.observed import Observed

    cfg = _cfg(*overrides)
    run = Run.from_config(cfg, tmp_path)
    model = Observed()
    run_stages(model, cfg, run, STAGES[:STAGES.index(stop) + 1])
    return model, run


def test_the_figure_names_the_object_track_epoch_and_magnitude(tmp_path):
    """The title holds the NORAD id and the track read by hand from the file's header, the time
    axes the UTC start, the magnitude axes the band and that the magnitudes are reduced to
    1000 km; the published period (MMT's 18.888 s) is a line of the periodogram and in the fold's
    legend."""
    from cssat.data import read_light_curve
    from cssat.experiments.forward.verdicts import fitted_model
    from cssat.plots.characterise import characterise_figure, figure_labels

    model, run = _model(tmp_path, f"observations={STARLINK}", "characterise.figures=false")
    m, d = model.score(run), run.results["measure"]
    labels = figure_labels(d.lc.meta, m, d.lc.kind, m["band"])
    fig = characterise_figure(d.t, d.y, None, run.results["estimate"].period, None, labels=labels, verdict=m["verdict"])
    title = fig._suptitle.get_text()
    assert "51722" in title and "STARLINK-3535" in title and "20416355" in title and "2022-05-21 19:22:07.790" in title
    light, periodogram, fold, resid = fig.axes
    assert light.get_xlabel() == resid.get_xlabel() == "s since 2022-05-21 19:22:07.790 UTC"
    assert "Clear magnitude" in light.get_ylabel() and "1000 km" in light.get_ylabel()

    rb = read_light_curve(EXAMPLE_TRACK)  # MMT's label: 2 Periodic, 18.888 s
    mb, rb_run = _model(tmp_path / "rb", f"observations={EXAMPLE_TRACK}", "characterise.tracks=[101]",
                        "characterise.figures=false", "stages.tumbling=off", "stages.spin=off")
    mm, db, res = mb.score(rb_run), rb_run.results["measure"], rb_run.results["estimate"].period
    model_y, trend = fitted_model(db.t, db.y, res, 1, db.tracks)
    fig = characterise_figure(db.t, db.y, None, res, model_y, trend=trend, verdict=mm["verdict"],
                              labels=figure_labels(rb.meta, mm, rb.kind, mm["band"]))
    _, periodogram, fold, _ = fig.axes
    assert "track 101" in fig._suptitle.get_text() and "99001" in fig._suptitle.get_text()
    published = [ln for ln in periodogram.get_lines() if ln.get_linestyle() == "--"]
    assert len(published) == 1 and np.allclose(published[0].get_xdata(), 18.888)
    assert any(t.get_text().startswith("MMT 18.89 s") for t in periodogram.get_legend().get_texts())
    assert any(t.get_text().startswith("MMT 18.89 s") for t in fold.get_legend().get_texts())


def test_the_metrics_are_a_catalogue_row(tmp_path):
    """One verdict word, the file's track, one sentence why, the warnings as one string and real
    booleans; every value JSON's own type (summary.csv keeps the scalars)."""
    model, run = _model(tmp_path, f"observations={STARLINK}", "characterise.figures=false", "stages.spin=off")
    m = model.score(run)
    assert m["verdict"] == "not periodic" and m["periodic"] is False  # MMT: 0 Not variable
    assert m["track"] == "20416355" and m["object_id"] == "51722"
    assert isinstance(m["why"], str) and m["why"] and "\n" not in m["why"]
    assert isinstance(m["warnings"], str)
    assert m["model_fits"] is True or m["model_fits"] is False
    assert all(not isinstance(v, np.generic) for v in m.values())
    json.dumps({k: v for k, v in m.items() if k != "alternatives"}, allow_nan=True)


def _undetermined(res: dict) -> dict:
    """``res`` as the reworked estimate_period words an undetermined verdict."""
    return {**res, "periodic": None, "verdict": "undetermined", "verdict_why": "one cycle and a half: too few to tell",
            "period_s": float("nan"), "period_err_s": float("nan")}


def test_undetermined_is_not_not_periodic(tmp_path, monkeypatch):
    """estimate_period's third verdict (``periodic: None``) is carried as ``undetermined`` with
    its own why: no period_vs_published, the spin stage says why it needs more, and
    ``stages.period=on`` refuses it as undetermined, not as "no significant period"."""
    import functools

    import cssat.inversion.period

    real = cssat.inversion.period.estimate_period
    monkeypatch.setattr(cssat.inversion.period, "estimate_period",
                        functools.wraps(real)(lambda *a, **k: _undetermined(real(*a, **k))))
    model, run = _model(tmp_path, f"observations={EXAMPLE_TRACK}", "characterise.tracks=[101]",
                        "characterise.figures=false")
    m = model.score(run)
    assert m["verdict"] == "undetermined" and m["periodic"] is None
    assert m["why"] == "one cycle and a half: too few to tell" and "period_vs_published" not in m
    assert "periodic light curve (the period is undetermined)" in m["stage_spin"]
    assert "undetermined" in model.headline(m, None) and "not periodic" not in model.headline(m, None)
    with pytest.raises(FieldError) as err:
        _model(tmp_path / "on", f"observations={EXAMPLE_TRACK}", "characterise.tracks=[101]", "stages.period=on")
    assert err.value.field == "stages.period" and "undetermined" in err.value.detail


def test_the_verdict_words_before_the_period_rework():
    """Without estimate_period's ``verdict``/``verdict_why`` (today's result) the word comes from
    ``periodic`` and the why from the FAP and repeat tests."""
    from cssat.experiments.forward.verdicts import VERDICTS, period_verdict, period_why

    assert set(VERDICTS) == set(VERDICT_WORDS)
    old = {"periodic": False, "fap": 0.2, "repeat": 0.1, "why": "the peak"}
    assert period_verdict(old) == "not periodic" and "0.2" in period_why(old) and "repeat 0.10" in period_why(old)
    assert period_verdict({**old, "periodic": True, "fap": 1e-9, "repeat": 0.9}) == "periodic"
    assert period_verdict({**old, "periodic": None}) == "undetermined" and period_verdict(None) == "undetermined"
    assert period_why({**old, "verdict_why": "said so"}) == "said so"


def _curve(kind: str, n: int = 1500, step: float = 0.4, seed: int = 0):
    """``t`` (s, a regular cadence), ``y`` (mag, noise 0.05): one period of 23 s with its first
    harmonic, two incommensurate periods (23 s and 37 s: a tumbler's look), or noise alone."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * step
    y = rng.normal(0, 0.05, n)
    if kind == "periodic":
        y += 0.4 * np.sin(2 * np.pi * t / 23.0) + 0.2 * np.sin(4 * np.pi * t / 23.0)
    elif kind == "two periods":
        y += 0.4 * np.sin(2 * np.pi * t / 23.0) + 0.4 * np.sin(2 * np.pi * t / 37.0 + 1.0)
    return t, 8.0 + y


@pytest.mark.parametrize("kind, skipped", [("periodic", "one period fits"), ("flat", "no more than its noise"),
                                           ("two periods", None)])
def test_tumbling_auto_runs_only_where_the_period_stage_asks(kind, skipped):
    """``stages.tumbling: auto``: one period that fits, or a curve that varies no more than its
    noise, records the stage as skipped with why (it used to run on every curve, ~8x the period
    stage); two periods (no single period fits) run it."""
    from cssat.experiments.context import Run
    from cssat.experiments.forward.verdicts import period_stage, tumbling_stage, variation_over_noise
    from cssat.models.observed.config import ObservedSettings, StagesConfig

    t, y = _curve(kind)
    tracks = np.zeros(len(t), dtype=str)
    opt = ObservedSettings(observations="(synthetic)", stages=StagesConfig(spin="off"))
    run = Run(out_dir=Path("."), dtype=None, device=None, seed=0)
    m = {"variation_over_noise": variation_over_noise(t, y, None, tracks)}
    res = period_stage(run, opt, t, y, None, tracks, m)
    assert m["verdict"] in VERDICT_WORDS, m["verdict"]
    if kind == "two periods":  # a long common "period" may be found, but its series does not fit
        assert m["verdict"] != "periodic" or m["model_fits"] is False, (m["verdict"], m["chi2_per_sample"])
    else:
        assert (m["verdict"] == "periodic") is (kind == "periodic"), (m["verdict"], m["why"])
    tumbling_stage(run, opt, t, y, None, res, m)
    if skipped:
        assert m["stage_tumbling"].startswith("skipped: ") and skipped in m["stage_tumbling"], m["stage_tumbling"]
        assert "tumbling" not in m and "seconds_tumbling" not in run.timings()
    else:
        assert m["stage_tumbling"] == "ok" and "seconds_tumbling" in run.timings(), m["stage_tumbling"]


def test_what_the_period_stage_asks_of_the_tumbling_stage():
    """The rule itself: a curve not called periodic runs it when it varies over twice its noise
    or its model misfits; a periodic one only when its model misfits; no period result (the
    stage off): the data decide."""
    from cssat.experiments.forward.verdicts import TUMBLING_MIN_VARIATION, _tumbling_not_asked

    fits, misfits = {"model_fits": True, "chi2_per_sample": 1.0}, {"model_fits": False, "chi2_per_sample": 9.0}
    for verdict in ("not periodic", "undetermined"):
        assert _tumbling_not_asked({"verdict": verdict, "variation_over_noise": 1.2 * TUMBLING_MIN_VARIATION}, fits) is None
        assert "noise" in _tumbling_not_asked({"verdict": verdict, "variation_over_noise": 1.2}, fits)
        assert _tumbling_not_asked({"verdict": verdict, "variation_over_noise": 1.2}, misfits) is None
    assert "one period fits" in _tumbling_not_asked({"verdict": "periodic", "variation_over_noise": 9.0}, fits)
    assert _tumbling_not_asked({"verdict": "periodic", "variation_over_noise": 9.0}, misfits) is None
    assert _tumbling_not_asked({"verdict": "undetermined"}, None) is None


def test_variation_over_noise_is_one_for_noise():
    from cssat.experiments.forward.verdicts import variation_over_noise

    t, y = _curve("flat", n=4000)
    tracks = np.zeros(len(t), dtype=str)
    assert 0.9 < variation_over_noise(t, y, None, tracks) < 1.1
    assert 0.9 < variation_over_noise(t, y, np.full(len(t), 0.05), tracks) < 1.1
    t, y = _curve("two periods", n=4000)
    assert variation_over_noise(t, y, None, tracks) > 3


def test_spin_on_without_an_element_set_is_refused_before_the_file_is_read():
    from cssat.experiments.forward.observed import observed_settings

    with pytest.raises(FieldError) as err:
        observed_settings(_cfg(f"observations={EXAMPLE_TRACK}", "stages.spin=on"))
    assert err.value.field == "stages.spin" and "scenario.tle" in err.value.detail


def test_spin_on_with_one_night_is_refused_before_the_period_search(tmp_path):
    """A one-night file with an element set: refused at ``clean`` naming ``stages.spin`` and the
    nights, before the period stage has run (its timing absent)."""
    from cssat.data import ObservedLightCurve, write_light_curve
    from cssat.experiments.context import Run
    from cssat.experiments.forward.base import run_stages
    from cssat.experiments.forward.observed import Observed

    t = np.datetime64("2020-04-01T21:00:00", "us") + (np.linspace(0, 600, 300) * 1e6).astype("timedelta64[us]")
    y = 8.0 + 0.3 * np.sin(2 * np.pi * np.linspace(0, 600, 300) / 37.0)
    write_light_curve(tmp_path / "one.csv", ObservedLightCurve(t, y, np.full(300, 0.02), "magnitude"))
    cfg = _cfg(f"observations={tmp_path / 'one.csv'}", "stages.spin=on", TLE)
    run = Run.from_config(cfg, tmp_path / "r")
    with pytest.raises(FieldError) as err:
        run_stages(Observed(), cfg, run, ("plan", "measure", "estimate"))
    assert err.value.field == "stages.spin" and "nights" in err.value.detail
    assert "seconds_period" not in run.timings() and set(run.results) == {"plan"}
    assert "stage_period" not in err.value.partial_metrics


@pytest.mark.parametrize("key, value", [("min_period_s", -1), ("max_harmonics", 0), ("fap_max", 2.0)])
def test_period_option_errors_keep_their_prefix(tmp_path, key, value):
    with pytest.raises(FieldError) as err:
        _model(tmp_path, f"observations={EXAMPLE_TRACK}", f"period.{key}={value}", "characterise.figures=false")
    assert err.value.field == f"period.{key}", str(err.value)


def test_an_unknown_observed_key_is_refused_naming_it_and_the_allowed():
    from cssat.experiments.forward.observed import observed_settings

    with pytest.raises(FieldError) as err:
        observed_settings(_cfg(f"observations={EXAMPLE_TRACK}", "+observed.bogus=1"))
    assert err.value.field == "observed.bogus" and "value_col" in err.value.detail and "time_scale" in err.value.detail


def test_a_failed_file_leaves_what_was_known(tmp_path):
    """A stage that fails leaves ``partial_metrics`` on the exception: ``verdict: failed``, the
    error as ``why`` and, once the file was read, its object and track."""
    with pytest.raises(FieldError) as err:
        _model(tmp_path, f"observations={STARLINK}", "characterise.min_samples=100000")
    part = err.value.partial_metrics
    assert part["verdict"] == "failed" and "characterise.min_samples" in part["why"]
    assert part["object_id"] == "51722" and part["track"] == "20416355"
    bad = tmp_path / "broken.txt"
    bad.write_text("# satellite: 1 X\n# Date Time Mag\n2020-01-01 00:00:00 99.999\n")
    with pytest.raises(FieldError) as err:
        _model(tmp_path / "b", f"observations={bad}")
    assert err.value.partial_metrics["verdict"] == "failed" and "observations" in err.value.partial_metrics["why"]


@pytest.mark.parametrize("overrides, field", [
    (["tumbling.min_period_s=-5"], "tumbling.min_period_s"),  # was never checked where auto skips the search
    (["tumbling.order=11"], "tumbling.order"),
    (["stages.tumbling=maybe"], "stages.tumbling"),
    (["characterise.min_samples=3"], "characterise.min_samples"),
    (["period.method=bogus"], "period.method"),
    (["+period.min_periods=3"], "period.min_periods"),  # added past the schema: refused when planned
    (["stages.period=off", "stages.spin=on", TLE], "stages.spin"),  # can never be served: refused before reading
])
def test_settings_refused_in_plan_naming_the_key(overrides, field):
    from cssat.experiments.forward.observed import observed_settings

    with pytest.raises(FieldError) as err:
        observed_settings(_cfg(f"observations={EXAMPLE_TRACK}", *overrides))
    assert err.value.field == field, str(err.value)


@pytest.mark.parametrize("override, key", [("tumbling.order=x", "tumbling.order"),  # was int("x")'s traceback
                                           ("characterise.max_epoch_days=abc", "characterise.max_epoch_days"),
                                           ("period.min_periods=3", "period.min_periods"),
                                           ("stages.bogus=on", "stages.bogus")])
def test_the_schema_refuses_a_wrong_type_or_an_unknown_key_when_composed(override, key):
    """The groups are typed (cssat.models.observed.config): a value of the wrong type, or a key
    that is no field, is refused by Hydra's composition, naming the key."""
    from hydra.errors import ConfigCompositionException

    with pytest.raises(ConfigCompositionException, match=key.replace(".", r"\.")):
        _cfg(f"observations={EXAMPLE_TRACK}", override)


def test_a_group_given_as_a_mapping_is_checked_by_its_dataclass():
    """Without Hydra (a catalogue's rows): the same refusals, each naming its full key and, for
    an unknown key, the group's settings."""
    from cssat.models.observed.config import CharacteriseConfig, PeriodConfig, StagesConfig, TumblingConfig, typed_group

    for cls, key, values, field in [(TumblingConfig, "tumbling", {"order": "x"}, "tumbling.order"),
                                    (CharacteriseConfig, "characterise", {"max_epoch_days": "abc"},
                                     "characterise.max_epoch_days"),
                                    (CharacteriseConfig, "characterise", {"max_epoch_days": 0}, "characterise.max_epoch_days"),
                                    (StagesConfig, "stages", {"spin": True}, "stages.spin"),
                                    (PeriodConfig, "period", {"min_periods": 3}, "period.min_periods")]:
        with pytest.raises(FieldError) as err:
            typed_group(cls, values, key)
        assert err.value.field == field, str(err.value)
    with pytest.raises(FieldError) as err:
        typed_group(PeriodConfig, {"min_periods": 3}, "period")
    assert "estimate_period" in err.value.detail and "n_surrogates" in err.value.detail and "method" in err.value.detail


def test_period_method_picks_a_registered_method(tmp_path):
    """``period.method``: null is estimate_period; a registered method's name runs that method
    (the library's lombscargle, a periodogram's peak on its grid: its period on the example
    track's first track within 2 % of MMT's published 18.888 s or its double, not refined as
    estimate_period's is, to 1e-4)."""
    model, run = _model(tmp_path, f"observations={EXAMPLE_TRACK}", "characterise.tracks=[101]", "period.method=lombscargle",
                        "characterise.figures=false", "stages.tumbling=off", "stages.spin=off")
    p = model.score(run)["period_s"]
    assert run.results["plan"].period.method == "lombscargle"
    assert min(abs(p / 18.888 - 1), abs(p / (2 * 18.888) - 1)) < 0.02, p
    assert abs(p / 18.888 - 1) > 1e-3, p


@pytest.mark.parametrize("override, field", [("observed.format=bogus", "observed.format"),  # was "format"
                                             ("observed.kind=flux", "observed.kind")])  # was "observations.kind"
def test_the_reader_s_refusal_of_a_setting_names_its_config_key(override, field):
    from cssat.experiments.scene import read_observations

    with pytest.raises(FieldError) as err:
        read_observations(_cfg(f"observations={STARLINK}", override))
    assert err.value.field == field, str(err.value)
    with pytest.raises(FieldError) as err:  # a file's own fault keeps the file's name
        read_observations(_cfg(f"observations={REAL / 'absent.txt'}"))
    assert err.value.field == "observations", str(err.value)


def test_apparent_magnitudes_are_reduced_to_1000_km_before_the_period_search(tmp_path):
    """An MMT track (apparent ``Mag``, ``Distance`` in km) of a body whose magnitude at 1000 km is
    a 20 s sinusoid, seen while its range grows from 700 to 1,900 km (2.2 mag of trend): the
    period stage's values are ``Mag − 5 log10(r / 1000 km)``, computed here from the file's own
    columns, and the period is the body's."""
    from conftest import cfg_of

    from cssat.experiments import run_experiment

    t = np.arange(0.0, 240.0, 0.1)
    r = 700.0 + 5.0 * t
    mag = 7.0 + 0.3 * np.sin(2 * np.pi * t / 20.0) + 5 * np.log10(r / 1000.0)
    mag += 0.01 * np.random.default_rng(4).standard_normal(t.size)
    stamps = np.datetime64("2022-05-21T19:22:07.000", "ms") + (t * 1000).round().astype("timedelta64[ms]")
    head = ("# satellite: 99002 TEST BODY\n# catalogue: 1 NORAD\n# variability: 0 Not variable\n# variability_period: None\n"
            "# type: 0 U/SAT Uncertain Satellite\n# npoints: {}\n#\n# Date Time StdMag Mag Filter Penumbra Distance Phase "
            "Channel Track\n").format(t.size)
    rows = [f"{str(s)[:10]} {str(s)[11:]} {m - 5 * np.log10(d / 1000.0):.5f} {m:.5f} Clear 0 {d:.3f} 60.0 1 1001\n"
            for s, m, d in zip(stamps, mag, r)]
    f = tmp_path / "track.txt"
    f.write_text(head + "".join(rows))
    cols = [ln.split() for ln in rows]
    want = np.array([float(c[3]) for c in cols]) - 5 * np.log10(np.array([float(c[6]) for c in cols]) / 1000.0)
    m = run_experiment(cfg_of("experiment=characterise", f"observations={f}", "stages.tumbling=off", "stages.spin=off",
                              "characterise.figures=false", "period.convention=photometric", "threads=1"), tmp_path / "run")
    assert m["status"] == "ok" and m["period_magnitudes"] == "apparent, reduced to a range of 1000 km"
    np.testing.assert_allclose(np.load(tmp_path / "run" / "arrays.npz")["values"], want, rtol=0, atol=1e-9)
    assert m["verdict"] == "periodic" and m["period_s"] == pytest.approx(20.0, rel=1e-3)
