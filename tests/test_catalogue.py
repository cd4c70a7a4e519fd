"""Issue 46, point 6: a catalogue at archive scale — characterise_file (one flat row a file, a bad
file a failed row), shards of a sweep joined into catalogue.csv only from complete shards, the
same rows through Dask, file names read literally (never interpolated), the launchers extra
named when missing, a full disk in one line."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cssat import catalogue as C
from cssat import catalogue_shards as S

REAL = Path(__file__).parent / "data" / "real"
STARLINK = REAL / "mmt_sat10288_starlink3535_track20416355.txt"  # MMT: "Not variable"
ONEWEB = REAL / "mmt_sat8843_oneweb0208_excerpt.txt"
EXE = [sys.executable, "-m", "cssat.app"]


def mmt_file(path: Path, norad: int, period_s: float | None, seed: int, n: int = 300) -> Path:
    """A synthetic MMT-9 export of one track: a double-peaked curve of ``period_s`` (or a
    constant) plus 0.03 mag of noise, 0.1 s cadence."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    mag = 8.0 + rng.normal(0, 0.03, n)
    if period_s:
        ph = 2 * np.pi * t / period_s
        mag += 0.4 * np.cos(2 * ph) + 0.15 * np.cos(ph + 0.3)
    t0 = np.datetime64("2021-03-04T21:10:05.000", "ms")
    lines = [f"# satellite: {norad} SYNTHETIC-{norad} / --", "# catalogue: 1 NORAD",
             f"# variability: {'2 Periodic' if period_s else '0 Not variable'}",
             f"# variability_period: {period_s if period_s else 'None'}", "#",
             "# Date Time StdMag Mag Filter Penumbra Distance Phase Channel Track"]
    for ti, m in zip(t, mag):
        stamp = str(t0 + np.timedelta64(int(round(ti * 1000)), "ms")).replace("T", " ")
        lines.append(f"{stamp}000 {m - 1:.3f} {m:.5f} Clear 0 2000.000 60.0 1 {norad}{seed}")
    path.write_text("\n".join(lines) + "\n")
    return path


BROKEN = "# satellite: 1 X\n# Date Time Mag\n2020-01-01 00:00:00 99.999\n"


def without_seconds(rows):
    """Rows less ``seconds`` (each call's own wall time, the one column that differs)."""
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]


def test_characterise_file_one_flat_row_a_file_and_a_bad_file_a_failed_row(tmp_path):
    per = mmt_file(tmp_path / "per.txt", 90001, 6.0, seed=1)
    flat = mmt_file(tmp_path / "flat.txt", 90002, None, seed=2)
    (tmp_path / "broken.txt").write_text(BROKEN)
    rows = {Path(r["file"]).name: r for r in map(C.characterise_file, [per, flat, tmp_path / "broken.txt",
                                                                        tmp_path / "gone.txt"])}
    for r in rows.values():
        assert tuple(r) == C.ROW_COLUMNS and r["verdict"] in C.VERDICTS
        assert all(v is None or isinstance(v, (str, int, float, bool)) for v in r.values())  # flat: a CSV row
    p = rows["per.txt"]
    assert p["status"] == "ok" and p["verdict"] == "periodic" and abs(p["period_s"] / 6.0 - 1) < 0.01, p
    assert p["object_id"] == "90001" and p["published_period_s"] == 6.0 and p["n_samples"] == 300 and p["error"] is None
    assert p["period_err_s"] > 0 and p["fap"] < 1e-3 and p["why"]
    f = rows["flat.txt"]
    assert f["status"] == "ok" and f["verdict"] in ("not periodic", "undetermined") and f["period_s"] is None, f
    b = rows["broken.txt"]
    assert b["status"] == "failed" and b["verdict"] == "failed" and "observations.Mag[row 1]" in b["error"]
    assert "\n" not in b["error"]
    g = rows["gone.txt"]
    assert g["verdict"] == "failed" and "no such file" in g["error"]
    assert C.characterise_file(per, stages={"tumbling": "off"})["period_s"] == p["period_s"]  # the same, again
    # a bad setting is the caller's, not the file's: raised before any file, naming the key
    with pytest.raises(ValueError, match=r"^period\.min_periods: not an option"):
        C.characterise_file(per, period={"min_periods": 3})
    with pytest.raises(ValueError, match=r"^stages\.spin: .*expected 'off'"):
        C.characterise_file(per, stages={"spin": "auto"})
    for not_a_path in (None, 123, ["a.txt"]):  # was os.fspath's TypeError
        with pytest.raises(ValueError, match=r"^path: expected a file's path"):
            C.characterise_file(not_a_path)


