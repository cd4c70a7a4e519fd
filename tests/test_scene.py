"""Scene layer: TLE checks, the paper's default geometry, Earth shadow, attitude, meshes."""

from pathlib import Path

import numpy as np
import pytest

from cssat.scene import (
    ASTRA_1KR_SYNTHETIC_TLE,
    astra_like,
    box,
    check_tle,
    dish,
    earth_shadow_fraction,
    load_mesh,
    make_scenario,
    nadir_pointing_frame,
    tess_like,
)

TESS_OBJ = Path(__file__).resolve().parents[2] / "shared" / "models" / "tess.obj"


def with_checksum(line: str) -> str:
    s = sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68]) % 10
    return line[:68] + str(s)


def test_tle_checks_name_the_line():
    l1, l2 = ASTRA_1KR_SYNTHETIC_TLE
    check_tle(l1, l2)
    bad = l1[:68] + str((int(l1[68]) + 1) % 10)
    with pytest.raises(ValueError, match=r"tle.line1: checksum"):
        check_tle(bad, l2)
    with pytest.raises(ValueError, match=r"tle.line2: a TLE line has 69 columns"):
        check_tle(l1, l2[:60])
    with pytest.raises(ValueError, match=r"tle.line2: must start with '2 '"):
        check_tle(l1, with_checksum("3" + l2[1:]))
    with pytest.raises(ValueError, match="catalogue numbers differ"):
        check_tle(l1, with_checksum(l2[:2] + "29056" + l2[7:]))


@pytest.fixture(scope="module")
def paper():
    return make_scenario()


def test_default_scenario_geometry_matches_the_design_notes(paper):
    assert len(paper) == 1437
    assert paper.times[0] == np.datetime64("2020-04-01T00:00:00")
    assert paper.times[-1] == np.datetime64("2020-04-01T23:56:00")
    # seen from 51.17 N 10.45 E the satellite stays near az 168.8, el 30.9, range ~38,500 km
    assert np.all(np.abs(paper.azimuth_deg - 168.8) < 0.5)
    assert np.all(np.abs(paper.elevation_deg - 30.9) < 0.5)
    assert np.all(np.abs(paper.range_km - 38_500) < 300)
    # geostationary: |r| ~ 42,164 km
    assert np.all(np.abs(np.linalg.norm(paper.r_sat, axis=1) - 42_164) < 100)


def test_default_scenario_eclipse_is_about_22_17_to_23_16(paper):
    shadow = paper.sunlit < 1.0
    idx = np.flatnonzero(shadow)
    assert idx.size > 0 and np.all(np.diff(idx) == 1)  # one contiguous eclipse
    start = paper.times[idx[0]].astype("datetime64[m]")
    end = paper.times[idx[-1]].astype("datetime64[m]")
    assert abs((start - np.datetime64("2020-04-01T22:17")).astype(int)) <= 3
    assert abs((end - np.datetime64("2020-04-01T23:16")).astype(int)) <= 3
    assert paper.sunlit.min() == 0.0  # a total eclipse (umbra) in the middle
    assert np.all(paper.sunlit[: idx[0]] == 1.0)


def test_shadow_fraction_against_hand_geometry():
    au = 1.496e8
    sun = np.array([[au, 0, 0]] * 5)
    geo = 42_164.0
    sat = np.array([[geo, 0, 0], [-geo, 0, 0], [0, geo, 0], [-geo, 6000, 0], [-geo, 6378.137, 0]])
    f = earth_shadow_fraction(sat, sun)
    assert f[0] == 1 and f[2] == 1  # sunward and quadrature
    assert f[1] == 0  # straight behind the Earth: umbra
    assert f[3] == 0  # still inside the umbra (Earth's disk 8.7°, Sun's 0.27°)
    assert 0 < f[4] < 1  # the shadow edge: penumbra
    # penumbra brightens monotonically as the satellite moves out of the shadow
    ys = np.linspace(6000, 6800, 50)
    fr = earth_shadow_fraction(np.stack([np.full(50, -geo), ys, np.zeros(50)], 1), np.tile([au, 0, 0], (50, 1)))
    assert np.all(np.diff(fr) >= 0) and fr[0] == 0 and fr[-1] == 1


def test_nadir_frame_is_a_rotation_with_the_papers_axes(paper):
    R = nadir_pointing_frame(paper.r_sat, paper.v_sat)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    rhat = paper.r_sat / np.linalg.norm(paper.r_sat, axis=1, keepdims=True)
    np.testing.assert_allclose(R[:, 2], -rhat, atol=1e-12)  # +z to the geocentre
    h = np.cross(paper.r_sat, paper.v_sat)
    np.testing.assert_allclose(np.einsum("ti,ti->t", R[:, 1], h / np.linalg.norm(h, axis=1, keepdims=True)), -1, atol=1e-12)


