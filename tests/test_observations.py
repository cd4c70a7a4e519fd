"""Issue 23: real observations in — any time stamps, measured light-curve files."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from cssat._checks import FieldError


def test_a_scenario_on_given_times_is_the_regular_one_at_those_times():
    """The same instants as a regular grid give the same scenario bit for bit; a subset with gaps
    gives those rows of it (to SGP4's and skyfield's round-off)."""
    from cssat.scene import make_scenario

    grid = make_scenario(start_utc="2020-04-01T00:00:00", n_steps=120, step_s=60.0)
    same = make_scenario(times=grid.times)
    for k in ("times", "r_sat", "v_sat", "r_sun", "r_obs", "elevation_deg", "range_km", "sunlit"):
        assert np.array_equal(getattr(same, k), getattr(grid, k)), k
    idx = np.array([3, 4, 5, 40, 41, 90, 119])  # three nights' worth of gaps, in miniature
    sub = make_scenario(times=grid.times[idx])
    assert np.array_equal(sub.times, grid.times[idx])
    for k in ("r_sat", "r_sun", "r_obs"):
        assert np.allclose(getattr(sub, k), getattr(grid, k)[idx], rtol=0, atol=1e-6), k  # km
    assert np.allclose(sub.elevation_deg, grid.elevation_deg[idx], atol=1e-9)


def test_every_time_form_gives_the_same_instants():
    from astropy.time import Time as AstropyTime

    from cssat.scene import utc_times
    from cssat.scene.orbit import _skyfield

    iso = ["2020-04-01T21:00:00", "2020-04-01T21:00:07.25", "2020-04-02T03:14:15.5"]
    expect = np.array(iso, dtype="datetime64[us]")
    ts, _ = _skyfield()
    dts = [datetime.fromisoformat(t) for t in iso]
    forms = {
        "iso": iso,
        "iso with offset": ["2020-04-01T23:00:00+02:00", "2020-04-01T21:00:07.25Z", "2020-04-02T03:14:15.5+00:00"],
        "datetime64": expect,
        "datetime": dts,
        "aware datetime": [d.replace(tzinfo=timezone.utc) for d in dts],
        "skyfield": ts.from_datetimes([d.replace(tzinfo=timezone.utc) for d in dts]),
        "astropy": AstropyTime(iso, scale="utc"),
    }
    for name, value in forms.items():
        got = utc_times(value)
        assert np.array_equal(got, expect), (name, got)


@pytest.mark.parametrize("times, field, words", [
    (["2020-04-01T00:00:00", "2020-04-01T00:00:00"], "scenario.times[1]", "increase"),
    (["2020-04-01T00:00:10", "2020-04-01T00:00:00"], "scenario.times[1]", "increase"),
    (["2020-04-01T00:00:00", "yesterday"], "scenario.times[1]", "ISO"),
    (np.array(["2020-04-01", "NaT"], dtype="datetime64[us]"), "scenario.times[1]", "NaT"),
    ([], "scenario.times", "at least one"),
])
def test_bad_time_stamps_name_the_index(times, field, words):
    from cssat.scene import make_scenario

    with pytest.raises(FieldError, match=words) as err:
        make_scenario(times=times)
    assert err.value.field == field


def test_a_scenario_spans_three_nights_of_irregular_stamps():
    from cssat.scene import make_scenario

    rng = np.random.default_rng(0)
    start = datetime(2020, 4, 1, 20)
    stamps = sorted({start + timedelta(days=d, seconds=float(s)) for d in range(3)
                     for s in rng.uniform(0, 6 * 3600, 400)})
    sc = make_scenario(times=stamps)
    assert len(sc) == len(stamps) and (np.diff(sc.times).astype(np.int64) > 0).all()
    assert (sc.elevation_deg > 20).all()  # Astra 1KR from Germany: always up


def _write(path, text):
    path.write_text(text)
    return path


def test_read_a_survey_export_with_any_column_names(tmp_path):
    from cssat.data import read_light_curve

    f = _write(tmp_path / "export.csv", "# an export with its own names\nobs_time,mag_v,sigma,band,site\n"
               "2020-04-01T21:00:00Z,10.52,0.02,V,Sonneberg\n2020-04-01T21:00:31.5Z,10.55,0.03,V,Sonneberg\n"
               "2020-04-02T22:10:00+01:00,10.41,0.02,R,Ondrejov\n")
    lc = read_light_curve(f, time_col="obs_time", value_col="mag_v", error_col="sigma", filter_col="band",
                          observer_col="site")
    assert lc.kind == "magnitude" and len(lc) == 3
    assert np.array_equal(lc.times_utc, np.array(["2020-04-01T21:00:00", "2020-04-01T21:00:31.5", "2020-04-02T21:10:00"],
                                                  dtype="datetime64[us]"))
    assert np.allclose(lc.values, [10.52, 10.55, 10.41]) and np.allclose(lc.errors, [0.02, 0.03, 0.02])
    assert list(lc.filters) == ["V", "V", "R"] and list(lc.observers) == ["Sonneberg"] * 2 + ["Ondrejov"]


def test_julian_dates_and_unix_seconds(tmp_path):
    from cssat.data import read_light_curve

    expect = np.array(["2020-04-01T00:00:00", "2020-04-01T12:00:00"], dtype="datetime64[us]")
    jd = _write(tmp_path / "jd.csv", "jd,mag\n2458940.5,9.0\n2458941.0,9.1\n")
    assert np.array_equal(read_light_curve(jd, time_col="jd", value_col="mag", time_format="jd").times_utc, expect)
    mjd = _write(tmp_path / "mjd.csv", "mjd,mag\n58940.0,9.0\n58940.5,9.1\n")
    assert np.array_equal(read_light_curve(mjd, time_col="mjd", value_col="mag", time_format="mjd").times_utc, expect)
    unix = _write(tmp_path / "unix.csv", "t,flux\n1585699200,1e-12\n1585742400,2e-12\n")
    lc = read_light_curve(unix, time_col="t", value_col="flux", kind="flux", time_format="unix")
    assert np.array_equal(lc.times_utc, expect) and lc.kind == "flux"


def test_a_written_light_curve_reads_back_exactly(tmp_path):
    from cssat.data import ObservedLightCurve, read_light_curve, write_light_curve

    rng = np.random.default_rng(1)
    t = np.datetime64("2020-04-01T20:00:00", "us") + np.sort(rng.choice(10**9, 50, replace=False)).astype("timedelta64[us]")
    lc = ObservedLightCurve(t, rng.normal(10, 0.3, 50), rng.uniform(0.01, 0.05, 50), "magnitude",
                            np.array(["V"] * 50), np.array(["A", "B"] * 25))
    write_light_curve(tmp_path / "lc.csv", lc)
    back = read_light_curve(tmp_path / "lc.csv")
    assert np.array_equal(back.times_utc, lc.times_utc) and np.array_equal(back.values, lc.values)
    assert np.array_equal(back.errors, lc.errors) and list(back.observers) == list(lc.observers)


def test_ecsv_and_fits_tables(tmp_path):
    pytest.importorskip("astropy")
    from astropy.table import Table

    from cssat.data import read_light_curve

    t = Table({"time_utc": ["2020-04-01T21:00:00", "2020-04-01T21:01:00"], "magnitude": [10.1, 10.2],
               "magnitude_err": [0.01, 0.02]})
    t.write(tmp_path / "lc.ecsv", format="ascii.ecsv")
    t.write(tmp_path / "lc.fits", format="fits")
    for name in ("lc.ecsv", "lc.fits"):
        lc = read_light_curve(tmp_path / name)
        assert np.allclose(lc.values, [10.1, 10.2]) and np.allclose(lc.errors, [0.01, 0.02]), name
        assert lc.times_utc[1] - lc.times_utc[0] == np.timedelta64(60, "s")


@pytest.mark.parametrize("text, kwargs, field, words", [
    ("time_utc,vmag\n2020-04-01T00:00:00,1\n", {}, "observations.value_col", "no column 'magnitude'; its columns: time_utc, vmag"),
    ("time_utc,magnitude\n2020-04-01T00:00:00,1\nnot-a-time,2\n", {}, "observations.time_utc[row 2]", "ISO"),
    ("time_utc,magnitude\n2020-04-01T00:00:00,1\n2020-04-01T00:00:01,nan\n", {}, "observations.magnitude[row 2]", "finite"),
    ("time_utc,magnitude\n2020-04-01T00:00:05,1\n2020-04-01T00:00:01,2\n", {}, "observations.time_utc[row 2]", "increase"),
    ("time_utc,magnitude,magnitude_err\n2020-04-01T00:00:00,1,0\n", {}, "observations.magnitude_err[row 1]", "> 0"),
    ("time_utc,magnitude\n", {}, "observations", "no data rows"),
    ("time_utc,magnitude\n2020-04-01T00:00:00\n", {}, "observations[row 1]", "1 fields, the header has 2"),
    ("time_utc,flux_W_m2\n2020-04-01T00:00:00,-1e-12\n", {"kind": "flux"}, "observations.flux_W_m2[row 1]", ">= 0"),
    ("jd,magnitude\nx,1\n", {"time_col": "jd", "time_format": "jd"}, "observations.jd[row 1]", "not a number"),
])
def test_bad_files_name_the_column_and_row(tmp_path, text, kwargs, field, words):
    from cssat.data import read_light_curve

    with pytest.raises(FieldError, match=words) as err:
        read_light_curve(_write(tmp_path / "bad.csv", text), **kwargs)
    assert err.value.field == field


def test_bad_reader_settings_name_the_setting(tmp_path):
    from cssat.data import read_light_curve

    f = _write(tmp_path / "ok.csv", "time_utc,magnitude\n2020-04-01T00:00:00,1\n")
    with pytest.raises(FieldError) as err:
        read_light_curve(f, kind="counts")
    assert err.value.field == "kind"
    with pytest.raises(FieldError) as err:
        read_light_curve(f, time_format="gps")
    assert err.value.field == "time_format"
    with pytest.raises(FieldError, match="no such file"):
        read_light_curve(tmp_path / "missing.csv")


def test_the_light_curve_experiment_runs_on_a_measured_files_stamps(tmp_path):
    """A measured curve with irregular stamps over three nights: the simulation runs on exactly
    those instants, and the residuals are the measured minus the simulated magnitudes."""
    import csv
    import json

    from cssat.data import ObservedLightCurve, write_light_curve
    from cssat.experiments import run_experiment

    rng = np.random.default_rng(2)
    t0 = np.datetime64("2020-04-01T20:00:00", "us")
    stamps = np.unique(np.concatenate([t0 + np.timedelta64(d, "D") + (rng.uniform(0, 5 * 3600e6, 20)).astype("timedelta64[us]")
                                       for d in range(3)]))
    measured = rng.normal(10.0, 0.05, len(stamps))
    write_light_curve(tmp_path / "obs.csv", ObservedLightCurve(stamps, measured, np.full(len(stamps), 0.05), "magnitude"))
    met = run_experiment(cfg_of("experiment=lightcurve", f"observations={tmp_path / 'obs.csv'}", "render.size=8",
                                "threads=1"), tmp_path / "run")
    assert met["status"] == "ok" and met["observations_n"] == len(stamps) == met["n_steps"]
    rows = list(csv.DictReader(open(tmp_path / "run" / "lightcurve.csv")))
    assert [np.datetime64(r["time_utc"].rstrip("Z"), "us") for r in rows] == list(stamps.astype("datetime64[s]").astype("datetime64[us]"))
    sim = np.array([float(r["magnitude"]) for r in rows])
    lit = np.isfinite(sim)  # April: Astra 1KR crosses the Earth's shadow near local midnight
    assert met["observations_compared"] == int(lit.sum()) > 0
    assert met["observations_rms_mag"] == pytest.approx(float(np.sqrt(np.mean((measured - sim)[lit] ** 2))), rel=1e-9)
    assert (tmp_path / "run" / "figures" / "observations.png").stat().st_size > 5000
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["observations_span_hours"] > 48


def test_a_bad_observations_file_exits_2_naming_the_row(tmp_path):
    import subprocess
    import sys

    bad = _write(tmp_path / "bad.csv", "time_utc,magnitude\n2020-04-01T00:00:00,10\n2020-04-01T00:01:00,nan\n")
    out = subprocess.run([sys.executable, "-m", "cssat.app", "experiment=lightcurve", f"observations={bad}",
                          f"hydra.run.dir={tmp_path / 'run'}", "threads=1"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 2, out.stderr[-2000:]
    text = out.stdout + out.stderr
    assert "observations.magnitude[row 2]" in text and "Traceback" not in text


def test_the_light_curve_dataset_takes_irregular_times():
    from cssat.data import LightCurves
    from cssat.optics import simulate_light_curve
    from cssat.scene import astra_like, make_scenario

    stamps = np.array(["2020-04-01T21:00:00", "2020-04-01T21:00:01.5", "2020-04-01T21:07:00", "2020-04-02T20:00:00"],
                      dtype="datetime64[us]")
    sc = make_scenario(times=stamps)
    ds = LightCurves(astra_like(), sc, length=2, seed=0)
    item = ds[1]
    assert np.allclose(item["times"].numpy(), [0.0, 1.5, 420.0, 82800.0])
    assert np.array_equal(item["clean"].numpy(), simulate_light_curve(astra_like(), sc).flux.numpy())


def cfg_of(*overrides):
    """The composed config of the command-line ``overrides`` (as the tests of the app do)."""
    from hydra import compose, initialize_config_module

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


@pytest.mark.parametrize("band", [None, "r"])
def test_magnitude_errors_become_flux_errors_by_the_derivative(tmp_path, band):
    """A magnitude's 1σ as a flux's: ``σ_F = |dF/dm| σ_m``, the derivative taken here by a central
    difference of the reader's own magnitude→flux conversion (files shifted by ±1e-6 mag); and
    back: the fluxes written with those errors read as a flux file give the magnitudes' 1σ."""
    from cssat.data import read_light_curve

    rng = np.random.default_rng(8)
    m = rng.uniform(4.0, 12.0, 20)
    s = rng.uniform(0.002, 0.2, 20)
    stamps = [f"2021-01-01T00:00:{i:02d}" for i in range(20)]

    def read(values, errors=None, kind="magnitude", name="lc.csv"):
        f = tmp_path / name
        col = "magnitude" if kind == "magnitude" else "flux_W_m2"
        rows = [f"{t},{v!r}" + ("" if errors is None else f",{e!r}") for t, v, e in zip(stamps, map(float, values),
                                                                                          map(float, s if errors is None else errors))]
        f.write_text(f"time_utc,{col}" + ("" if errors is None else f",{col}_err") + "\n" + "\n".join(rows) + "\n")
        return read_light_curve(f, kind=kind, value_col=col, error_col=None if errors is None else f"{col}_err", band=band)

    lc = read(m, s)
    h = 1e-6
    dF_dm = (read(m + h, name="hi.csv").fluxes() - read(m - h, name="lo.csv").fluxes()) / (2 * h)
    np.testing.assert_allclose(lc.flux_errors(), np.abs(dF_dm) * s, rtol=1e-6)
    back = read(lc.fluxes(), lc.flux_errors(), kind="flux", name="flux.csv")
    np.testing.assert_allclose(back.magnitude_errors(), s, rtol=1e-9)
    np.testing.assert_allclose(back.magnitudes(), m, rtol=0, atol=1e-9)