def _compose(overrides):
    from hydra import compose, initialize_config_module

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=overrides)


def test_dask_rows_equal_shard_rows_equal_characterise_file_rows(tmp_path):
    """The same files three ways: characterise_file in a loop, a Dask bag on threads, and the
    sweep's shard jobs (cssat.catalogue_shards.run, the function each job of `cssat -m` runs)."""
    db = pytest.importorskip("dask.bag")
    cat = tmp_path / "cat"
    cat.mkdir()
    mmt_file(cat / "a.txt", 90011, 4.0, seed=3)
    mmt_file(cat / "b.txt", 90012, None, seed=4)
    (cat / "c.txt").write_text(BROKEN)
    (cat / "d.txt").write_bytes(ONEWEB.read_bytes())
    files = C.catalogue_files(cat)
    assert [Path(f).name for f in files] == ["a.txt", "b.txt", "c.txt", "d.txt"]
    loop = [C.characterise_file(f) for f in files]
    bag = db.from_sequence(files, npartitions=2).map(C.characterise_file).compute(scheduler="threads", num_workers=2)
    assert without_seconds(bag) == without_seconds(loop)
    cfg = _compose(["experiment=characterise", f"observations={cat}", "catalogue.shard_size=3"])
    shard_rows = []
    from omegaconf import open_dict

    for k in range(C.n_shards(len(files), 3)):
        with open_dict(cfg):
            cfg.catalogue.shard = k
        metrics = S.run(cfg, tmp_path / f"job{k}")
        assert metrics["catalogue_table"] == f"tracks_{k}.csv" and metrics["n_files"] == (3 if k == 0 else 1)
        shard_rows += C.read_rows(tmp_path / f"job{k}" / metrics["catalogue_table"])
    assert without_seconds(shard_rows) == without_seconds(loop)  # through the CSV: full precision, None as empty
    assert [r["verdict"] for r in loop][:3] == ["periodic", loop[1]["verdict"], "failed"]


@pytest.mark.slow
def test_a_catalogue_sweep_joins_its_shards_and_reads_every_file_name_literally(tmp_path):
    """`cssat -m experiment=characterise observations=<dir> catalogue.shard_size=2 launcher=local`:
    3 shards of 5 files, joined into catalogue.csv (one row a file, sorted) equal to
    characterise_file's rows. File names an OmegaConf interpolation would rewrite are data: a file
    named t_${experiment_name}.txt is read, not t_characterise.txt twice. The shard tables are in
    each job's manifest: one edited afterwards is found, the catalogue not joined, and a resumed
    sweep runs that shard again (the others skipped) and joins."""
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    cat = tmp_path / "cat"
    cat.mkdir()
    mmt_file(cat / "t_characterise.txt", 90021, 5.0, seed=5)
    (cat / "t_${experiment_name}.txt").write_bytes(STARLINK.read_bytes())
    (cat / "h_${oc.env:HOME}.txt").write_bytes(ONEWEB.read_bytes())
    (cat / "back\\slash.txt").write_text(BROKEN)
    mmt_file(cat / "z.txt", 90022, None, seed=6)
    sweep = tmp_path / "sweep"
    args = EXE + ["-m", "experiment=characterise", f"observations={cat}", "catalogue.shard_size=2", "launcher=local",
                  f"hydra.sweep.dir={sweep}"]
    res = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "Traceback" not in res.stderr
    files = C.catalogue_files(cat)
    want = without_seconds([C.characterise_file(f) for f in files])
    got = without_seconds(C.read_rows(sweep / "catalogue.csv"))
    assert got == want
    ids = {Path(r["file"]).name: r["object_id"] for r in got}
    assert ids == {"back\\slash.txt": None, "h_${oc.env:HOME}.txt": "48243", "t_${experiment_name}.txt": "51722",
                   "t_characterise.txt": "90021", "z.txt": "90022"}
    assert "observations.Mag[row 1]" in next(r["error"] for r in got if r["status"] == "failed")
    summary = list(__import__("csv").DictReader(open(sweep / "summary.csv")))
    assert [(r["catalogue.shard"], r["status"], r["n_files"]) for r in summary] == [("0", "ok", "2"), ("1", "ok", "2"),
                                                                                     ("2", "ok", "1")]
    for k in range(3):  # each shard's table is a result of its job: hashed in its manifest
        m = json.loads((sweep / str(k) / "metrics.json").read_text())
        assert f"tracks_{k}.csv" in m["files"], m["files"]
    overrides = (sweep / "1" / ".hydra" / "overrides.yaml").read_text()
    assert "t_characterise" not in overrides and "slash" not in overrides  # the file names are not overrides
    from astropy.table import Table

    assert len(Table.read(sweep / "catalogue.csv", format="ascii.csv")) == 5  # astropy reads the catalogue

    # an edited shard table: the summary refuses to join it (exit 1), no catalogue is left
    table = sweep / "1" / "tracks_1.csv"
    table.write_text(table.read_text().replace("SYNTHETIC", "EDITED"))
    from cssat import summary

    assert summary.main([str(sweep)]) == 1
    assert not (sweep / "catalogue.csv").exists()
    # resumed: shard 1 runs again (its table changed since its run), 0 and 2 are skipped, the catalogue joined
    res = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    log = res.stdout + res.stderr
    assert log.count("skipped (resume=false to redo)") == 2 and "tracks_1.csv changed since the run" in log
    assert without_seconds(C.read_rows(sweep / "catalogue.csv")) == want


