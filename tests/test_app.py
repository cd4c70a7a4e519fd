"""The Hydra app: every config composes, Simulation 1 runs end to end, bad values name their field."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_module

from cssat.experiments import ConfigError, run_experiment

SMALL = ["target.size=16", "cs.m=200", "threads=1"]


def flat_psnr(arrays):
    """The PSNR of the flat image at the truth's mean: what the total flux alone gives (the floor)."""
    t = arrays["truth"]
    return 10 * np.log10(1 / np.mean((t - t.mean()) ** 2))


def cfg_of(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def test_every_experiment_config_composes():
    import cssat.conf

    exp_dir = Path(cssat.conf.__file__).parent / "experiment"
    names = sorted(p.stem for p in exp_dir.glob("*.yaml"))
    assert "sim1" in names
    for name in names:
        cfg = cfg_of(f"experiment={name}")
        assert cfg.experiment_name == name


@pytest.fixture(scope="module")
def sim1_small(tmp_path_factory):
    """``(metrics, out_dir)`` of Simulation 1 at :data:`SMALL` with its default denoiser
    (sparse-KSVD), run once for the tests that read it."""
    out = tmp_path_factory.mktemp("sim1_small") / "run"
    return run_experiment(cfg_of(*SMALL), out), out


def test_sim1_end_to_end(sim1_small):
    _, tmp_path = sim1_small
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["status"] == "ok" and saved["m"] == 200 and saved["n_pixels"] == 256
    for key in ("psnr", "ssim", "seconds", "solver_n_nonzero_coefs", "atmosphere", "noise"):
        assert key in saved
    import cssat
    import torch

    assert saved["cssat_version"] == cssat.__version__ and saved["torch_version"] == torch.__version__
    assert saved["numpy_version"] == np.__version__
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=Path(cssat.__file__).parent)
    if head.returncode == 0:  # cssat runs from a git checkout: its commit is recorded
        assert saved["git_commit"] == head.stdout.strip()
    arrays = np.load(tmp_path / "arrays.npz")
    assert arrays["truth"].shape == (16, 16) and arrays["y"].shape == (200,)
    assert arrays["reconstruction"].shape == (16, 16)
    assert (tmp_path / "figures" / "fig9_sim1.png").stat().st_size > 1000
    # the PSNR in metrics is the PSNR of the saved arrays
    mse = np.mean((arrays["reconstruction"] - arrays["truth"]) ** 2)
    assert saved["psnr"] == pytest.approx(10 * np.log10(1 / mse), rel=1e-9)
    # Fig. 9's third column: the denoised reconstruction and its PSNR
    assert saved["denoiser"] == "sparse_ksvd" and saved["denoise_sigma"] > 0
    mse_d = np.mean((arrays["denoised"] - arrays["truth"]) ** 2)
    assert saved["psnr_denoised"] == pytest.approx(10 * np.log10(1 / mse_d), rel=1e-9)
    assert not np.array_equal(arrays["denoised"], arrays["reconstruction"])


@pytest.mark.parametrize("name", ["none", "sparse_ksvd", "tv", "wavelet", "nlm"])
def test_every_denoiser_config_runs_in_sim1(tmp_path, name, sim1_small):
    if name == "wavelet":
        pytest.importorskip("pywt")
    if name == "sparse_ksvd":  # the default: the module's run
        metrics, tmp_path = sim1_small
    else:
        metrics = run_experiment(cfg_of(*SMALL, f"denoiser={name}"), tmp_path)
    arrays = np.load(tmp_path / "arrays.npz")
    assert metrics["denoiser"] == name and arrays["denoised"].shape == (16, 16)
    if name == "none":
        assert np.array_equal(arrays["denoised"], arrays["reconstruction"])
        assert metrics["psnr_denoised"] == metrics["psnr"]


