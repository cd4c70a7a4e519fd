"""Issue 46, point 1: every real archive file reads — the 20 real MMT-9 tracks of ../shared/real/mmt
with the defaults, a real SCORE database export (tests/data/real/SOURCES.md) — and the reader bugs
a hostile pass found. Expected values are parsed here from the files' own text (split(), the csv
module) or computed by astropy, never copied from the reader's output."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from cssat._checks import FieldError

MMT = Path(__file__).resolve().parents[2] / "shared" / "real" / "mmt"
SCORE = Path(__file__).parent / "data" / "real" / "score_hulianwang_digui01_lumos_sat.csv"
needs_mmt = pytest.mark.skipif(not (MMT / "manifest.csv").is_file(), reason="../shared/real/mmt is absent")
LABELS = {"Not variable": "nonvariable", "Aperiodic": "aperiodic", "Periodic": "periodic"}


def _manifest() -> list[dict[str, str]]:
    return list(csv.DictReader((MMT / "manifest.csv").open())) if (MMT / "manifest.csv").is_file() else []


def _data_lines(text: str) -> list[list[str]]:
    return [ln.split() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]


def _read(tmp_path, name, text, **kw):
    from cssat.data import read_light_curve

    f = tmp_path / name
    f.write_text(text)
    return read_light_curve(f, **kw)


def _field(fn, *a, **kw) -> FieldError:
    with pytest.raises(FieldError) as err:
        fn(*a, **kw)
    assert "\n" not in str(err.value)  # one line
    return err.value


@needs_mmt
@pytest.mark.parametrize("entry", _manifest(), ids=lambda e: e["file"])
def test_every_real_mmt_track_reads_with_the_defaults(entry):
    """Each of the 20 files: its rows, its track, MMT's label and period as the manifest gives
    them (no period for Not-variable tracks, whose header writes 0.0), times, magnitudes,
    channels and penumbra flags as the file's own lines say."""
    from cssat.data import read_light_curve

    path = MMT / entry["file"]
    lines = _data_lines(path.read_text())
    lc = read_light_curve(path)
    assert len(lc) == int(entry["n_rows"]) == len(lines)
    assert lc.meta["object_id"] == entry["norad"] and set(lc.tracks) == {entry["track"]}
    assert lc.meta["variability"] == LABELS[entry["variability_label"]]
    if entry["period_s"]:
        assert lc.meta["published_period_s"] == float(entry["period_s"])
    else:
        assert lc.meta.get("published_period_s") is None
    stamps = np.array([f"{d}T{t}" for d, t, *_ in lines], dtype="datetime64[us]")
    order = np.argsort(stamps, kind="stable")
    assert np.array_equal(lc.times_utc, stamps[order])
    assert np.array_equal(lc.values, np.array([float(r[3]) for r in lines])[order])  # Mag, the 4th field
    assert np.array_equal(lc.ranges_km, np.array([float(r[6]) for r in lines])[order])
    assert sorted(set(lc.channels)) == sorted({r[8] for r in lines})
    assert int(lc.penumbra.sum()) == sum(r[5] == "1" for r in lines)
    for ch in set(lc.channels):  # each channel's own stamps increase
        assert (np.diff(lc.times_utc[lc.channels == ch]).astype(np.int64) > 0).all()


@needs_mmt
def test_penumbra_and_three_channels_as_the_readme_counts():
    from cssat.data import read_light_curve

    assert int(read_light_curve(MMT / "25502_13047273.txt").penumbra.sum()) == 297  # README: 297 rows flagged
    assert set(read_light_curve(MMT / "25502_13108570_mid.txt").channels) == {"6", "2", "5"}


@needs_mmt
@pytest.mark.parametrize("value", ["0.0", "0", "None", ""])
def test_no_period_written_any_way_is_no_period(tmp_path, value):
    text = (MMT / "1616_10297354.txt").read_text().replace("# variability_period: 0.0", f"# variability_period: {value}")
    lc = _read(tmp_path, "np.txt", text)
    assert lc.meta.get("published_period_s") is None and lc.meta["variability"] == "nonvariable" and len(lc) == 321