def test_a_failed_shard_leaves_no_catalogue_and_the_summary_names_it(tmp_path, caplog):
    """The join writes only from complete shards: a shard that failed (its metrics say so) or is
    missing means no catalogue.csv — a stale one is removed — and the log names the job."""
    from cssat import summary

    sweep = tmp_path / "sweep"
    cat = tmp_path / "cat"
    cat.mkdir()
    for i in range(3):
        mmt_file(cat / f"f{i}.txt", 90030 + i, None, seed=i, n=60)
    cfg = _compose(["experiment=characterise", f"observations={cat}", "catalogue.shard_size=2"])
    from omegaconf import open_dict

    for k in range(2):
        d = sweep / str(k)
        (d / ".hydra").mkdir(parents=True)
        (d / ".hydra" / "overrides.yaml").write_text(f"- catalogue.shard={k}\n")
        with open_dict(cfg):
            cfg.catalogue.shard = k
        from cssat.experiments import run_experiment

        with open_dict(cfg):
            cfg.experiment_module = "cssat.catalogue_shards"
        run_experiment(cfg, d)
    assert summary.main([str(sweep)]) == 0
    joined = C.read_rows(sweep / "catalogue.csv")
    assert [Path(r["file"]).name for r in joined] == ["f0.txt", "f1.txt", "f2.txt"]
    (sweep / "1" / "metrics.json").write_text(json.dumps({"status": "failed", "error": "OSError: disk full"}))
    assert summary.main([str(sweep)]) == 1
    assert not (sweep / "catalogue.csv").exists()
    assert "catalogue not joined" in caplog.text and "job 1: failed (OSError: disk full)" in caplog.text
    import shutil

    shutil.rmtree(sweep / "1")  # a shard missing altogether
    caplog.clear()
    assert summary.main([str(sweep)]) == 1 and not (sweep / "catalogue.csv").exists()
    assert "shards [1] of 0 to 1 are not in this sweep" in caplog.text