def test_a_sample_s_night_is_the_local_evening_s_date(tmp_path):
    """``nights(utc_offset_h)``: a night runs from local noon to local noon and is named by the
    date of its evening (local times worked out here for each stamp) — at UTC+10 a sample at
    11:00 UTC (21:00 local) is that day's night and one at 01:00 UTC (11:00 local, before noon)
    the previous day's; at UTC−7, 04:00 UTC (21:00 local the day before) is the previous day's
    night and 20:00 UTC (13:00 local) that day's."""
    from cssat.data import read_light_curve

    stamps = ["2021-01-01T01:00:00", "2021-01-01T11:00:00", "2021-01-02T04:00:00", "2021-01-02T20:00:00"]
    f = _write(tmp_path / "n.csv", "time_utc,magnitude\n" + "".join(f"{t},10.0\n" for t in stamps))
    lc = read_light_curve(f)
    # local: Jan 1 11:00, Jan 1 21:00, Jan 2 14:00, Jan 3 06:00
    assert list(lc.nights(10.0)) == ["2020-12-31", "2021-01-01", "2021-01-02", "2021-01-02"]
    # local: Dec 31 18:00, Jan 1 04:00, Jan 1 21:00, Jan 2 13:00
    assert list(lc.nights(-7.0)) == ["2020-12-31", "2020-12-31", "2021-01-01", "2021-01-02"]
    assert list(lc.nights(0.0)) == ["2020-12-31", "2020-12-31", "2021-01-01", "2021-01-02"]