@needs_mmt
def test_channels_that_share_a_stamp_are_kept_and_one_channel_s_duplicate_is_named(tmp_path):
    """Two channels may write the same stamp: both samples are kept with the defaults. Within one
    channel an exact repeat of a line is dropped; a second value at a stamp is refused naming
    the row and the channel."""
    text = (MMT / "23947_4199024.txt").read_text()
    lines = text.splitlines()
    data = [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")]
    ch = {i: lines[i].split()[8] for i in data}
    i3 = next(i for i in data if ch[i] == "3" and ch.get(i + 1) == "6")  # a channel-3 line then a channel-6 one
    f = lines[i3 + 1].split()
    f[1] = lines[i3].split()[1]  # the channel-6 sample at the channel-3 stamp
    shared = lines[:i3 + 1] + [" ".join(f)] + lines[i3 + 2:]
    lc = _read(tmp_path, "shared.txt", "\n".join(shared) + "\n")
    assert len(lc) == 237
    t = np.datetime64(f"{f[0]}T{f[1]}", "us")
    assert sorted(lc.channels[lc.times_utc == t]) == ["3", "6"]
    repeat = lines[:i3 + 1] + [lines[i3]] + lines[i3 + 1:]
    lc = _read(tmp_path, "repeat.txt", "\n".join(repeat) + "\n")
    assert len(lc) == 237 and lc.meta["duplicates_dropped"] == 1
    g = lines[i3].split()
    g[3] = "9.99"
    second = lines[:i3 + 1] + [" ".join(g)] + lines[i3 + 1:]
    row = sum(1 for i in data if i <= i3) + 1
    err = _field(_read, tmp_path, "second.txt", "\n".join(second) + "\n")
    assert err.field.endswith(f"[row {row}]") and "channel 3" in str(err) and "duplicate" in str(err)
    merged = _read(tmp_path, "second.txt", "\n".join(second) + "\n", duplicates="merge")
    assert len(merged) == 237 and np.isclose(merged.values[merged.times_utc == np.datetime64(f"{g[0]}T{g[1]}")][0],
                                             (float(g[3]) + float(lines[i3].split()[3])) / 2)


@needs_mmt
def test_concatenated_exports_of_two_objects_are_refused_or_one_is_picked(tmp_path):
    """Hostile pass: two objects' exports in one file became one object (the last header kept)."""
    a, b = (MMT / "59344_30093088.txt").read_text(), (MMT / "1616_10297354.txt").read_text()
    err = _field(_read, tmp_path, "two.txt", a + b)
    assert err.field == "observations.object" and "59344 CZ-6A R/B" in str(err) and "1616 ATLAS D R/B" in str(err)
    one = _read(tmp_path, "two.txt", a + b, object=1616)
    assert len(one) == 321 and one.meta["object_id"] == "1616" and one.meta.get("published_period_s") is None
    other = _read(tmp_path, "two.txt", a + b, object="CZ-6A R/B")
    assert len(other) == 529 and other.meta["published_period_s"] == 14.5319174


@needs_mmt
def test_each_block_keeps_its_own_track_and_period(tmp_path):
    """Hostile pass: per-block '# track:' lines merged three nights into one track."""
    files = ["1863_10198570.txt", "1863_25465546.txt", "1863_30225046.txt"]
    texts = [(MMT / f).read_text() for f in files]
    lc = _read(tmp_path, "three.txt", "".join(texts))
    ids = {f.split("_")[1].split(".")[0]: len(_data_lines(t)) for f, t in zip(files, texts)}
    assert {k: int((lc.tracks == k).sum()) for k in ids} == ids and len(lc.split()) == 3
    assert lc.meta.get("published_period_s") is None  # three passes, three of MMT's periods
    assert lc.meta["published_periods_s"] == {"10198570": 1.4973012, "25465546": 1.60256096, "30225046": 1.616598324}


@needs_mmt
def test_a_second_column_line_applies_to_its_own_block(tmp_path):
    """Hostile pass: the last '# Date Time ...' line was applied to every row. A block whose
    column line swaps StdMag and Mag is read by its own line; one that names other columns is
    refused naming its line."""
    lines = (MMT / "1616_10297354.txt").read_text().splitlines()
    head, rows = lines[:8], lines[8:18]
    swapped = [" ".join([f[0], f[1], f[3], f[2], *f[4:]]) for f in (r.split() for r in rows[5:])]
    text = "\n".join(head + rows[:5] + ["# track: 999", "# Date Time Mag StdMag Filter Penumbra Distance Phase Channel"]
                     + swapped) + "\n"
    lc = _read(tmp_path, "cols.txt", text)
    assert np.array_equal(lc.values, [float(r.split()[3]) for r in rows])  # every row's own Mag
    assert list(lc.tracks) == ["10297354"] * 5 + ["999"] * 5
    other = "\n".join(head + rows[:5] + ["# Date Time Mag Filter Channel"] + [" ".join(r.split()[i] for i in (0, 1, 3, 4, 8))
                                                                             for r in rows[5:]]) + "\n"
    err = _field(_read, tmp_path, "other.txt", other)
    assert err.field == "observations[line 14]" and "column line" in str(err)


def _score_rows() -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(SCORE.open()))
    return rows[0], rows[1:]