def test_box_and_dish_geometry():
    b = box((2.0, 3.0, 4.0), divisions=3)
    assert len(b) == 6 * 9 * 2
    assert b.areas.sum() == pytest.approx(2 * (6 + 8 + 12))
    assert np.all(np.einsum("fi,fi->f", b.centroids, b.normals) > 0)  # outward
    d = dish(1.0, 0.25, center=(0, 0, 0), axis=(0, 0, 1), rings=40, segments=128, two_sided=False)
    # paraboloid z = r²/4 (focal length 1): area = (π/6)(1/a²)((1+4a²)^1.5 - 1) with a = 1/4
    a = 0.25
    exact = np.pi / (6 * a * a) * ((1 + 4 * a * a) ** 1.5 - 1)
    assert d.areas.sum() == pytest.approx(exact, rel=2e-3)
    assert np.all(d.normals[:, 2] > 0)  # concave side faces the axis


def test_procedural_models():
    a = astra_like(material="uniform")  # the paper's single material (the default dresses the parts: test_materials)
    assert len(a) == 4028
    assert np.all(a.cd == 0.8) and np.all(a.cs == 0.2)
    assert 10 < a.radius < 15 and np.all(a.areas > 0)
    t = tess_like(cd=0.5, cs=0.1)
    assert np.all(t.cd == 0.5) and 1.5 < t.radius < 3.5


def test_load_mesh_files_and_errors(tmp_path, caplog):
    b = box((1.0, 2.0, 3.0), divisions=2)
    for ext in ("obj", "stl", "ply"):
        p = tmp_path / f"b.{ext}"
        b.to_trimesh().export(p)
        m = load_mesh(p)
        assert len(m) == len(b)
        assert m.areas.sum() == pytest.approx(b.areas.sum())
    m = load_mesh(tmp_path / "b.obj", scale=0.001)  # millimetres
    assert m.areas.sum() == pytest.approx(b.areas.sum() * 1e-6)
    with pytest.raises(ValueError, match="^path: no such file"):
        load_mesh(tmp_path / "missing.obj")
    (tmp_path / "empty.obj").write_text("# nothing\n")
    with pytest.raises(ValueError, match="^path: .*(no triangles|cannot read)"):
        load_mesh(tmp_path / "empty.obj")
    (tmp_path / "some.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")
    with caplog.at_level("WARNING", logger="cssat"):
        some = load_mesh(tmp_path / "some.obj")
    assert len(some) == 1 and "dropped 1 zero-area" in caplog.text
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="^path: every facet .* degenerate"):
        load_mesh(tmp_path / "flat.obj")
    with pytest.raises(ValueError, match="^scale: must be a positive"):
        load_mesh(tmp_path / "b.obj", scale=0)


@pytest.mark.skipif(not TESS_OBJ.exists(), reason="../shared/models/tess.obj not present")
def test_real_tess_mesh_loads():
    m = load_mesh(TESS_OBJ)
    assert len(m) > 15_000
    assert np.all(m.areas > 0)


def test_sgp4_error_codes_are_reported():
    # an ISS-like orbit propagated far past its decay
    l1 = "1 25544U 98067A   20092.00000000  .00016717  00000-0  10270-2 0  9997"
    l2 = "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391 56354"
    make_scenario((l1, l2), start_utc="2020-04-01T00:00:00", n_steps=3)  # fine at epoch
    with pytest.raises(ValueError, match=r"tle: SGP4 error 6 \(.*decayed\) at step 0"):
        make_scenario((l1, l2), start_utc="2021-01-26T00:00:00", n_steps=3)  # 300 days on
    with pytest.raises(ValueError, match=r"tle: SGP4 error 1 \(mean eccentricity"):
        make_scenario((l1, l2), start_utc="2022-12-27T00:00:00", n_steps=3)


def test_scenario_arguments_are_checked():
    with pytest.raises(ValueError, match="scenario.n_steps"):
        make_scenario(n_steps=0)
    with pytest.raises(ValueError, match="scenario.start_utc"):
        make_scenario(start_utc="April 1st")
    with pytest.raises(ValueError, match="observer.lat_deg"):
        make_scenario(lat_deg=91.0, n_steps=2)


# --- what users hold: satellites and start times in their libraries' forms (issue 14) ---------

