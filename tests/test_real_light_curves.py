"""Issue 34: real light curves end to end — the files observers publish, periods with the
defaults, "not periodic" as an answer, refusals, the characterise experiment and a catalogue.

Real files (tests/data/real/, sources and licences in SOURCES.md): two MMT-9 exports of
satellites the MMT database labels "Not variable", an ALCDEF file of (1) Ceres, SCORE's own test
upload. Synthetic files in published formats (tests/data/formats/make_examples.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cssat._checks import FieldError
from cssat.smoke import EXAMPLE_TRACK

DATA = Path(__file__).parent / "data"
REAL = DATA / "real"
MMT_REAL = [REAL / "mmt_sat10288_starlink3535_track20416355.txt", REAL / "mmt_sat8843_oneweb0208_excerpt.txt"]
MMT_RB = EXAMPLE_TRACK  # the synthetic MMT-format rocket body shipped in the package


def test_mmt_exports_read_as_published_with_their_metadata():
    from cssat.data import read_light_curve

    lc = read_light_curve(MMT_REAL[0])
    assert len(lc) == 200 and lc.kind == "magnitude" and lc.magnitude_system == "apparent"
    assert lc.meta["object_id"] == "51722" and lc.meta["name"] == "STARLINK-3535" and lc.meta["variability"] == "nonvariable"
    assert "published_period_s" not in lc.meta
    assert lc.times_utc[0] == np.datetime64("2022-05-21T19:22:07.790")  # the first row's two fields, as written
    assert lc.values[0] == 4.84617 and lc.ranges_km[0] == 597.555 and lc.phase_deg[0] == 94.476
    assert set(lc.tracks) == {"20416355"} and set(lc.filters) == {"Clear"} and lc.channels is not None
    std = read_light_curve(MMT_REAL[0], value_col="StdMag")
    assert std.values[0] == 5.873 and std.magnitude_system.startswith("normalised")
    rb = read_light_curve(MMT_RB)
    assert rb.meta["published_period_s"] == 18.888 and rb.meta["name"] == "SYNTHETIC R/B"
    assert [len(x) for x in rb.split()] == [600, 600]  # two tracks, two channels interleaved 7 ms apart
    assert np.all(np.diff(rb.times_utc).astype(np.int64) > 0)


def test_alcdef_score_and_astropy_tables():
    from astropy.table import QTable, Table
    from astropy.time import Time
    import astropy.units as u

    from cssat.data import read_light_curve

    ceres = read_light_curve(REAL / "alcdef_ceres_stephens_2011.txt")
    assert len(ceres) == 1210 and ceres.meta["name"] == "Ceres" and len(set(ceres.tracks)) == 5
    jd0 = 2455817.735937  # the first DATA line; 1970-01-01 is JD 2440587.5 (an independent conversion)
    expect = np.datetime64("1970-01-01T00:00:00", "us") + np.timedelta64(int(round((jd0 - 2440587.5) * 86400e6)), "us")
    assert abs((ceres.times_utc[0] - expect).astype(np.int64)) <= 1 and set(ceres.filters) == {"R", "V"}  # the blocks' MAGBAND
    with pytest.raises(FieldError, match=r"observations\.object.*18 objects"):
        read_light_curve(REAL / "score_test_data.csv")
    pel = read_light_curve(REAL / "score_test_data.csv", object=58296)
    assert len(pel) == 2 and pel.sites[0].tolist() == [52.15399, 4.49085, 8.0] and pel.ranges_km[0] == 571.894
    assert len(read_light_curve(REAL / "score_test_data.csv", object="Kuiper-P1")) == 2
    with pytest.raises(FieldError, match=r"observation_time\[row 2\].*must increase"):  # Pomenis: reports, not a series
        read_light_curve(REAL / "pomenis_starlink_v1p5_observations.csv", time_col="observation_time",
                         value_col="ab_magnitude")
    # an ECSV file whose Time column is in TT: 69.184 s from UTC in 2020
    tt = read_light_curve(DATA / "formats" / "lightcurve_tt.ecsv")
    assert tt.times_utc[0] == np.datetime64("2020-04-01T20:58:50.816") and tt.meta["object_id"] == "99002"
    # an astropy Table object and a FITS file with TIMESYS TT
    t = Time("2020-04-01T21:00:00", scale="tt") + np.arange(20) * u.s
    tab = Table({"time": t, "mag": np.linspace(9, 10, 20) * u.mag})
    assert read_light_curve(tab).times_utc[0] == np.datetime64("2020-04-01T20:58:50.816")
    q = QTable({"time": t, "flux": np.linspace(1, 2, 20) * u.W / u.m ** 2})
    with pytest.raises(FieldError, match="not a magnitude"):
        read_light_curve(q, value_col="flux")
    assert read_light_curve(q, value_col="flux", kind="flux").values[-1] == 2.0
    ts = ceres.to_table()
    assert len(ts) == 1210 and ts["mag"].unit == u.mag and ts.meta["name"] == "Ceres"


def test_a_fits_table_honours_timesys(tmp_path):
    from astropy.table import Table
    from astropy.time import Time
    import astropy.units as u

    from cssat.data import read_light_curve

    t = Time("2020-04-01T21:00:00", scale="tt") + np.arange(20) * u.s
    Table({"time": t, "mag": np.linspace(9, 10, 20) * u.mag}).write(tmp_path / "lc.fits")
    lc = read_light_curve(tmp_path / "lc.fits")
    assert lc.times_utc[0] == np.datetime64("2020-04-01T20:58:50.816") and lc.values[-1] == 10.0


@pytest.mark.parametrize("text, kwargs, field, words", [
    ("time_utc,magnitude\n2020-01-01T00:00:00,9.1\n2020-01-01T00:00:01,99.999\n", {}, r"magnitude\[row 2\]", "not a magnitude"),
    ("time_utc,magnitude\n2020-01-01T00:00:00,9.1\n2020-01-01T00:00:01,-1000\n", {}, r"magnitude\[row 2\]", "not a magnitude"),
    ("time_utc,flux\n2020-01-01T00:00:00,9.1\n", {"value_col": "flux"}, r"observations\.kind", "flux"),
    ("time_utc,magnitude\n2020-01-01T00:00:00,9.1\n2020-01-01T00:00:00,9.2\n", {}, r"time_utc\[row 2\]", "duplicate"),
])
def test_bad_files_name_the_field(tmp_path, text, kwargs, field, words):
    from cssat.data import read_light_curve

    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(FieldError, match=words) as err:
        read_light_curve(f, **kwargs)
    assert pytest.importorskip("re").search(field, err.value.field), err.value.field


def test_duplicates_merge_whitespace_columns_and_a_huge_file(tmp_path, monkeypatch):
    from cssat.data import read_light_curve, text

    f = tmp_path / "lc.txt"
    f.write_text("# date time mag err\n2020-01-01 00:00:00 9.0 0.1\n2020-01-01 00:00:00 9.2 0.1\n2020-01-01 00:00:01 9.4 0.2\n")
    lc = read_light_curve(f, time_col=["date", "time"], value_col="mag", error_col="err", duplicates="merge")
    assert len(lc) == 2 and lc.values[0] == pytest.approx(9.1) and lc.errors[0] == pytest.approx(0.1 / np.sqrt(2))
    long = tmp_path / "long.csv"
    long.write_text("time_utc,magnitude,note\n2020-01-01T00:00:00,9.0,\"" + "x" * 140_000 + "\"\n")
    with pytest.raises(FieldError, match="observations"):
        read_light_curve(long)
    monkeypatch.setattr(text, "BYTES_PER_BYTE", 10 ** 9)  # as if the file were ~10 GB per byte
    with pytest.raises(FieldError, match="split it"):
        read_light_curve(f, time_col=["date", "time"], value_col="mag")


def _sinusoid(P=628.3, T=3000, span=6000.0):
    t = np.linspace(0, span, T)
    return t, 2 + np.sin(2 * np.pi * t / P)


def test_periods_with_the_defaults_and_no_period_as_an_answer():
    from astropy.timeseries import LombScargle

    from cssat.inversion import estimate_period

    t, y = _sinusoid()
    out = estimate_period(t, y)  # noise free: not doubled (was 1256.6 s)
    assert out["periodic"] and abs(out["period_s"] - 628.3) < max(3 * out["period_err_s"], 1e-6 * 628.3), out["period_s"]
    flat = estimate_period(t, np.full_like(t, 3.0))  # a constant: no period (was 275,812 s)
    assert not flat["periodic"] and np.isnan(flat["period_s"])
    rng = np.random.default_rng(5)
    assert not estimate_period(t, rng.normal(size=t.size))["periodic"]
    walk = np.cumsum(rng.normal(size=2000)) * 0.05  # red noise: aperiodic
    assert not estimate_period(np.arange(2000) * 0.1, walk)["periodic"]
    # the MMT-format rocket body: double-peaked, two channels, two tracks; a plain periodogram gives half
    from cssat.data import read_light_curve

    rb = read_light_curve(MMT_RB)
    for track in rb.split():
        ts, mag = track.times_s(), track.values
        res = estimate_period(ts, mag)
        assert res["periodic"] and abs(res["period_s"] / 18.888 - 1) < 0.01, res["period_s"]
        assert "P/2" in {a["relation"] for a in res["alternatives"]} and res["fap"] < 1e-3  # 2P: past half the track
        f, p = LombScargle(ts, mag).autopower(minimum_frequency=2 / ts[-1], maximum_frequency=5.0, samples_per_peak=10)
        assert abs(1 / f[np.argmax(p)] / (18.888 / 2) - 1) < 0.02  # astropy's peak: the half period
    for path in MMT_REAL:  # MMT: "Not variable"
        lc = read_light_curve(path)
        assert not estimate_period(lc.times_s(), lc.values)["periodic"], path.name


def test_one_period_is_not_tumbling():
    from cssat.inversion import estimate_tumbling_periods

    t, y = _sinusoid(T=800)
    out = estimate_tumbling_periods(t, y + np.random.default_rng(1).normal(0, 0.01, t.size))
    assert out["tumbling"] is False and out["why"]


def test_characterise_a_real_track_and_a_periodic_one(tmp_path):
    from conftest import run_cli

    code, lines = run_cli(["experiment=characterise", f"observations={MMT_REAL[1]}", f"hydra.run.dir={tmp_path / 'a'}"], tmp_path)
    assert code == 0, lines
    m = json.loads((tmp_path / "a" / "metrics.json").read_text())
    # MMT: "Not variable"; the excerpt holds 1.3 cycles of its best period: not periodic, or undetermined
    assert m["status"] == "ok" and m["verdict"] in ("not periodic", "undetermined") and m["periodic"] is not True
    assert m["object_id"] == "48243" and m["why"]
    assert m["stage_spin"].startswith("skipped: needs") and "scenario.tle" in m["stage_spin"]
    assert (tmp_path / "a" / "figures" / "characterise.png").is_file()
    code, lines = run_cli(["experiment=characterise", f"observations={MMT_RB}", "characterise.tracks=[101]",
                           f"hydra.run.dir={tmp_path / 'b'}"], tmp_path)
    m = json.loads((tmp_path / "b" / "metrics.json").read_text())
    assert code == 0 and m["periodic"] and abs(m["period_vs_published"]) < 0.01 and m["n_samples"] == 600


@pytest.mark.parametrize("args, field", [
    (["experiment=characterise"], "observations"),
    (["experiment=characterise", f"observations={MMT_RB}", "stages.spin=maybe"], "stages.spin"),
    (["experiment=characterise", f"observations={MMT_RB}", "period.min_periods=3"], "period.min_periods"),
    (["experiment=characterise", f"observations={MMT_RB}", "stages.spin=on"], "stages.spin"),
    (["experiment=characterise", f"observations={MMT_RB}", "+observed.bogus=1"], "observed.bogus"),  # was a traceback
    (["experiment=inversion", f"observations={MMT_RB}", "nights.n=1"], "scenario.tle"),  # NORAD 99001, not Astra's
])
def test_refusals_exit_2_naming_the_field(tmp_path, args, field):
    from conftest import run_cli

    code, lines = run_cli([*args, f"hydra.run.dir={tmp_path / 'r'}"], tmp_path)
    assert code == 2 and any(field in ln for ln in lines), lines
    assert not (tmp_path / "r" / "metrics.json").is_file() or json.loads((tmp_path / "r" / "metrics.json").read_text())["status"] == "failed"


def test_a_glob_that_matches_nothing_is_refused(tmp_path):
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "cssat.app", "-m", "experiment=characterise",
                          f"observations={tmp_path}/*.txt"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and "observations: no file matches" in res.stderr


@pytest.mark.parametrize("scale, offset_s", [("utc", 0.0), ("tai", 37.0), ("tt", 69.184)])
def test_csv_time_scales_through_astropy(tmp_path, scale, offset_s):
    """2020: TAI − UTC = 37 s, TT − TAI = 32.184 s (IERS Bulletin C): a stamp in TAI or TT is
    that much later than the same instant in UTC; Julian dates alike."""
    from cssat.data import read_light_curve

    f = tmp_path / "lc.csv"
    f.write_text("time,mag\n2020-04-01T21:00:00,9.0\n2020-04-01T21:00:10,9.1\n")
    lc = read_light_curve(f, time_col="time", value_col="mag", time_scale=scale)
    expect = np.datetime64("2020-04-01T21:00:00", "us") - np.timedelta64(int(round(offset_s * 1e6)), "us")
    assert lc.times_utc[0] == expect
    g = tmp_path / "jd.csv"
    g.write_text("jd,mag\n2458941.375,9.0\n2458941.5,9.1\n")  # 2020-04-01 21:00 and 2020-04-02 00:00
    jd = read_light_curve(g, time_col="jd", value_col="mag", time_format="jd", time_scale=scale)
    assert jd.times_utc[0] == expect


def test_one_observer_per_sample():
    """A SCORE-like mix of two sites: each sample's observer is its own site — the rows of the
    two single-site scenarios (make_scenario), put back in time order."""
    from hydra import compose, initialize_config_module

    from cssat.experiments.scene import build_scenario
    from cssat.scene import ASTRA_1KR_SYNTHETIC_TLE, make_scenario

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=characterise"])
    times = np.array(["2020-04-01T21:00:00", "2020-04-01T21:01:00", "2020-04-01T21:02:30", "2020-04-01T21:04:00"],
                     dtype="datetime64[us]")
    sites = np.array([[51.17, 10.45, 0.0], [-30.2, -70.7, 2200.0], [51.17, 10.45, 0.0], [-30.2, -70.7, 2200.0]])
    mixed = build_scenario(cfg, times, sites)
    for rows, (lat, lon, alt) in (([0, 2], sites[0]), ([1, 3], sites[1])):
        one = make_scenario(tle=ASTRA_1KR_SYNTHETIC_TLE, times=times[rows], lat_deg=lat, lon_deg=lon, alt_m=alt)
        for k in ("r_obs", "range_km", "elevation_deg", "r_sat"):
            assert np.allclose(getattr(mixed, k)[rows], getattr(one, k), rtol=0, atol=1e-9), k
    assert np.array_equal(mixed.times, times)


@pytest.mark.parametrize("n, hours", [(2, 0.1), (60, 2.0)])
def test_an_inversion_the_data_cannot_constrain_is_refused(tmp_path, n, hours):
    """A 2-row file, and one pass of 60 samples: exit 2 naming ``observations`` and what is
    missing, no shape written (was: an EGI and a shape.obj with status ok)."""
    from conftest import run_cli

    from cssat.data import ObservedLightCurve, write_light_curve

    t = np.datetime64("2020-04-01T21:00:00", "us") + (np.linspace(0, hours * 3600, n) * 1e6).astype("timedelta64[us]")
    write_light_curve(tmp_path / "obs.csv", ObservedLightCurve(t, np.full(n, 9.0), np.full(n, 0.05), "magnitude"))
    code, lines = run_cli(["experiment=inversion", f"observations={tmp_path / 'obs.csv'}", "nights.n=1",
                           "inversion.n_normals=64", f"hydra.run.dir={tmp_path / 'r'}"], tmp_path)
    assert code == 2 and any("observations" in ln and "nights" in ln for ln in lines), lines
    assert not (tmp_path / "r" / "shape.obj").exists()


MMT_HEAD = "# satellite: 51722 STARLINK-3535 / US\n# variability: 0 Not variable\n# Date Time StdMag Mag Filter Penumbra Distance Phase Channel Track\n"
MMT_ROW = "2022-05-21 19:22:{:06.3f} 5.873 4.84617 Clear 0 597.555 94.476 8 20416355\n"


@pytest.mark.parametrize("name, text, kwargs, field", [
    ("novar.txt", "# satellite: 1 X\n# variability:\n# Date Time Mag\n2020-01-01 00:00:00 9.0\n", {}, None),
    ("score.csv", "satellite_name,norad_cat_id,observation_time_utc,apparent_magnitude\n", {}, "observations"),
    ("period.txt", MMT_HEAD.replace("# Date", "# variability_period: -5\n# Date") + MMT_ROW.format(7.79), {},
     "observations.variability_period"),
    ("dist.txt", MMT_HEAD + MMT_ROW.format(7.79).replace("597.555", "-500"), {}, r"observations.Distance[row 1]"),
    ("phase.txt", MMT_HEAD + MMT_ROW.format(7.79).replace("94.476", "400"), {}, r"observations.Phase[row 1]"),
    ("jd0.txt", "STARTMETADATA\nOBJECTNAME=X\nDELIMITER=PIPE\nENDMETADATA\nDATA=0|7.3|0.004\n", {}, "observations.JD[row 1]"),
    ("open.txt", "STARTMETADATA\nOBJECTNAME=X\nDATA=2455817.7|7.3|0.004\n", {}, "observations"),
    ("year.csv", "time_utc,magnitude\n2020-01-01T00:00:00,9\n9999-12-31T23:59:59,8\n", {}, r"observations.time_utc[row 2]"),
    ("dup.csv", "time_utc,magnitude,magnitude\n2020-01-01T00:00:00,9,8\n", {}, "observations"),
    ("mmtflux.txt", MMT_HEAD + MMT_ROW.format(7.79), {"kind": "flux"}, "observations.kind"),
    ("mmtobj.txt", MMT_HEAD + MMT_ROW.format(7.79), {"object": 25544}, "observations.object"),
    ("unixtt.csv", "t,magnitude\n1585774800,9\n", {"time_col": "t", "time_format": "unix", "time_scale": "tt"},
     "observations.time_scale"),
])
def test_hostile_files_are_field_errors(tmp_path, name, text, kwargs, field):
    """Each a FieldError naming its field (found by a hostile-input pass: IndexErrors, a year-0
    JD, a flux option silently ignored, a negative distance accepted)."""
    from cssat.data import read_light_curve

    f = tmp_path / name
    f.write_text(text)
    if field is None:  # a header key without its value is no value, not a crash
        assert "variability" not in read_light_curve(f).meta
        return
    with pytest.raises(FieldError) as err:
        read_light_curve(f, **kwargs)
    assert err.value.field == field, (err.value.field, str(err.value))


def test_hostile_tables_and_arrays():
    from astropy.table import MaskedColumn, QTable, Table
    from astropy.time import Time
    import astropy.units as u

    from cssat.data import read_light_curve
    from cssat.inversion import estimate_period

    t = Time("2020-04-01T21:00:00") + np.arange(30) * u.s
    masked = Table({"time": t, "mag": MaskedColumn(np.full(30, 9.0), mask=[False] * 5 + [True] + [False] * 24)})
    with pytest.raises(FieldError, match=r"row 6"):
        read_light_curve(masked)
    with pytest.raises(FieldError, match="one value per row"):
        read_light_curve(Table({"time": t, "mag": np.ones((30, 2))}))
    with pytest.raises(FieldError, match="not a flux"):
        read_light_curve(QTable({"time": t, "flux": np.ones(30) * u.m}), value_col="flux", kind="flux")
    jy = read_light_curve(QTable({"time": t, "flux": np.ones(30) * u.Jy, "flux_err": np.full(30, 10.0) * u.mJy}),
                          value_col="flux", kind="flux")
    # a flux density in Jy becomes a magnitude through the band's zero point (issue 46): astropy's AB
    # magnitude of 1 Jy, within V's Vega-AB offset (< 0.05 mag); the error 2.5/ln10 * 10 mJy / 1 Jy
    assert jy.kind == "magnitude" and abs(jy.values[0] - (1 * u.Jy).to_value(u.ABmag)) < 0.05
    assert jy.errors[0] == pytest.approx(2.5 / np.log(10) * 0.01)
    with pytest.raises(FieldError, match="error_col"):
        read_light_curve(Table({"time": t, "mag": np.ones(30)}), error_col="nope")
    with pytest.raises(FieldError):
        read_light_curve(5)
    ts = np.linspace(0, 100, 500)
    ys = np.sin(2 * np.pi * ts / 7.3)
    stamps = np.datetime64("2020-01-01", "us") + (ts * 1e6).astype("timedelta64[us]")
    assert abs(estimate_period(stamps, ys)["period_s"] / 7.3 - 1) < 1e-6  # datetime64 times: seconds
    assert abs(estimate_period(ts, 1e8 + 0.3 * ys)["period_s"] / 7.3 - 1) < 1e-6  # a large offset is no obstacle
    for bad in ({"sigma": np.full(5, 0.02)}, {"min_period_s": 1e-9}):
        with pytest.raises(FieldError):
            estimate_period(ts, ys, **bad)
    for a, b in ((np.array(["a"] * 500), ys), (ts.reshape(50, 10), ys), (ts, ys + 0j)):
        with pytest.raises(FieldError):
            estimate_period(a, b)
    far = np.r_[ts, ts + 7 * 86400]  # two tracks a week apart: each track's resolution, then the fringes (issue 46)
    wk = estimate_period(far, np.r_[ys, ys] + 0.01 * np.random.default_rng(2).normal(size=2 * ts.size))
    assert wk["cycle_count"].startswith("ambiguous") and wk["period_err_s"] > 0.25 * 7.3 ** 2 / (7 * 86400)
    with pytest.raises(FieldError, match="trial frequencies"):  # a grid of one stretch's resolution can still be too big
        estimate_period(far, np.r_[ys, ys], min_period_s=1e-6)


def test_a_file_of_tracks_a_week_apart_is_characterised_track_by_track_then_whole(tmp_path):
    from conftest import run_cli

    lines = MMT_RB.read_text().splitlines()
    far = [ln.replace("2021-03-04", "2021-03-11", 1) if ln.endswith(" 102") else ln for ln in lines]
    (tmp_path / "far.txt").write_text("\n".join(far) + "\n")
    code, out = run_cli(["experiment=characterise", f"observations={tmp_path / 'far.txt'}", "characterise.figures=false",
                         f"hydra.run.dir={tmp_path / 'r'}"], tmp_path)
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    # each track apart, and the whole at one track's resolution (a full grid would need 1.5e7 frequencies): its
    # cycle count across the week is not fixed, so its period is the tracks' envelope with their 1σ
    assert code == 0 and m["n_tracks_periodic"] == 2 and m["verdict"] == "periodic"
    assert all(abs(p / 18.888 - 1) < 0.01 for p in m["track_periods_s"]) and abs(m["period_s"] / 18.888 - 1) < 0.01
    assert "cycle count across the gaps is not fixed" in m["warnings"]
    assert (tmp_path / "r" / "tracks.csv").read_text().count("\n") == 3


def test_tracks_nights_merge_and_light_time():
    from cssat.data import ObservedLightCurve, read_light_curve

    rb = read_light_curve(MMT_RB)
    a, b = rb.split()
    assert set(a.tracks) == {"101"} and set(b.tracks) == {"102"}
    with pytest.raises(FieldError, match="no track 7; the tracks: 101, 102"):
        rb.select(tracks=[7])
    both = ObservedLightCurve.merge([b, a])
    assert np.array_equal(both.times_utc, rb.times_utc) and np.array_equal(both.values, rb.values)
    assert len(rb.select(stop="2021-03-04T21:11:10")) == 600  # the first track: 21:10:05 to 21:11:04.807
    # a night runs local noon to noon: 21:10 UTC at 10.45° E (UTC+0.7 h) is the evening of the 4th
    assert set(rb.nights(utc_offset_h=10.45 / 15)) == {"2021-03-04"}
    shifted = rb.light_time_corrected()
    delay = (rb.times_utc - shifted.times_utc).astype(np.int64) / 1e6
    assert np.allclose(delay, rb.ranges_km / 299792.458, atol=1e-6)  # c exactly, km/s
    ts = a.to_table()
    assert ts["time"].scale == "utc" and len(ts) == 600 and ts.meta["name"] == "SYNTHETIC R/B"
    back = read_light_curve(ts)
    assert np.array_equal(back.times_utc, a.times_utc) and np.array_equal(back.values, a.values)


def test_a_drift_is_not_tumbling_and_a_half_integer_period_repeats():
    """Found by review: a steady rotator with a 0.3-mag drift was called tumbling (a 'period' at
    the cadence); a period of 13.5 frames had no cycle parity covering the phase (repeat NaN)."""
    from cssat.inversion import estimate_period, estimate_tumbling_periods

    rng = np.random.default_rng(0)
    t = np.arange(2000) * 0.1
    w = 2 * np.pi * t / 13.37
    for slope in (0.0, 0.3):
        y = 6 + 0.3 * np.cos(w) + 0.6 * np.cos(2 * w + 1) + slope * t / t[-1] + rng.normal(0, 0.05, t.size)
        out = estimate_tumbling_periods(t, y)
        assert out["tumbling"] is False, (slope, out["periods_s"], out["delta_bic"])
    y = 6 + 0.3 * np.cos(2 * np.pi * t / 1.35) + rng.normal(0, 0.05, t.size)
    res = estimate_period(t, y)
    assert res["periodic"] and abs(res["period_s"] / 1.35 - 1) < 1e-3
    sparse = np.arange(120) * 2.0  # a 2 s cadence, 6.5 samples a cycle
    res = estimate_period(sparse, 6 + 0.5 * np.cos(2 * np.pi * sparse / 13.0) + rng.normal(0, 0.05, sparse.size))
    assert res["periodic"] and abs(res["period_s"] / 13.0 - 1) < 0.01