def test_the_join_on_a_full_disk_writes_nothing_half_and_says_so_in_one_line(tmp_path, monkeypatch, caplog):
    from cssat import _tmpfiles, summary

    sweep = tmp_path / "sweep"
    d = sweep / "0"
    (d / ".hydra").mkdir(parents=True)
    (d / ".hydra" / "overrides.yaml").write_text("- catalogue.shard=0\n")
    mmt_file(tmp_path / "cat.txt", 90040, None, seed=0, n=60)
    cfg = _compose(["experiment=characterise", f"observations={tmp_path / 'cat.txt'}", "catalogue.shard=0",
                    "+experiment_module=cssat.catalogue_shards"])
    from cssat.experiments import run_experiment

    run_experiment(cfg, d)
    real_replace = os.replace

    def full(src, dst):
        if str(dst).endswith("catalogue.csv"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(_tmpfiles.os, "replace", full)
    assert summary.main([str(sweep)]) == 1
    assert not (sweep / "catalogue.csv").exists() and not list(sweep.glob(".*.tmp"))
    lines = [r.getMessage() for r in caplog.records if "No space left" in r.getMessage()]
    assert len(lines) == 1 and "\n" not in lines[0], lines


def test_a_full_disk_in_a_sweep_ends_in_one_line_not_a_traceback(tmp_path, monkeypatch):
    """Hydra prints an exception escaping its sweep (here: a job's own .hydra/ files, written by
    Hydra before the job runs, on a full disk) as a traceback; cssat says it in one line and exits
    1. In the joblib launcher's worker the same error is that job's failure alone."""
    from conftest import run_cli
    from hydra.core import utils as hydra_utils

    def full(cfg, filename, output_dir):
        raise OSError(errno.ENOSPC, "No space left on device", str(output_dir / filename))

    monkeypatch.setattr(hydra_utils, "_save_config", full)
    mmt_file(tmp_path / "a.txt", 90050, None, seed=0, n=60)
    code, lines = run_cli(["-m", "experiment=characterise", f"observations={tmp_path}/*.txt",
                           f"hydra.sweep.dir={tmp_path / 'sweep'}"], tmp_path)
    assert code == 1 and not any("Traceback" in ln or "File " in ln for ln in lines), lines
    assert [ln for ln in lines if "No space left" in ln] == [f"cannot write the results: {tmp_path / 'sweep'}/0/.hydra/"
                                                              "config.yaml: No space left on device"], lines
    assert not (tmp_path / "sweep" / "catalogue.csv").exists()
    # the launcher's worker: an OSError of Hydra's own job files is that job's failure, returned, not raised
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    from hydra.core.utils import JobStatus
    from hydra_plugins.cssat_launcher import launcher as L
    from hydra_plugins.hydra_joblib_launcher import _core

    def no_space(idx, overrides, *a):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(_core, "execute_job", no_space)
    out = L._execute_job(3, ["catalogue.shard=3"], None, _compose_hydra(tmp_path), None, None)
    assert out.status == JobStatus.COMPLETED and out.return_value is None and out.overrides == ["catalogue.shard=3"]


def _compose_hydra(tmp_path):
    from hydra import compose, initialize_config_module

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=[f"hydra.sweep.dir={tmp_path}/s"], return_hydra_config=True)


@pytest.mark.parametrize("name", ["t_${experiment_name}.txt", "h_${oc.env:HOME}.txt", "a\\b.txt", "it's.txt",
                                  "q\\${x}.txt", "end\\", "c,d e=f.txt"])
def test_a_file_name_is_given_to_the_config_literally(name):
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    value = "/data/" + name
    o = OverridesParser.create().parse_overrides([C.literal_override("observations", value)])[0]
    cfg = OmegaConf.create({"experiment_name": "characterise", "observations": o.value()})
    assert OmegaConf.to_container(cfg, resolve=True)["observations"] == value


def test_one_file_named_like_an_interpolation_is_read_as_named(tmp_path):
    """`cssat experiment=characterise observations=<dir>/t_${experiment_name}.txt` reads that file,
    not t_characterise.txt beside it."""
    from conftest import run_cli

    (tmp_path / "t_${experiment_name}.txt").write_bytes(STARLINK.read_bytes())
    mmt_file(tmp_path / "t_characterise.txt", 90060, None, seed=0, n=60)
    code, lines = run_cli(["experiment=characterise", f"observations={tmp_path}/t_${{experiment_name}}.txt",
                           "characterise.figures=false", f"hydra.run.dir={tmp_path / 'run'}"], tmp_path)
    assert code == 0, lines
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["object_id"] == "51722"  # STARLINK-3535's, not the synthetic 90060 of t_characterise.txt


def test_the_sweep_is_cut_into_shards_and_the_file_names_never_become_overrides(tmp_path):
    from cssat.app import expand_file_sweeps

    for i in range(5):
        (tmp_path / f"f{i}.txt").write_text("x")
    (tmp_path / ".hidden").write_text("x")
    argv = ["-m", "experiment=characterise", f"observations={tmp_path}", "catalogue.shard_size=2"]
    out = expand_file_sweeps(argv)
    files = C.catalogue_files(tmp_path)
    assert len(files) == 5 and not any("f0.txt" in a for a in out)
    assert out[:2] == argv[:2] and out[2] == C.literal_override("observations", str(tmp_path))
    assert "catalogue.shard=range(0,3)" in out and "catalogue.n_files=5" in out
    assert f"catalogue.listing_sha='{C.listing_sha(files)}'" in out
    assert "catalogue.shard=range(0,1)" in expand_file_sweeps(argv[:3])  # the default: 500 files a shard
    assert "catalogue.shard=range(0,5)" not in expand_file_sweeps(argv[:3] + ["catalogue.shard=4"])  # its own shards
    for bad in ("0", "-1", "two", "1,2"):
        with pytest.raises(ValueError, match=r"^catalogue\.shard_size: expected one integer >= 1"):
            expand_file_sweeps(argv[:3] + [f"catalogue.shard_size={bad}"])
    with pytest.raises(ValueError, match=r"^observations: no file matches"):
        expand_file_sweeps(["-m", "experiment=characterise", f"observations={tmp_path}/*.fits"])
    # the experiment's default (its typed config's) is the one the command line assumes
    assert _compose(["experiment=characterise"]).catalogue.shard_size == C.DEFAULT_SHARD_SIZE