def _tle_as_omm(line1: str, line2: str) -> dict:
    """An OMM/GP record of a TLE, read off its columns by hand (the TLE format's definition)."""
    yy, day = int(line1[18:20]), float(line1[20:32])
    from datetime import datetime, timedelta

    epoch = datetime(2000 + yy if yy < 57 else 1900 + yy, 1, 1) + timedelta(days=day - 1)

    def exp_field(f):  # " 12345-3" → 0.12345e-3
        f = f.strip()
        return float(f"{f[0] if f[0] in '+-' else ''}0.{f.lstrip('+-')[:-2]}e{f[-2:]}")

    return {"OBJECT_NAME": "ASTRA 1KR", "NORAD_CAT_ID": int(line1[2:7]), "EPOCH": epoch.isoformat(),
            "MEAN_MOTION": float(line2[52:63]), "ECCENTRICITY": float("0." + line2[26:33]),
            "INCLINATION": float(line2[8:16]), "RA_OF_ASC_NODE": float(line2[17:25]),
            "ARG_OF_PERICENTER": float(line2[34:42]), "MEAN_ANOMALY": float(line2[43:51]),
            "MEAN_MOTION_DOT": float(line1[33:43]), "MEAN_MOTION_DDOT": exp_field(line1[44:52]),
            "BSTAR": exp_field(line1[53:61])}


def test_every_satellite_form_gives_the_same_orbit():
    from sgp4.api import Satrec
    from skyfield.api import EarthSatellite, load

    l1, l2 = ASTRA_1KR_SYNTHETIC_TLE
    ref = make_scenario(n_steps=30, step_s=600.0)
    forms = {
        "3 lines": ("ASTRA 1KR", l1, l2),
        "3LE text": f"0 ASTRA 1KR\n{l1}\n{l2}\n",
        "2-line text": f"{l1}\n{l2}",
        "EarthSatellite": EarthSatellite(l1, l2, "ASTRA 1KR", load.timescale(builtin=True)),
        "Satrec": Satrec.twoline2rv(l1, l2),
        "OMM": _tle_as_omm(l1, l2),
    }
    for what, sat in forms.items():
        sc = make_scenario(sat, n_steps=30, step_s=600.0)
        np.testing.assert_allclose(sc.r_sat, ref.r_sat, atol=1e-3, rtol=0, err_msg=what)  # 1 m
        np.testing.assert_array_equal(sc.times, ref.times)
        assert sc.name == ("NORAD 29055" if what in ("Satrec", "2-line text") else "ASTRA 1KR"), what
    assert ref.name == "Astra 1KR (synthetic TLE)"
    with pytest.raises(ValueError, match="scenario.tle: an OMM/GP record needs .*missing MEAN_MOTION"):
        make_scenario({k: v for k, v in forms["OMM"].items() if k != "MEAN_MOTION"}, n_steps=2)
    with pytest.raises(ValueError, match="scenario.tle.line1: checksum"):
        make_scenario(("X", l1[:68] + "0", l2), n_steps=2)
    with pytest.raises(TypeError, match="scenario.tle: expected two TLE lines .* an sgp4 Satrec"):
        make_scenario(42, n_steps=2)
    with pytest.raises(ValueError, match="scenario.tle: a TLE has 2 lines, or 3"):
        make_scenario(l1, n_steps=2)


def test_every_start_time_form_gives_the_same_times():
    from datetime import datetime, timedelta, timezone

    from skyfield.api import load

    ref = make_scenario(n_steps=3, step_s=60.0, start_utc="2020-04-01T06:30:00")
    cet = timezone(timedelta(hours=1))
    ts = load.timescale(builtin=True)
    for start in (datetime(2020, 4, 1, 6, 30), datetime(2020, 4, 1, 7, 30, tzinfo=cet),
                  np.datetime64("2020-04-01T06:30"), ts.utc(2020, 4, 1, 6, 30), "2020-04-01T06:30:00Z"):
        sc = make_scenario(n_steps=3, step_s=60.0, start_utc=start)
        np.testing.assert_array_equal(sc.times, ref.times, err_msg=repr(start))
        np.testing.assert_allclose(sc.r_sat, ref.r_sat, atol=1e-6, rtol=0)
    with pytest.raises(TypeError, match="scenario.start_utc: expected an ISO string, a datetime"):
        make_scenario(n_steps=2, start_utc=1585699200)
    with pytest.raises(ValueError, match="scenario.start_utc: expected one time"):
        make_scenario(n_steps=2, start_utc=ts.utc(2020, 4, 1, [0, 1]))


def test_the_lightcurve_config_takes_three_lines_and_omm_records():
    from hydra import compose, initialize_config_module

    from cssat.experiments.scene import build_scenario

    l1, l2 = ASTRA_1KR_SYNTHETIC_TLE
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        three = compose(config_name="config", overrides=["experiment=lightcurve", "scenario.n_steps=3",
                                                         f"scenario.tle=['ASTRA 1KR','{l1}','{l2}']"])
        omm = compose(config_name="config", overrides=["experiment=lightcurve", "scenario.n_steps=3"])
    omm.scenario.tle = _tle_as_omm(l1, l2)
    a, b = build_scenario(three), build_scenario(omm)
    assert a.name == b.name == "ASTRA 1KR"
    np.testing.assert_allclose(a.r_sat, b.r_sat, atol=1e-3, rtol=0)
