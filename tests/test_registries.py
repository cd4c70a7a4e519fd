"""The registries of light-curve formats and period methods: a format and a method added from a
brand-new module in a temporary package and run end to end; unknown names refused naming the
field and the registered names."""

from __future__ import annotations

import importlib
import sys
import textwrap

import numpy as np
import pytest

from cssat._checks import FieldError

FORMAT_MODULE = '''
"""A made-up survey's format: a '# tinysurvey' first line, then 'mjd;mag;err' rows."""
from pathlib import Path

import numpy as np

from cssat.data import register_format
from cssat.data.formats import to_utc


def identify(path, first_lines):
    return bool(first_lines) and first_lines[0].startswith("# tinysurvey")


def read(path, **options):
    rows = [ln.split(";") for ln in Path(path).read_text().splitlines()[1:] if ln.strip()]
    mjd, mag, err = (np.array([float(r[k]) for r in rows]) for k in range(3))
    return {"times_utc": to_utc(mjd, "mjd", "utc", "observations.mjd"), "values": mag, "errors": err,
            "kind": "magnitude", "meta": {"format": "tinysurvey", "object_id": "99999"}}


register_format("tinysurvey", identify, read, extensions=("tiny",), overwrite=True)
'''

METHOD_MODULE = '''
"""A made-up period method: the period of the highest power of a 1-term least-squares
periodogram on a fixed grid (a brute-force loop)."""
import numpy as np

from cssat.inversion import register_period_method


def bruteforce(times_s, flux, *, sigma=None, segments=None, zero_points=None, convention="photometric",
               min_period_s=None, max_period_s=None, periods=None):
    t, y = np.asarray(times_s, float), np.asarray(flux, float)
    grid = np.asarray(periods if periods is not None else np.linspace(50.0, 400.0, 3501))
    rss = []
    for p in grid:
        X = np.stack([np.ones_like(t), np.cos(2 * np.pi * t / p), np.sin(2 * np.pi * t / p)], 1)
        c, *_ = np.linalg.lstsq(X, y, rcond=None)
        rss.append(float(np.sum((y - X @ c) ** 2)))
    p = float(grid[int(np.argmin(rss))])
    return {"period_s": p, "period_err_s": float("nan"), "verdict": "periodic", "periodic": True,
            "verdict_why": "the brute-force fit's best period", "alternatives": [], "warnings": [],
            "best_period_s": p, "model_fits": True, "chi2_per_sample": 1.0, "fap": 0.0, "repeat": 1.0}


register_period_method("bruteforce", bruteforce, overwrite=True)
'''


@pytest.fixture
def plugin_package(tmp_path, monkeypatch):
    """A package ``cssat_plugins_test`` in ``tmp_path`` (on sys.path) with the two modules."""
    pkg = tmp_path / "cssat_plugins_test"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "tinysurvey.py").write_text(textwrap.dedent(FORMAT_MODULE))
    (pkg / "bruteforce.py").write_text(textwrap.dedent(METHOD_MODULE))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield pkg
    from cssat.data.registry import _FORMATS
    from cssat.inversion.period_methods import _METHODS

    _FORMATS.pop("tinysurvey", None)
    _METHODS.pop("bruteforce", None)
    for mod in [m for m in sys.modules if m.startswith("cssat_plugins_test")]:
        del sys.modules[mod]


def _write_tiny(path, mjd, mag):
    path.write_text("# tinysurvey v1\n" + "".join(f"{float(a)!r};{float(b)!r};0.05\n" for a, b in zip(mjd, mag)))