def test_another_experiment_s_file_sweep_gives_hydra_each_name_literally(tmp_path):
    """Outside characterise a directory is still one job per file: each name quoted so that
    Hydra's parser and OmegaConf give back exactly the file's path (was: ${...} interpolated,
    backslashes doubled)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    from cssat.app import expand_file_sweeps

    names = ["t_${experiment_name}.txt", "h_${oc.env:HOME}.txt", "a\\b.txt", "it's.txt"]
    for n in names:
        (tmp_path / n).write_text("x")
    out = expand_file_sweeps(["-m", "experiment=lightcurve", f"observations={tmp_path}"])
    o = OverridesParser.create().parse_overrides([out[2]])[0]
    got = [OmegaConf.to_container(OmegaConf.create({"experiment_name": "lightcurve", "o": getattr(v, "text", v)}),
                                  resolve=True)["o"] for v in o.sweep_iterator()]  # a quoted value: its text
    assert got == sorted(str(tmp_path / n) for n in names)


def test_a_bad_catalogue_setting_is_refused_before_any_job(tmp_path):
    from conftest import run_cli

    for i in range(2):
        mmt_file(tmp_path / f"f{i}.txt", 90080 + i, None, seed=i, n=60)
    for arg, key in (("catalogue.tumbling=maybe", "catalogue.tumbling: expected true or false, got 'maybe'"),
                     ("+period.min_periods=3", "period.min_periods: no such key; period is a typed config")):
        code, lines = run_cli(["-m", "experiment=characterise", f"observations={tmp_path}", arg,
                               f"hydra.sweep.dir={tmp_path / 'sweep'}"], tmp_path)
        assert code == 2 and len(lines) == 1 and lines[0].startswith(f"bad input: {key}"), lines
        assert not (tmp_path / "sweep").exists()


def test_a_shard_refuses_a_file_list_that_changed_since_the_sweep_listed_it(tmp_path):
    from cssat._checks import FieldError

    for i in range(3):
        mmt_file(tmp_path / f"f{i}.txt", 90070 + i, None, seed=i, n=60)
    files = C.catalogue_files(tmp_path)
    cfg = _compose(["experiment=characterise", f"observations={tmp_path}", "catalogue.shard=0",
                    "catalogue.n_files=3", f"catalogue.listing_sha='{C.listing_sha(files)}'"])
    (tmp_path / "f3.txt").write_text("new")
    with pytest.raises(FieldError, match=r"^observations: the files changed since the sweep listed them"):
        S.run(cfg, tmp_path / "job")
    cfg = _compose(["experiment=characterise", f"observations={tmp_path}", "catalogue.shard=9"])
    with pytest.raises(FieldError, match=r"^catalogue\.shard: 4 files in shards of 500 make 1 shards \(0 to 0\), got 9"):
        S.run(cfg, tmp_path / "job")
    assert not (tmp_path / "job" / "tracks_0.csv").exists()


def test_a_launcher_whose_plugin_is_missing_names_the_launchers_extra(tmp_path, monkeypatch):
    """A plain install has no hydra-joblib-launcher: Hydra would say "Could not find
    'hydra/launcher/joblib'"; cssat names the extra in one line and exits 2."""
    from conftest import run_cli

    from cssat.app import missing_launcher

    monkeypatch.setitem(sys.modules, "hydra_plugins.hydra_joblib_launcher", None)  # not importable
    code, lines = run_cli(["-m", "experiment=characterise", f"observations={STARLINK}", "launcher=local",
                           f"hydra.sweep.dir={tmp_path / 'sweep'}"], tmp_path)
    assert code == 2 and len(lines) == 1, lines
    assert "launcher=local needs hydra-joblib-launcher" in lines[0] and "pip install 'cssat[launchers]'" in lines[0]
    assert not (tmp_path / "sweep").exists()
    monkeypatch.setitem(sys.modules, "hydra_plugins.hydra_submitit_launcher", None)
    assert "pip install 'cssat[launchers]'" in missing_launcher(["launcher=slurm"])
    assert missing_launcher(["experiment=characterise"]) is None


def test_import_cssat_catalogue_stays_light():
    code = ("import sys, cssat.catalogue; heavy = [m for m in ('numpy', 'torch', 'omegaconf', 'hydra', 'yaml') "
            "if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
