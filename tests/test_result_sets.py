"""A result set is the run's own files and nothing else (issue 21, point 0): the five corruptions
found by a hostile user, each a test."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_module

from cssat._record import digest, read_input, recording
from cssat.experiments import run_experiment
from cssat.experiments.results import check_complete, file_hash, load_saved

APP = [sys.executable, "-m", "cssat.app"]
SMALL = ["target.size=16", "threads=1", "denoiser=none"]
LIGHTCURVE = ["experiment=lightcurve", "scenario.n_steps=12", "scenario.step_s=3600", "render.size=16",
              "model=tess_like", "threads=1", "shadows=false"]


def cfg_of(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def listed_files_are_all_there(d: Path) -> dict:
    saved = load_saved(d)
    assert saved is not None and saved["status"] == "ok"
    for rel, h in saved["files"].items():
        assert file_hash(d / rel) == h
    return saved


def test_a_run_lists_only_its_own_files_and_moves_another_experiments_aside(tmp_path, caplog):
    d = tmp_path / "run"
    lc = run_experiment(cfg_of(*LIGHTCURVE), d)
    assert "lightcurve.csv" in lc["files"]
    with caplog.at_level("WARNING", logger="cssat"):
        met = run_experiment(cfg_of(*SMALL), d)
    files = set(met["files"])
    assert files == {"arrays.npz", "figures/fig9_sim1.png"}, files
    assert not (d / "lightcurve.csv").exists() and not (d / "figures" / "fig4_lightcurve.png").exists()
    moved = d / "previous" / f"lightcurve-{lc['config_sha']}"
    assert (moved / "lightcurve.csv").is_file() and (moved / "metrics.json").is_file()
    assert "moved to" in caplog.text and str(moved) in caplog.text
    listed_files_are_all_there(d)
    # resume accepts exactly this set and nothing else
    assert check_complete(d, load_saved(d), met["config_sha"], None) is None


def test_another_figure_format_does_not_join_the_set(tmp_path):
    d = tmp_path / "run"
    run_experiment(cfg_of(*SMALL), d)
    met = run_experiment(cfg_of(*SMALL, "figure_format=svg"), d)
    assert set(met["files"]) == {"arrays.npz", "figures/fig9_sim1.svg"}
    assert not (d / "figures" / "fig9_sim1.png").exists()  # moved aside, not left beside the SVG


def test_a_nested_run_and_unrelated_files_are_not_listed(tmp_path):
    d = tmp_path / "run"
    (d / "notes").mkdir(parents=True)
    (d / "notes" / "mine.txt").write_text("not a result")
    run_experiment(cfg_of(*SMALL), d / "inner")
    met = run_experiment(cfg_of(*SMALL, "cs.m=100"), d)
    assert set(met["files"]) == {"arrays.npz", "figures/fig9_sim1.png"}
    assert (d / "notes" / "mine.txt").exists() and (d / "inner" / "arrays.npz").exists()


def test_inputs_are_hashed_as_they_are_read(tmp_path):
    from PIL import Image

    from cssat.data.images import load_target

    img = tmp_path / "t.png"
    Image.fromarray(np.arange(256, dtype=np.uint8).reshape(16, 16)).save(img)
    first = img.read_bytes()
    with recording(tmp_path) as rec:
        load_target(str(img), 16)
        Image.fromarray(np.zeros((16, 16), np.uint8)).save(img)  # overwritten during the run
    assert rec.inputs == {str(img): digest(first)}
    assert read_input(img) == img.read_bytes()  # outside a recording: plain read, nothing noted


def test_an_image_overwritten_during_a_run_is_not_resumed(tmp_path):
    """The run reads the image, then it is overwritten (as by another process while the run
    computes): the manifest holds the hash of what was read, so the rerun does not skip."""
    from PIL import Image

    img = tmp_path / "t.png"
    Image.fromarray((np.arange(256).reshape(16, 16) % 251).astype(np.uint8)).save(img)
    (tmp_path / "overwriter.py").write_text(
        "from PIL import Image\nimport numpy as np\n"
        "from cssat.data.images import load_target\n"
        "def run(cfg, out_dir):\n"
        "    load_target(cfg.target.image, 16)\n"
        f"    Image.fromarray(np.zeros((16, 16), np.uint8)).save({str(img)!r})\n"
        "    return {'psnr': 1.0}\n")
    sys.path.insert(0, str(tmp_path))
    try:
        d = tmp_path / "run"
        over = [*SMALL, f"target.image={img}", "+experiment_module=overwriter"]
        met = run_experiment(cfg_of(*over), d)
        assert met["inputs"][str(img)] != file_hash(img)
        assert "changed since it was read" in check_complete(d, load_saved(d), met["config_sha"], None)
    finally:
        sys.path.remove(str(tmp_path))


def _sweep_env(tmp_path, body):
    (tmp_path / "slow.py").write_text(body)
    (tmp_path / "conf" / "experiment").mkdir(parents=True, exist_ok=True)
    (tmp_path / "conf" / "experiment" / "slow.yaml").write_text(
        "# @package _global_\nexperiment_name: slow\nexperiment_module: slow\ncs:\n  m: 1\n")
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    return [f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "experiment=slow"], env


@pytest.mark.slow
def test_two_sweeps_cannot_share_a_directory(tmp_path):
    over, env = _sweep_env(tmp_path, "import time\ndef run(cfg, out_dir):\n    time.sleep(4)\n"
                                     "    return {'psnr': float(cfg.cs.m)}\n")
    sweep = tmp_path / "sweep"
    first = subprocess.Popen(APP + ["-m", *over, "cs.m=1,2", f"hydra.sweep.dir={sweep}"], cwd=tmp_path, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    t = time.time()
    while not (sweep / ".cssat-sweep.lock.pid").exists() and time.time() - t < 60:
        time.sleep(0.05)
    second = subprocess.run(APP + ["-m", *over, "cs.m=2500", f"hydra.sweep.dir={sweep}"], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=120)
    out = first.communicate(timeout=300)[0]
    assert second.returncode == 2, second.stdout + second.stderr
    err = (second.stdout + second.stderr).strip().splitlines()
    assert len(err) == 1 and "hydra.sweep.dir" in err[0] and "in use by another cssat sweep" in err[0]
    assert first.returncode == 0, out
    rows = {r["job"]: r for r in _rows(sweep / "summary.csv")}
    assert {k: (r["cs.m"], r["status"]) for k, r in rows.items()} == {"0": ("1", "ok"), "1": ("2", "ok")}


def test_a_job_refused_or_never_run_fails_the_sweep(tmp_path):
    """Job 1's directory is held by another run: the job is refused, its row is not ok, and the
    sweep exits non-zero (it used to exit 0 with the other run's values in its row)."""
    over, env = _sweep_env(tmp_path, "def run(cfg, out_dir):\n    return {'psnr': float(cfg.cs.m)}\n")
    sweep = tmp_path / "sweep"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom cssat.experiments.results import run_lock\n"
         f"with run_lock({str(sweep / '1')!r}):\n    print('held', flush=True)\n    time.sleep(60)\n"],
        stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    try:
        res = subprocess.run(APP + ["-m", *over, "cs.m=1,2", f"hydra.sweep.dir={sweep}"], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=300)
    finally:
        holder.kill()
    assert res.returncode == 1, res.stdout + res.stderr
    rows = {r["job"]: r for r in _rows(sweep / "summary.csv")}
    assert rows["0"]["status"] == "ok" and rows["1"]["status"] != "ok"