def test_a_new_format_is_one_module_read_end_to_end(plugin_package, tmp_path):
    from cssat.data import read_light_curve, registered_formats

    importlib.import_module("cssat_plugins_test.tinysurvey")
    assert "tinysurvey" in registered_formats()
    mjd = 60000.0 + np.arange(50) * 30.0 / 86400.0
    mag = 8.0 + 0.2 * np.sin(2 * np.pi * np.arange(50) / 17.0)
    f = tmp_path / "track.dat"  # identified by its first line (the suffix is no one's)
    _write_tiny(f, mjd, mag)
    lc = read_light_curve(f)
    assert lc.meta["format"] == "tinysurvey" and lc.kind == "magnitude"
    np.testing.assert_allclose(lc.values, mag)
    # the stamps: 30 s apart from MJD 60000 = 2023-02-25T00:00 UTC (an independent calendar sum)
    np.testing.assert_allclose(lc.times_s(), np.arange(50) * 30.0, atol=2e-6)
    assert str(lc.times_utc[0]) == "2023-02-25T00:00:00.000000"
    # the shared checks apply to a new format too: a magnitude placeholder is refused naming its row
    bad = mag.copy()
    bad[7] = 99.999
    _write_tiny(f, mjd, bad)
    with pytest.raises(FieldError, match=r"row 8"):
        read_light_curve(f)
    # by its extension alone, and by name
    g = tmp_path / "other.tiny"
    g.write_text("# tinysurvey\n" + f.read_text().split("\n", 1)[1].replace("99.999", "8.0"))
    assert read_light_curve(g).meta["format"] == "tinysurvey"
    assert read_light_curve(g, format="tinysurvey").meta["object_id"] == "99999"
    # the object check every format gets: the file names 99999
    with pytest.raises(FieldError, match=r"observations.object"):
        read_light_curve(g, object="12345")


def test_unknown_format_names_the_field_and_the_formats(tmp_path):
    from cssat.data import read_light_curve, registered_formats

    f = tmp_path / "x.csv"
    f.write_text("time_utc,magnitude\n2020-01-01T00:00:00,8.0\n")
    with pytest.raises(FieldError) as err:
        read_light_curve(f, format="nosuchformat")
    assert err.value.field == "format"
    for name in ("csv", "mmt", "score", "alcdef", "ecsv", "fits", "astropy"):
        assert name in err.value.detail
    assert set(registered_formats()) >= {"csv", "mmt", "score", "alcdef", "ecsv", "fits", "astropy"}


def test_ambiguous_and_unidentified_files_are_refused_naming_format(tmp_path):
    from cssat.data import read_light_curve, register_format, unregister_format
    from cssat.data.registry import _FORMATS, identify_format

    def read(path, **options):
        raise AssertionError("not reached")

    f = tmp_path / "x.both"
    f.write_text("# both\n")
    register_format("aaa_test", lambda p, lines: bool(lines) and lines[0].startswith("# both"), read, priority=5)
    register_format("bbb_test", None, read, extensions=("both",), priority=5)
    try:
        with pytest.raises(FieldError) as err:
            read_light_curve(f)
        assert err.value.field == "format" and "aaa_test" in err.value.detail and "bbb_test" in err.value.detail
        assert "ambiguous" in err.value.detail
        # of unequal priority, the higher one wins
        register_format("bbb_test", None, read, extensions=("both",), priority=6, overwrite=True)
        assert identify_format(f) == "bbb_test"
        with pytest.raises(FieldError, match="registered already"):
            register_format("bbb_test", None, read, extensions=("both",))
    finally:
        unregister_format("aaa_test")
        unregister_format("bbb_test")
    csv = _FORMATS.pop("csv")  # without the fallback, a file no format identifies
    try:
        with pytest.raises(FieldError, match="no format identifies it") as err:
            identify_format(f)
        assert err.value.field == "format" and "mmt" in err.value.detail
    finally:
        _FORMATS["csv"] = csv


def _signal(n=600, period=137.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 3000.0, n))
    y = 0.3 * np.sin(2 * np.pi * t / period) + 0.1 * np.cos(4 * np.pi * t / period) + rng.normal(0.0, 0.05, n)
    return t, y