def _score_text(header: list[str], rows: list[list[str]]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows([header] + rows)
    return buf.getvalue()


def test_a_real_score_export_reads_with_satchecker_s_range_where_the_observer_gave_none():
    """Every row writes range_to_satellite_km = 0.0 (none measured): the range is SatChecker's,
    and meta says so; the phase angle is SatChecker's; the site, magnitude and error each row's."""
    from cssat.data import read_light_curve

    header, rows = _score_rows()
    col = {c: [float(r[header.index(c)]) for r in rows] for c in ("range_to_satellite_km", "range_to_sat_km_satchecker",
           "phase_angle_deg_satchecker", "apparent_magnitude", "apparent_magnitude_uncertainty",
           "observer_latitude_deg", "observer_longitude_deg", "observer_altitude_m")}
    assert set(col["range_to_satellite_km"]) == {0.0}
    lc = read_light_curve(SCORE)
    assert len(lc) == len(rows) == 29 and lc.meta["object_id"] == "62323"
    assert np.array_equal(lc.ranges_km, col["range_to_sat_km_satchecker"]) and lc.meta["range_source"] == "satchecker"
    assert np.array_equal(lc.phase_deg, col["phase_angle_deg_satchecker"]) and lc.meta["phase_source"] == "satchecker"
    assert np.array_equal(lc.values, col["apparent_magnitude"]) and np.array_equal(lc.errors, col["apparent_magnitude_uncertainty"])
    assert np.array_equal(lc.sites, np.stack([col["observer_latitude_deg"], col["observer_longitude_deg"],
                                              col["observer_altitude_m"]], 1))
    same = read_light_curve(SCORE, time_col="observation_time_utc", value_col="apparent_magnitude",
                            error_col="apparent_magnitude_uncertainty")  # options that agree with the format
    assert np.array_equal(same.values, lc.values)


def test_score_ranges_mixed_negative_and_missing(tmp_path):
    header, rows = _score_rows()
    rc, sc = header.index("range_to_satellite_km"), header.index("range_to_sat_km_satchecker")
    mixed = [list(r) for r in rows]
    mixed[2][rc] = "1600.5"
    lc = _read(tmp_path, "mixed.csv", _score_text(header, mixed))
    assert lc.meta["range_source"] == "mixed" and lc.meta["range_satchecker_rows"] == [i + 1 for i in range(29) if i != 2]
    assert lc.ranges_km[2] == 1600.5 and lc.ranges_km[3] == float(rows[3][sc])  # the file is in time order
    neg = [list(r) for r in rows]
    neg[4][rc] = "-5"
    err = _field(_read, tmp_path, "neg.csv", _score_text(header, neg))
    assert err.field == "observations.range_to_satellite_km[row 5]" and "-5" in str(err)
    keep = [j for j, c in enumerate(header) if not c.endswith("_satchecker")]  # an upload: no SatChecker columns
    up = [[r[j] for j in keep] for r in rows]
    h = [header[j] for j in keep]
    for r in up:
        r[h.index("range_to_satellite_km")] = "1500"
    up[1][h.index("range_to_satellite_km")] = ""
    err = _field(_read, tmp_path, "up.csv", _score_text(h, up))
    assert err.field == "observations.range_to_satellite_km[row 2]" and "range_to_sat_km_satchecker" in str(err)
    for r in up:  # no range anywhere: none, not an error
        r[h.index("range_to_satellite_km")] = "0.0"
    assert _read(tmp_path, "up.csv", _score_text(h, up)).ranges_km is None
    zero_err = [list(r) for r in rows]
    zero_err[0][header.index("apparent_magnitude_uncertainty")] = "0.0"  # a placeholder: unknown
    lc = _read(tmp_path, "zero.csv", _score_text(header, zero_err))
    assert lc.errors is None and "errors_note" in lc.meta


@needs_mmt
def test_options_that_contradict_a_fixed_format_are_named_with_the_allowed_values():
    from cssat.data import read_light_curve

    err = _field(read_light_curve, SCORE, value_col="x")
    assert err.field == "observations.value_col" and "'apparent_magnitude'" in str(err)
    err = _field(read_light_curve, MMT / "150_12326488.txt", kind="flux")
    assert err.field == "observations.kind" and "'magnitude'" in str(err)
    err = _field(read_light_curve, MMT / "150_12326488.txt", value_col="Distance")
    assert err.field == "observations.value_col" and "'Mag', 'StdMag'" in str(err)
    lc = read_light_curve(MMT / "150_12326488.txt", value_col="StdMag", time_col=["Date", "Time"], kind="magnitude")
    assert lc.values[0] == float(_data_lines((MMT / "150_12326488.txt").read_text())[0][2])


def test_a_flux_in_jansky_is_the_magnitude_astropy_gives(tmp_path):
    """Hostile pass: a V = 8 curve in Jy read as V = -19.8. In AB the magnitude is astropy's
    ABmag of the flux; in Vega V it differs by V's Vega-AB offset only (< 0.05 mag)."""
    from astropy.table import QTable, Table
    from astropy.time import Time
    import astropy.units as u

    from cssat.data import read_light_curve

    mags = np.linspace(7.5, 8.5, 20)
    t = Time("2020-04-01T21:00:00") + np.arange(20) * u.s
    q = QTable({"time": t, "flux": (mags * u.ABmag).to(u.Jy), "flux_err": np.full(20, 1e-5) * u.Jy})
    ab = read_light_curve(q, kind="flux", band="V", band_system="AB")
    assert ab.kind == "magnitude" and np.allclose(ab.values, mags, atol=1e-9)
    fj = (mags * u.ABmag).to_value(u.Jy)
    assert np.allclose(ab.errors, 2.5 / np.log(10) * 1e-5 / fj)
    Table(q).write(tmp_path / "jy.ecsv", format="ascii.ecsv")
    vega = read_light_curve(tmp_path / "jy.ecsv", kind="flux")
    assert np.abs(vega.values - mags).max() < 0.05 and "Jy" in vega.meta["converted_from"]
    flam = QTable({"time": t, "flux": np.ones(20) * u.erg / u.s / u.cm ** 2 / u.AA})
    assert _field(read_light_curve, flam, kind="flux").field == "observations.flux"


@pytest.mark.parametrize("text, kwargs, field, words", [
    ("time_utc,magnitude\n2020-01-01T00:00:00,1.2e-12\n2020-01-01T00:00:01,1.5e-12\n", {}, "observations.kind", "fluxes"),
    ("time_utc,flux_W_m2\n2020-01-01T00:00:00,-1.2\n2020-01-01T00:00:01,3.4\n", {"kind": "flux"},
     "observations.flux_W_m2[row 1]", "look like magnitudes"),
    ("time_utc,counts\n2020-01-01T00:00:00,15000\n", {"value_col": "counts"}, "observations.counts[row 1]", "kind='flux'"),
])
def test_a_flux_in_a_magnitude_column_and_the_reverse_are_refused(tmp_path, text, kwargs, field, words):
    err = _field(_read, tmp_path, "k.csv", text, **kwargs)
    assert err.field == field and words in str(err)


def test_a_table_s_column_name_and_kind_must_agree():
    from astropy.table import Table
    from astropy.time import Time
    import astropy.units as u

    from cssat.data import read_light_curve

    t = Time("2020-04-01T21:00:00") + np.arange(5) * u.s
    assert _field(read_light_curve, Table({"time": t, "flux": np.full(5, 2e-12)}), value_col="flux").field == "observations.kind"
    assert _field(read_light_curve, Table({"time": t, "mag": np.full(5, 9.0)}), value_col="mag",
                  kind="flux").field == "observations.kind"


def test_time_scale_and_time_format_are_honoured_for_tables(tmp_path):
    """Hostile pass: observed.time_scale was ignored for ECSV and astropy tables, and a jd
    column with time_format=jd was refused as 'not an ISO date-time'. 2020: TT - UTC = 69.184 s."""
    from astropy.table import Table
    from astropy.time import Time
    import astropy.units as u

    from cssat.data import read_light_curve

    utc = np.datetime64("2020-04-01T21:00:00", "us")
    iso = Table({"time": ["2020-04-01T21:00:00", "2020-04-01T21:00:10"], "mag": [9.0, 9.1]})
    assert read_light_curve(iso, time_scale="tt").times_utc[0] == utc - np.timedelta64(69184, "ms")
    assert read_light_curve(iso).times_utc[0] == utc
    jd = Table({"jd": [2458941.375, 2458941.5], "mag": [9.0, 9.1]})  # 2020-04-01 21:00 and 2020-04-02 00:00 UTC
    jd.write(tmp_path / "jd.ecsv", format="ascii.ecsv")
    jd.write(tmp_path / "jd.fits", format="fits")
    for f in ("jd.ecsv", "jd.fits"):
        assert read_light_curve(tmp_path / f, time_col="jd", time_format="jd").times_utc[0] == utc, f
        assert read_light_curve(tmp_path / f).times_utc[0] == utc, f  # a column named jd, found and read as JD
    tt = Table({"time": Time("2020-04-01T21:00:00", scale="tt") + np.arange(3) * u.s, "mag": [9.0, 9.1, 9.2]})
    assert read_light_curve(tt, time_scale="tt").times_utc[0] == utc - np.timedelta64(69184, "ms")
    assert _field(read_light_curve, tt, time_scale="tdb").field == "observations.time_scale"


def test_a_commented_header_and_common_column_names(tmp_path):
    """A CSV whose first line is a '#' comment takes its header from the last '#' line (even when
    a data row has a text field); jd/mjd/mag/err columns are found without being named."""
    lc = _read(tmp_path, "c.csv", "# jd,mag,err,filter\n2458941.375,9.0,0.1,V\n2458941.5,9.2,0.2,V\n")
    assert lc.times_utc[0] == np.datetime64("2020-04-01T21:00:00") and list(lc.values) == [9.0, 9.2]
    assert list(lc.errors) == [0.1, 0.2] and list(lc.filters) == ["V", "V"]
    ws = _read(tmp_path, "w.txt", "# an export\n# MJD Mag Err\n58940.875 9.0 0.1\n58941.0 9.1 0.1\n")
    assert ws.times_utc[1] == np.datetime64("2020-04-02T00:00:00") and ws.meta["time_format"] == "mjd"