def test_summarize_checks_every_jobs_hashes(tmp_path):
    from cssat.summary import main as summarize_main

    over, env = _sweep_env(tmp_path, "import numpy as np\nfrom cssat.experiments.files import write_npz\n"
                                     "def run(cfg, out_dir):\n    write_npz(f'{out_dir}/arrays.npz', x=np.ones(3))\n"
                                     "    return {'psnr': float(cfg.cs.m)}\n")
    sweep = tmp_path / "sweep"
    res = subprocess.run(APP + ["-m", *over, "cs.m=1,2,3", f"hydra.sweep.dir={sweep}"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    assert summarize_main([str(sweep)]) == 0
    with open(sweep / "2" / "arrays.npz", "ab") as f:
        f.write(b"\0")
    assert summarize_main([str(sweep)]) == 1
    rows = {r["job"]: r for r in _rows(sweep / "summary.csv")}
    assert rows["2"]["status"] == "corrupt" and "arrays.npz" in rows["2"]["error"]
    assert rows["0"]["status"] == rows["1"]["status"] == "ok"
    # metrics.json covers itself: a value edited by hand (valid JSON) is corrupt, not an ok row of psnr 99
    (sweep / "2" / "arrays.npz").write_bytes((sweep / "1" / "arrays.npz").read_bytes())  # mended
    assert summarize_main([str(sweep)]) == 0
    meta = json.loads((sweep / "0" / "metrics.json").read_text())
    meta["psnr"] = 99.0
    (sweep / "0" / "metrics.json").write_text(json.dumps(meta, indent=2))
    assert summarize_main([str(sweep)]) == 1
    rows = {r["job"]: r for r in _rows(sweep / "summary.csv")}
    assert rows["0"]["status"] == "corrupt" and "metrics.json changed" in rows["0"]["error"]
    # another sweep's metrics in a job directory are not this sweep's row
    meta = json.loads((sweep / "1" / "metrics.json").read_text())
    meta["sweep_id"] = "someone-else"
    (sweep / "1" / "metrics.json").write_text(json.dumps(meta))
    assert summarize_main([str(sweep)]) == 1
    assert {r["job"]: r["status"] for r in _rows(sweep / "summary.csv")}["1"] == "missing"


def _rows(path):
    import csv

    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("where", ["empty run dir", "chdir"])
def test_the_working_directory_and_the_cache_are_never_results(tmp_path, where):
    """``hydra.run.dir=''`` (the working directory) and ``hydra.job.chdir=true`` (the cache below
    the run): the manifest lists the run's own files only."""
    (tmp_path / "unrelated.txt").write_text("x")
    extra = ["hydra.run.dir=."] if where == "empty run dir" else [f"hydra.run.dir={tmp_path / 'r'}",
                                                                   "hydra.job.chdir=true"]
    res = subprocess.run(APP + [*SMALL, *extra], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    d = tmp_path if where == "empty run dir" else tmp_path / "r"
    saved = listed_files_are_all_there(d)
    assert set(saved["files"]) == {"arrays.npz", "figures/fig9_sim1.png"}