def test_a_new_period_method_is_one_module_run_through_the_period_stage(plugin_package):
    """The characterise experiment's period stage, through the library, with the new method by
    its config key; its verdict and period in the metrics."""
    from pathlib import Path

    from cssat.experiments.context import Run
    from cssat.experiments.forward.verdicts import period_stage
    from cssat.inversion import PeriodResult, find_period, period_methods
    from cssat.models.observed.config import ObservedSettings, PeriodConfig

    importlib.import_module("cssat_plugins_test.bruteforce")
    assert "bruteforce" in period_methods()
    t, y = _signal()
    res = find_period(t, y, method="bruteforce")
    assert isinstance(res, PeriodResult) and res.method == "bruteforce"
    assert abs(res.period_s - 137.0) < 0.2  # the grid's 0.1 s step
    run = Run(out_dir=Path("."), dtype=None, device=None, seed=0)
    m: dict = {}
    opt = ObservedSettings(observations="(synthetic)", period=PeriodConfig(method="bruteforce"))
    out = period_stage(run, opt, t, y, np.full(len(t), 0.05), np.zeros(len(t), dtype=int).astype(str), m)
    assert out.method == "bruteforce" and m["verdict"] == "periodic" and m["period_s"] == res.period_s
    assert m["why"] == "the brute-force fit's best period" and m["stage_period"] == "ok"
    # an option the method does not take: a FieldError naming the option under period.
    opt.period = PeriodConfig(method="bruteforce", fap_max=0.01)
    with pytest.raises(FieldError) as err:
        period_stage(run, opt, t, y, None, np.zeros(len(t)).astype(str), {})
    assert err.value.field == "period.fap_max" and "periods" in err.value.detail


def test_unknown_period_method_names_the_key_and_the_methods():
    from pathlib import Path

    from cssat.experiments.context import Run
    from cssat.experiments.forward.verdicts import period_stage
    from cssat.inversion import find_period, register_period_method
    from cssat.models.observed.config import ObservedSettings, PeriodConfig

    t, y = _signal(200)
    with pytest.raises(FieldError) as err:
        find_period(t, y, method="nosuch")
    assert err.value.field == "method" and all(k in err.value.detail for k in ("cssat", "lombscargle", "pdm"))
    run = Run(out_dir=Path("."), dtype=None, device=None, seed=0)
    with pytest.raises(FieldError) as err:  # refused by the period settings' own check, before any stage
        PeriodConfig(method="nosuch")
    assert err.value.field == "period.method" and "cssat, lombscargle, pdm" in err.value.detail
    opt = ObservedSettings(observations="(synthetic)")
    opt.period.method = "nosuch"  # past that check: the period stage names it too
    with pytest.raises(FieldError) as err:
        period_stage(run, opt, t, y, None, np.zeros(len(t)).astype(str), {})
    assert err.value.field == "period.method" and "cssat, lombscargle, pdm" in err.value.detail
    with pytest.raises(FieldError, match="registered already"):
        register_period_method("cssat", lambda t, y: {})


def test_the_peers_find_the_period_a_brute_force_periodogram_finds():
    """lombscargle and pdm against a brute-force search written here: the 2-term least-squares
    periodogram's best period (LS), and Stellingwerf's θ by an explicit loop over bins (PDM),
    on the same grid."""
    from cssat.inversion import find_period
    from cssat.inversion.period_methods import frequency_grid

    t, y = _signal(300)
    f = frequency_grid(t)
    span = t[-1] - t[0]
    assert f[0] == pytest.approx(2 / span) and np.diff(f) == pytest.approx(0.1 / span)
    rss = []
    for fi in f:
        w = 2 * np.pi * fi * t
        X = np.stack([np.ones_like(t), np.cos(w), np.sin(w), np.cos(2 * w), np.sin(2 * w)], 1)
        c, *_ = np.linalg.lstsq(X, y, rcond=None)
        rss.append(np.sum((y - X @ c) ** 2))
    ls = find_period(t, y, method="lombscargle")
    assert ls.period_s == pytest.approx(1 / f[int(np.argmin(rss))], rel=1e-12)
    yy = y - np.polyval(np.polyfit(t - t.mean(), y, 2), t - t.mean())
    theta = []
    for fi in f:
        ph = (t * fi) % 1.0
        num, dof = 0.0, 0
        for b in range(10):
            s = yy[(ph >= b / 10) & (ph < (b + 1) / 10)]
            if len(s) > 1:
                num += np.sum((s - s.mean()) ** 2)
                dof += len(s) - 1
        theta.append(num / dof / yy.var(ddof=1))
    pdm = find_period(t, y, method="pdm")
    assert pdm.period_s == pytest.approx(1 / f[int(np.argmin(theta))], rel=1e-12)
    for r in (ls, pdm):
        assert r.verdict == "periodic" and r.periodic is True and abs(r.period_s / 137.0 - 1) < 0.01
