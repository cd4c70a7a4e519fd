"""Named sweeps, launchers, sweep summaries and resuming (issue 6)."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_module
from omegaconf import OmegaConf

from cssat.summary import collect, main as summarize_main

EXE = [sys.executable, "-m", "cssat.app", "-m"]


def compose_hydra(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides), return_hydra_config=True)


def rows_of(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _named_sweeps():
    import cssat.conf

    return sorted(p.stem for p in (Path(cssat.conf.__file__).parent / "sweep").glob("*.yaml"))


@pytest.mark.parametrize("sweep", _named_sweeps())
def test_named_sweeps_name_valid_values_of_their_experiment(sweep):
    """Every value of every named sweep composes with its experiment and is in its allowed range."""
    from cssat.experiments.build import build_solver

    base = compose_hydra(f"sweep={sweep}")
    params = dict(base.hydra.sweeper.params)
    assert params, f"sweep {sweep} sweeps nothing"
    for key, values in params.items():
        for value in str(values).split(","):
            cfg = compose_hydra(f"sweep={sweep}", f"{key}={value}")
            exp = cfg.experiment_name
            node = OmegaConf.select(cfg, key)
            if OmegaConf.is_config(node):  # a config group: the option builds
                from cssat.experiments.build import build

                build(node, key)
            else:
                # the key exists in the experiment's config (a typed float field reads 6 as 6.0)
                assert str(node) == value or (isinstance(node, float) and node == float(value)), (key, node, value)
            from cssat.experiments.forward import measurements

            N = cfg.target.size ** 2
            m = measurements(cfg.cs, N)
            assert 1 <= m <= N
            if exp == "sim3":
                from cssat.experiments.build import build as build_node

                est = build_node(cfg.reference, "reference")
                n_ref, pool = est.sizes(N)  # validates them
                assert 1 <= n_ref <= min(pool, N)
                est.settings(N)
            build_solver(cfg.solver, m, N)  # e.g. K/m in [0, 1]


def test_launcher_configs_compose():
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    slurm = compose_hydra("launcher=slurm")
    assert "SlurmLauncher" in slurm.hydra.launcher._target_
    assert slurm.hydra.launcher.cpus_per_task == slurm.threads
    local = compose_hydra("launcher=submitit_local")
    assert "LocalLauncher" in local.hydra.launcher._target_
    joblib = compose_hydra("launcher=local")
    assert "JoblibLauncher" in joblib.hydra.launcher._target_  # cssat.launcher.RobustJoblibLauncher
    assert joblib.threads * joblib.hydra.launcher.n_jobs <= 2  # no oversubscription of 2 cores


@pytest.mark.slow
def test_joblib_sweep_2x2_summary_failed_job_and_resume(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    sweep = tmp_path / "sweep"
    args = ["target.size=16", "cs.m=0,120", "solver.k_ratio=0.05,0.2", "launcher=local",
            "denoiser.n_iter=2", f"hydra.sweep.dir={sweep}"]
    res = subprocess.run(EXE + args, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 1, res.stderr  # cs.m=0 fails: the sweep finishes, then exits 1
    rows = rows_of(sweep / "summary.csv")
    assert len(rows) == 4
    assert {(r["cs.m"], r["solver.k_ratio"]) for r in rows} == {(m, k) for m in ("0", "120") for k in ("0.05", "0.2")}
    status = {r["cs.m"]: set() for r in rows}
    for r in rows:
        status[r["cs.m"]].add(r["status"])
    assert status == {"0": {"failed"}, "120": {"ok"}}  # cs.m=0 is refused, and is a row, not a gap
    assert all(float(r["psnr"]) > 10 for r in rows if r["status"] == "ok")
    assert (sweep / "summary_psnr.png").stat().st_size > 1000
    # resume: the same sweep into the same directory skips the complete jobs and redoes the failed
    before = {r["job"]: json.loads((sweep / r["job"] / "metrics.json").read_text())["seconds"] for r in rows}
    res = subprocess.run(EXE + args, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 1, res.stderr
    assert res.stderr.count("skipped") + res.stdout.count("skipped") == 2
    after = {r["job"]: json.loads((sweep / r["job"] / "metrics.json").read_text())["seconds"] for r in rows_of(sweep / "summary.csv")}
    for job, sec in before.items():
        ok = next(r for r in rows if r["job"] == job)["status"] == "ok"
        assert (after[job] == sec) == ok


def test_standalone_summary_reports_missing_jobs(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    res = subprocess.run(EXE + ["target.size=16", "cs.m=60,120", "threads=1", "denoiser=none", f"hydra.sweep.dir={sweep}"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr
    (sweep / "1" / "metrics.json").unlink()  # an interrupted job
    (sweep / "summary.csv").unlink()
    assert summarize_main([str(sweep)]) == 1  # a row is not ok
    rows = rows_of(sweep / "summary.csv")
    assert [r["status"] for r in rows] == ["ok", "missing"] and [r["cs.m"] for r in rows] == ["60", "120"]
    _, swept = collect(sweep)
    assert swept == ["cs.m"]
    with pytest.raises(SystemExit):
        summarize_main([str(tmp_path / "nowhere")])
    assert "sweep_dir" in capsys.readouterr().err


def test_m_n_sweep_writes_psnr_in_every_row_and_a_map(tmp_path):
    """The phase-transition sweep of Simulation 3 over m × N_ref, at 16²."""
    sweep = tmp_path / "sweep"
    args = ["sweep=m_n", "target.size=16", "cs.m=100,200", "reference.n=100,200", "reference.pool=300",
            "reference.repeats=1", "reference.n_nonzero_coefs=10", "reference.baseline=false", "denoiser=none",
            "denoiser@denoiser3d=none", f"cache_dir={tmp_path / 'cache'}", "threads=1", f"hydra.sweep.dir={sweep}"]
    res = subprocess.run(EXE + args, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr
    rows = rows_of(sweep / "summary.csv")
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    assert {(r["cs.m"], r["reference.n"]) for r in rows} == {(m, k) for m in ("100", "200") for k in ("100", "200")}
    for r in rows:  # psnr is the headline of each job: its best repeat, as in its metrics.json
        met = json.loads((sweep / r["job"] / "metrics.json").read_text())
        assert float(r["psnr"]) == pytest.approx(max(met["repeat_psnr"])) and float(r["psnr"]) > 5
    assert (sweep / "summary_psnr.png").stat().st_size > 5000
    assert len(list((tmp_path / "cache").glob("refs-*.npy"))) == 1  # the pool is rendered once, shared


def test_a_smaller_sweep_into_an_old_sweep_directory_summarises_only_its_jobs(tmp_path):
    sweep = tmp_path / "sweep"
    base = ["target.size=16", "threads=1", "denoiser=none", f"hydra.sweep.dir={sweep}"]
    assert subprocess.run(EXE + base + ["cs.m=60,90,120"], capture_output=True, cwd=tmp_path, timeout=600).returncode == 0
    assert len(rows_of(sweep / "summary.csv")) == 3
    res = subprocess.run(EXE + base + ["cs.m=60"], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr
    rows = rows_of(sweep / "summary.csv")
    assert [r["job"] for r in rows] == ["0"] and rows[0]["status"] == "ok"  # jobs 1 and 2 are the old sweep's
    assert "1 jobs (1 ok)" in res.stdout + res.stderr


def test_a_sweep_of_only_bad_input_exits_2_and_a_mixed_one_1(tmp_path):
    # every job refused by a FieldError is a wrong command line: exit 2, as one bad run; one job
    # that ran keeps the sweep's exit at 1 (not every job ended ok)
    base = ["experiment=inversion", "threads=1"]
    res = subprocess.run(EXE + base + ["inversion.parametric.parts_keep=0,99", f"hydra.sweep.dir={tmp_path / 'a'}"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 2, res.stderr
    assert "every job was refused as bad input" in res.stderr + res.stdout
    assert {r["status"] for r in rows_of(tmp_path / "a" / "summary.csv")} == {"failed"}
    small = ["target.size=16", "threads=1", "denoiser=none", f"hydra.sweep.dir={tmp_path / 'b'}"]
    res = subprocess.run(EXE + small + ["solver.k_ratio=0.1,7"], capture_output=True, text=True, cwd=tmp_path,
                         timeout=600)
    assert res.returncode == 1, res.stderr
    assert sorted(r["status"] for r in rows_of(tmp_path / "b" / "summary.csv")) == ["failed", "ok"]


def test_summarize_marks_a_corrupt_metrics_file_and_checks_the_metric(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    res = subprocess.run(EXE + ["target.size=16", "cs.m=60,120", "threads=1", "denoiser=none", f"hydra.sweep.dir={sweep}"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr
    text = (sweep / "1" / "metrics.json").read_text()
    (sweep / "1" / "metrics.json").write_text(text[: len(text) // 2])  # truncated
    assert summarize_main([str(sweep)]) == 1
    rows = rows_of(sweep / "summary.csv")
    assert [r["status"] for r in rows] == ["ok", "corrupt"] and "metrics.json" in rows[1]["error"]
    with pytest.raises(SystemExit):
        summarize_main([str(sweep), "--metric", "psnr_typo"])
    err = capsys.readouterr().err
    assert "--metric" in err and "psnr_typo" in err and "psnr" in err


@pytest.mark.slow
def test_a_worker_killed_by_the_os_fails_its_job_only(tmp_path):
    """Under launcher=local, a job whose worker process is killed (as by the OOM killer) is a
    failed row; the other jobs finish — also the one that shared the batch with it when its
    worker died, which is never blamed —, the summary is written, and the sweep exits 1."""
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    import os

    (tmp_path / "killer.py").write_text(
        "import os, signal, time\n"
        "def run(cfg, out_dir):\n"
        "    if cfg.cs.m == 2:\n"
        "        time.sleep(0.5)\n"
        "        os.kill(os.getpid(), signal.SIGKILL)  # what the OOM killer does\n"
        "    time.sleep(2)  # job 1 is still running in the other worker when job 2's worker dies\n"
        "    return {'psnr': float(cfg.cs.m), 'ssim': None}\n")
    (tmp_path / "conf" / "experiment").mkdir(parents=True)
    (tmp_path / "conf" / "experiment" / "killer.yaml").write_text(
        "# @package _global_\nexperiment_name: killer\nexperiment_module: killer\ncs:\n  m: 1\n")
    sweep = tmp_path / "sweep"
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    res = subprocess.run(EXE + [f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "experiment=killer", "cs.m=1,2,3,4",
                                "launcher=local", f"hydra.sweep.dir={sweep}"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600, env=env)
    assert res.returncode == 1, res.stdout + res.stderr
    rows = {r["cs.m"]: r for r in rows_of(sweep / "summary.csv")}
    assert set(rows) == {"1", "2", "3", "4"}
    assert rows["2"]["status"] == "failed" and "killed" in rows["2"]["error"]
    assert all(rows[m]["status"] == "ok" and float(rows[m]["psnr"]) == float(m) for m in ("1", "3", "4"))


def test_an_optuna_search_runs_at_a_tiny_size(tmp_path):
    """conf/hparams_search/omp_optuna.yaml (the optuna extra): trials are jobs of one sweep, the
    best value Optuna reports is the best PSNR of the summary."""
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    import yaml

    sweep = tmp_path / "search"
    res = subprocess.run([sys.executable, "-m", "cssat.app", "hparams_search=omp_optuna", "target.size=16",
                          "hydra.sweeper.n_trials=3", "denoiser=none", "threads=1", f"hydra.sweep.dir={sweep}"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    rows = rows_of(sweep / "summary.csv")
    assert len(rows) == 3 and all(r["status"] == "ok" for r in rows)
    ks = [float(r["solver.k_ratio"]) for r in rows]
    assert all(0.02 <= k <= 0.4 for k in ks) and len(set(ks)) == 3
    best = yaml.safe_load((sweep / "optimization_results.yaml").read_text())
    assert best["best_value"] == pytest.approx(max(float(r["psnr"]) for r in rows))