def test_sim1_is_deterministic_and_recovers_a_compressible_image(tmp_path):
    a = run_experiment(cfg_of(*SMALL, "cs.m=230", "denoiser=none"), tmp_path / "a")  # the reconstruction's numbers
    b = run_experiment(cfg_of(*SMALL, "cs.m=230", "denoiser=none"), tmp_path / "b")
    assert a["psnr"] == b["psnr"]
    ya, yb = (np.load(tmp_path / d / "arrays.npz")["y"] for d in "ab")
    assert np.array_equal(ya, yb)
    # m = N with the error-constrained mode: OMP fits y exactly, so the image is recovered
    full = run_experiment(cfg_of(*SMALL, "cs.m=256", "solver.epsilon=1e-9", "dtype=float64", "denoiser=none"), tmp_path / "c")
    assert full["psnr"] > 80


@pytest.mark.slow
def test_a_cold_numba_cache_gives_the_numbers_of_a_warm_one(tmp_path):
    """The first run (numba compiles every kernel) and the next (kernels from numba's on-disk
    cache) of one config and seed give identical arrays and metrics. sim1 at 64² (one signal, K =
    704 atoms, 2 threads) differed before: its kernels' fast-math let LLVM reassociate and fuse
    differently when a helper was compiled into its caller (cold) than when it was loaded from the
    cache (warm): PSNR 25.0214 against 25.0036 dB."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}  # empty: a cold cache
    runs = []
    for name in ("cold", "warm"):
        out = subprocess.run([sys.executable, "-m", "cssat.app", "experiment=sim1", "target.size=64", "denoiser=none",
                              "threads=2", f"hydra.run.dir={tmp_path / name}"], env=env, capture_output=True, text=True,
                             timeout=900)
        assert out.returncode == 0, out.stderr[-2000:]
        runs.append(tmp_path / name)
    assert any((tmp_path / "numba-cache").rglob("*.nbi"))  # the second run had kernels to load
    a, b = (np.load(d / "arrays.npz") for d in runs)
    for key in a.files:
        assert np.array_equal(a[key], b[key]), key
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in runs)
    scores = [k for k in ma if k.startswith(("psnr", "ssim", "omp_"))]
    assert scores and all(ma[k] == mb[k] for k in scores), {k: (ma[k], mb[k]) for k in scores}


@pytest.mark.parametrize(
    "override,field",
    [
        ("cs.m=0", "cs.m"),
        ("cs.m=257", "cs.m"),
        ("solver.n_nonzero_coefs=0", "solver.n_nonzero_coefs"),
        ("solver.n_nonzero_coefs=201", "solver.n_nonzero_coefs"),
        ("solver.epsilon=-1", "solver.epsilon"),
        ("dtype=float16", "dtype"),
        ("device=tpu", "device"),
        ("target.image=/nonexistent.png", "target.image"),
        ("denoiser.n_iter=0", "denoiser.n_iter"),
        ("denoiser.sigma=-1", "denoiser.sigma"),
        ("denoiser.block_size=17", "denoiser.block_size"),
        ("atmosphere.std=-1", "atmosphere.std"),
        ("atmosphere.emitters=facets", "atmosphere.emitters"),
        ("noise=gaussian,noise.relative=-0.1", "noise.relative"),
        ("solver=tv,solver.max_iter=0", "solver.max_iter"),
        ("solver=pnp,solver.init=random", "solver.init"),
        ("solver=pnp,solver.denoiser.gain=0", "solver.denoiser.gain"),
    ],
)
def test_bad_config_names_the_field_and_leaves_only_a_failed_status(tmp_path, override, field):
    with pytest.raises(ValueError, match=rf"^{field}:"):
        run_experiment(cfg_of(*SMALL, *override.split(",")), tmp_path)
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["status"] == "failed" and field in saved["error"]
    assert not (tmp_path / "arrays.npz").exists()
    assert not list(tmp_path.glob(".*tmp"))


def test_non_square_image_is_refused(tmp_path):
    from PIL import Image

    Image.fromarray(np.zeros((10, 12), np.uint8)).save(tmp_path / "r.png")
    with pytest.raises(ValueError, match="target.image: image is 10×12"):
        run_experiment(cfg_of(*SMALL, f"target.image={tmp_path / 'r.png'}"), tmp_path / "out")


def test_console_script_runs_and_exits_2_on_bad_config(tmp_path):
    """A run in a process of its own exits 0; a bad value exits 2 naming it (through ``main()`` in
    this process: a bad value's exit status in a process of its own is test_observations.py's)."""
    from conftest import run_cli

    exe = [sys.executable, "-m", "cssat.app"]
    env = {**os.environ, "HYDRA_FULL_ERROR": "1"}
    ok = subprocess.run(exe + SMALL + ["denoiser=none", f"hydra.run.dir={tmp_path / 'run'}"], capture_output=True, text=True,
                        env=env, cwd=tmp_path, timeout=300)
    assert ok.returncode == 0, ok.stderr
    assert "sim1: PSNR" in ok.stdout + ok.stderr
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["status"] == "ok"
    code, lines = run_cli(SMALL + ["cs.m=-3", f"hydra.run.dir={tmp_path / 'bad'}"], tmp_path)
    assert code == 2
    assert any("cs.m: must be in [1, 256], got -3" in ln for ln in lines), lines


def test_multirun_sweep_records_a_failed_job_and_goes_on(tmp_path):
    exe = [sys.executable, "-m", "cssat.app", "-m"]
    sweep = tmp_path / "sweep"
    res = subprocess.run(exe + SMALL[:1] + ["threads=1", "denoiser=none", "cs.m=0,120", f"hydra.sweep.dir={sweep}"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert res.returncode == 1, res.stderr  # every job ran, the summary is written, and the sweep says it failed
    assert (sweep / "summary.csv").exists()
    status = {json.loads((sweep / str(i) / "metrics.json").read_text())["status"] for i in (0, 1)}
    assert status == {"failed", "ok"}
    bad = json.loads((sweep / "0" / "metrics.json").read_text())
    assert bad["error"].startswith("FieldError: cs.m: must be in [1, 256]")


def test_lightcurve_experiment_end_to_end(tmp_path):
    cfg = cfg_of("experiment=lightcurve", "scenario.n_steps=40", "scenario.step_s=1800", "render.size=24",
                 "model=tess_like", "threads=1")
    metrics = run_experiment(cfg, tmp_path)
    assert metrics["status"] == "ok" and metrics["n_steps"] == 40 and metrics["psnr"] is None
    assert metrics["pixel_sum_relative_error"] < 1e-12
    for fig in ("fig4_lightcurve.png", "fig5_atmosphere.png"):
        assert (tmp_path / "figures" / fig).stat().st_size > 5000
    arrays = np.load(tmp_path / "arrays.npz")
    assert arrays["flux"].shape == (40,) and arrays["mark_images"].shape == (5, 24, 24)
    # numbers, not strings: seconds since the epoch stored beside them; masks as booleans
    assert arrays["times"].dtype == np.float64 and str(arrays["epoch_utc"]).startswith("2020-04-01T00:00")
    np.testing.assert_allclose(arrays["times"], np.arange(40) * 1800.0)
    assert arrays["lit"].dtype == bool and arrays["above_horizon"].dtype == bool
    np.testing.assert_array_equal(arrays["lit"], arrays["flux"] > 0)
    # the phase angle, independently: the Sun and the observer as seen from the satellite (GCRS)
    from cssat.experiments.scene import build_scenario

    sc = build_scenario(cfg)
    to_sun, to_obs = sc.r_sun - sc.r_sat, sc.r_obs - sc.r_sat
    cosang = (to_sun * to_obs).sum(1) / np.linalg.norm(to_sun, axis=1) / np.linalg.norm(to_obs, axis=1)
    np.testing.assert_allclose(arrays["phase_angle_deg"], np.degrees(np.arccos(cosang)), atol=1e-9)
    # the light curve as a CSV that numpy (and so pandas/astropy) reads as is
    table = np.genfromtxt(tmp_path / "lightcurve.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert table.dtype.names == ("time_utc", "flux_W_m2", "magnitude", "phase_angle_deg", "sunlit", "elevation_deg")
    np.testing.assert_allclose(table["flux_W_m2"], arrays["flux"], rtol=1e-12)
    assert str(table["time_utc"][1]) == "2020-04-01T00:30:00Z"
    with pytest.raises(ValueError, match="model.name"):
        run_experiment(cfg_of("experiment=lightcurve", "model.name=hubble"), tmp_path / "bad")


def test_sim2_small_recovers_phi_and_uses_the_reference_cache(tmp_path):
    over = ["experiment=sim2", "target.size=16", "cs.m=200", "threads=1", "dtype=float64",
            f"cache_dir={tmp_path / 'cache'}", "denoiser.n_iter=3"]
    a = run_experiment(cfg_of(*over), tmp_path / "a")
    assert a["reference_n"] == 256 and not a["reference_cached"]
    assert a["phi_relative_error"] < 1e-8  # Eq. 24 is exact up to round-off
    assert len(list((tmp_path / "cache").glob("refs-*.npy"))) == 1
    b = run_experiment(cfg_of(*over), tmp_path / "b")
    assert b["reference_cached"] and b["psnr"] == a["psnr"] and b["psnr_denoised"] == a["psnr_denoised"]
    arrays = np.load(tmp_path / "a" / "arrays.npz")
    assert arrays["denoised"].shape == (16, 16)
    assert (tmp_path / "a" / "figures" / "fig11_sim2.png").stat().st_size > 1000
    # a different reference seed is a different cache entry
    run_experiment(cfg_of(*over, "reference.seed=5"), tmp_path / "c")
    assert len(list((tmp_path / "cache").glob("refs-*.npy"))) == 2


def test_sim3_small_runs_repeats_and_3d_denoising(tmp_path):
    over = ["experiment=sim3", "target.size=16", "cs.m=200", "threads=1", "reference.pool=300",
            "reference.n=200", "reference.repeats=3", "reference.n_nonzero_coefs=20",
            f"cache_dir={tmp_path / 'cache'}", "denoiser.n_iter=2", "denoiser3d.n_iter=2"]
    met = run_experiment(cfg_of(*over), tmp_path)
    assert len(met["repeat_psnr"]) == 3 and len(met["repeat_psnr_denoised_3d"]) == 3
    assert met["repeat_estimate_mean_atoms"][0] <= 20
    arrays = np.load(tmp_path / "arrays.npz")
    assert arrays["reconstructions"].shape == (3, 16, 16) and arrays["denoised_3d"].shape == (3, 16, 16)
    # the metrics are those of the saved images (PSNR by its formula, range 1)
    def db(a):
        return 10 * np.log10(1 / np.mean((a - arrays["truth"]) ** 2))

    np.testing.assert_allclose(met["repeat_psnr"], [db(a) for a in arrays["reconstructions"]], rtol=1e-9)
    np.testing.assert_allclose(met["repeat_psnr_denoised_3d"], [db(a) for a in arrays["denoised_3d"]], rtol=1e-9)
    assert met["psnr"] == pytest.approx(db(arrays["reconstructions"][met["best_repeat"]]), rel=1e-9)
    assert all(met["psnr"] >= db(a) for a in arrays["reconstructions"])  # the headline is the best repeat
    assert met["psnr_denoised"] == pytest.approx(db(arrays["denoised_2d"][met["best_repeat"]]), rel=1e-9)
    for fig in ("fig13_sim3_results.png", "fig14_sim3_denoised.png"):
        assert (tmp_path / "figures" / fig).stat().st_size > 1000
    # the minimum-norm baseline is reported beside the sparse estimate
    assert 0 < met["phi_relative_error_min_norm_mean"] and "psnr_min_norm_mean" in met


def test_sim3_sizes_follow_the_target_size():
    """At 64² the rules give the paper's Simulation 3 (N_ref = 3277, a pool of 8000, T0 = 200,
    the baseline on all 9 repeats); target.size=128 alone scales them: 0.8 n², the pool with n²,
    T0 = 71, the baseline on the first repeat."""
    from cssat.experiments.build import build
    from cssat.experiments.forward import measurements

    for size, want in ((64, (3277, 3277, 8000, 200, 9)), (128, (13107, 13107, 32000, 71, 1))):
        cfg = cfg_of("experiment=sim3", f"target.size={size}")
        N = size * size
        m = measurements(cfg.cs, N)
        est = build(cfg.reference, "reference")
        (n_ref, pool), (t0, tol) = est.sizes(N), est.settings(N)
        assert (m, n_ref, pool, t0, est.baseline_repeats(m, N)) == want and tol is None


def test_sim3_baseline_on_the_first_repeat_only(tmp_path):
    over = ["experiment=sim3", "target.size=16", "cs.m=200", "threads=1", "reference.pool=300", "reference.n=200",
            "reference.repeats=2", "reference.n_nonzero_coefs=10", f"cache_dir={tmp_path / 'cache'}",
            "denoiser=none", "denoiser@denoiser3d=none"]
    met = run_experiment(cfg_of(*over, "reference.baseline=first"), tmp_path / "a")
    first, second = met["repeat_psnr_min_norm"]
    assert second is None and met["psnr_min_norm_mean"] == first and met["baseline_repeats"] == 1
    assert len(met["repeat_psnr"]) == 2 and None not in met["repeat_psnr"]
    both = run_experiment(cfg_of(*over, "reference.baseline=true"), tmp_path / "b")
    assert both["repeat_psnr_min_norm"][0] == first and both["repeat_psnr_min_norm"][1] is not None
    with pytest.raises(ConfigError, match=r"reference.baseline: expected one of \[True, False, 'first', 'auto'\]"):
        run_experiment(cfg_of(*over, "reference.baseline=some"), tmp_path / "c")


@pytest.mark.parametrize("exp", ["sim2", "sim3"])
def test_memory_estimate_stops_a_run_that_does_not_fit(tmp_path, exp):
    with pytest.raises(ValueError, match=r"^memory: .*GB"):
        run_experiment(cfg_of(f"experiment={exp}", "memory_limit_gb=0.5", "threads=1"), tmp_path)
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["status"] == "failed" and not (tmp_path / "arrays.npz").exists()


@pytest.mark.parametrize("solver", ["l1", "tv"])
def test_sim1_with_convex_solvers(tmp_path, solver):
    met = run_experiment(cfg_of(*SMALL, f"solver={solver}", "denoiser=none"), tmp_path)
    assert met["solver"] == solver and met["solver_iterations"] >= 1
    assert met["psnr"] > flat_psnr(np.load(tmp_path / "arrays.npz")) + 5
    with pytest.raises(ValueError, match="^solver.lam"):
        run_experiment(cfg_of(*SMALL, f"solver={solver}", "solver.lam=-1"), tmp_path / "bad")


def test_sim1_with_plug_and_play(tmp_path):
    met = run_experiment(cfg_of(*SMALL, "solver=pnp", "solver.max_iter=4", "solver.denoiser.n_iter=1", "denoiser=none"), tmp_path)
    assert met["solver"] == "pnp" and met["solver_iterations"] == 4
    assert met["psnr"] > flat_psnr(np.load(tmp_path / "arrays.npz")) + 3
    assert met["solver_denoiser"] == "sparse_ksvd"
    # any denoiser group option is PnP's prior
    tv = run_experiment(cfg_of(*SMALL, "solver=pnp", "solver.max_iter=4", "denoiser@solver.denoiser=tv", "denoiser=none"),
                        tmp_path / "tv")
    assert tv["solver_denoiser"] == "tv" and tv["psnr"] != met["psnr"]


def test_solvers_experiment_compares_every_solver(tmp_path):
    cfg = cfg_of("experiment=solvers", "target.size=16", "grid.axes.0.values=[0.46875,0.78125]", "threads=1",
                 "grid_options.pnp.max_iter=3", "grid_options.pnp.denoiser.n_iter=1", "denoiser.n_iter=2")
    met = run_experiment(cfg, tmp_path)
    with open(tmp_path / "comparison.csv", newline="") as f:
        import csv

        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 5 and {r["solver"] for r in rows} == {"omp", "omp_ksvd", "l1", "tv", "pnp"}
    arrays = np.load(tmp_path / "arrays.npz")
    db = {k: 10 * np.log10(1 / np.mean((arrays[k] - arrays["truth"]) ** 2)) for k in arrays.files if k != "truth"}
    for r in rows:  # the table and the metrics are the PSNR of the saved images
        assert float(r["psnr"]) == pytest.approx(db[f"{r['solver']}_m{r['m']}"], rel=1e-9)
        assert met[f"psnr_{r['solver']}_m{r['m']}"] == pytest.approx(float(r["psnr"]))
    # the headline is the best image at the last m
    assert met["psnr"] == pytest.approx(max(v for k, v in db.items() if k.endswith("_m200")), rel=1e-9)
    assert met["psnr"] == pytest.approx(db[f"{met['best_solver']}_m200"], rel=1e-9)
    # the paper's pipeline is OMP's image, denoised
    assert not np.array_equal(arrays["omp_ksvd_m200"], arrays["omp_m200"])
    assert (tmp_path / "figures" / "solvers.png").stat().st_size > 1000


@pytest.mark.parametrize("exp", ["sim2", "sim3"])
def test_reference_experiments_take_any_solver(tmp_path, exp):
    over = [f"experiment={exp}", "target.size=16", "cs.m=200", "threads=1", "solver=tv",
            f"cache_dir={tmp_path / 'cache'}", "denoiser=none"]
    if exp == "sim2":
        over.append("dtype=float64")
    else:
        over += ["reference.pool=300", "reference.n=200", "reference.repeats=2", "reference.n_nonzero_coefs=10",
                 "reference.baseline=false", "denoiser@denoiser3d=none"]
    met = run_experiment(cfg_of(*over), tmp_path / "run")
    assert met["solver"] == "tv"
    assert met["psnr"] > (15 if exp == "sim2" else 10)


def test_the_app_returns_the_optimized_metric(tmp_path):
    from cssat.app import task

    value = task(cfg_of(*SMALL, "denoiser=none"), tmp_path / "a")
    saved = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert value == saved["psnr"]
    assert task(cfg_of(*SMALL, "denoiser=none", "optimized_metric=ssim"), tmp_path / "b") == saved["ssim"]
    assert task(cfg_of(*SMALL, "denoiser=none", "optimized_metric=null"), tmp_path / "c") is None
    assert task(cfg_of(*SMALL, "cs.m=0"), tmp_path / "d", multirun=True) is None  # a failed job in a sweep


@pytest.mark.parametrize("overrides", [
    ("target.size=4096", "cs.m=13225"),                      # Φ and ΦΨ alone would be 1.8 TB
    ("experiment=lightcurve", "render.size=4096"),           # 1437 renders of 4096² would be 193 GB
    ("experiment=solvers", "target.size=4096", "grid.axes.0.values=[0.000788]"),
])
def test_every_experiment_refuses_a_run_that_does_not_fit_before_any_work(tmp_path, overrides, monkeypatch):
    from cssat.experiments import context

    entered, stage = [], context.Run.stage
    monkeypatch.setattr(context.Run, "stage", lambda self, name: entered.append(name) or stage(self, name))
    with pytest.raises(ValueError, match=r"^memory: this run needs about [0-9.]+ GB"):
        run_experiment(cfg_of(*overrides, "threads=1"), tmp_path)
    assert set(entered) <= {"setup"}  # refused while planning: no stage that renders or allocates ran
    assert json.loads((tmp_path / "metrics.json").read_text())["status"] == "failed"


def test_realism_experiment_maps(tmp_path):
    cfg = cfg_of("experiment=realism", "target.size=12", "cs.m=115", "threads=1", "grid.axes.0.values=[0.058,60]",
                 "grid.axes.1.values=[-2,14]", "atmosphere.n_radial=32", "atmosphere.n_angular=6", "atmosphere.n_layers=4",
                 "grid_options.tv.max_iter=300", "noise.systematic=0", "~grid.axes.0.cells.geo_moving",
                 "~grid.axes.0.cells.leo_pass", "~grid.axes.2.cells.tv_phi_unknown")
    met = run_experiment(cfg, tmp_path)
    with open(tmp_path / "realism.csv", newline="") as f:
        import csv

        rows = list(csv.DictReader(f))
    assert len(rows) == 3 * 2 * 3  # (paper + 2 sizes) × 2 magnitudes × 3 solvers (flux, omp, tv)
    for fig in ("realism_flux.png", "realism_omp.png", "realism_tv.png", "realism_curves.png", "realism_information.png"):
        assert (tmp_path / "figures" / fig).stat().st_size > 5000
    # the physics: at GEO one transmission for all pixels; at 60″ the pixels decorrelate
    assert met["phi_effective_rank_centered_0.058"] <= 2 < met["phi_effective_rank_centered_60"]
    assert met["phi_effective_rank_0.058"] == 1  # Φ itself: its common row holds > 99 % of the energy
    assert met["phi_effective_rank_centered_paper"] >= 0.75 * 115  # Gaussian: (nearly) full rank
    by = {(r["solver"], r["arcsec"], float(r["magnitude"])): r for r in rows}
    # brighter is better, and for the paper's Φ the image is recovered at V = -2
    assert float(by[("tv", "paper", -2.0)]["psnr"]) > float(by[("tv", "paper", 14.0)]["psnr"]) > met["psnr_flux_only"]
    assert met["psnr"] == max(float(r["psnr"]) for r in rows if r["arcsec"] == "60" and float(r["magnitude"]) == -2.0)
    # the flux-only reference: the PSNR of the flat image at the truth's mean
    from cssat.data import load_target

    t = load_target("tess", 12)
    assert met["psnr_flux_only"] == pytest.approx(10 * np.log10(1 / np.mean((t - t.mean()) ** 2)), rel=1e-9)
    for r in rows:  # every cell under the flux is labelled; TV at the noise never is (the flat image is its λ = ∞)
        assert (r["below_flux_only"] == "True") == (float(r["psnr"]) < met["psnr_flux_only"] - 0.1)
        if r["solver"] == "tv" and r["arcsec"] != "paper":
            assert r["below_flux_only"] == "False", r
        # V = -2 puts ~2e9 e⁻ in the brightest pixel of a 1 m telescope in 1 s: over a 1e5 e⁻ full well
        assert (r["unreachable"] == "True") == (float(r["magnitude"]) == -2.0)
    # the information bound: at GEO no mode but the flux is measurable, whatever the brightness
    assert all(int(r["info_modes"]) == 0 for r in rows if r["arcsec"] == "0.058")
    assert int(by[("tv", "paper", -2.0)]["info_modes"]) > 0


def test_cs_ratio_lets_the_image_size_change_alone(tmp_path):
    from cssat.experiments.forward import measurements

    # the defaults are the paper's m, exactly
    for exp, m, n in (("sim1", 13225, 128), ("sim2", 8192, 128), ("sim3", 3277, 64), ("realism", 819, 32)):
        assert measurements(cfg_of(f"experiment={exp}").cs, n * n) == m
    met = run_experiment(cfg_of("target.size=16", "threads=1", "denoiser=none"), tmp_path / "a")  # no cs.m given
    assert met["m"] == round(0.80718994140625 * 256) == 207
    assert run_experiment(cfg_of("target.size=16", "threads=1", "denoiser=none", "cs.ratio=0.25"), tmp_path / "b")["m"] == 64
    assert run_experiment(cfg_of("target.size=16", "threads=1", "denoiser=none", "cs.m=100", "cs.ratio=0.25"),
                          tmp_path / "c")["m"] == 100  # cs.m wins
    with pytest.raises(ValueError, match=r"^cs.ratio"):
        run_experiment(cfg_of("target.size=16", "threads=1", "cs.ratio=1.5"), tmp_path / "d")
