"""The one pipeline: every experiment runs with every option of every group (not only composes),
stage times add up, grids are cells of their own, solvers take the problem object."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_module

import cssat.conf
from cssat.experiments import run_experiment

CONF = Path(cssat.conf.__file__).parent
EXPERIMENTS = sorted(p.stem for p in (CONF / "experiment").glob("*.yaml"))
GROUPS = ("atmosphere", "noise", "solver", "denoiser")

#: each experiment at a tiny size (seconds a run)
TINY = {
    "sim1": ["target.size=12", "cs.m=100"],
    "sim2": ["target.size=12", "cs.m=80", "dtype=float64"],
    "sim3": ["target.size=12", "cs.m=80", "reference.pool=150", "reference.n=80", "reference.repeats=2",
             "reference.n_nonzero_coefs=10", "denoiser3d.n_iter=1"],
    "solvers": ["target.size=12", "grid.axes.0.values=[0.5]", "grid_options.pnp.max_iter=2",
                "grid_options.pnp.denoiser.n_iter=1", "grid_options.tv.max_iter=50", "grid_options.l1.max_iter=50"],
    "realism": ["target.size=12", "grid.axes.0.values=[0.058,60]", "grid.axes.1.values=[8]", "grid_options.tv.max_iter=50",
                "~grid.axes.0.cells.leo_pass"],  # its 160 samples need N >= 160
    "lightcurve": ["scenario.n_steps=3", "render.size=8"],
    "inversion": ["nights.n=2", "nights.fit=1", "scenario.step_s=900", "inversion.spin=known", "inversion.n_normals=64"],
    "inversion_tumbling": ["nights.n=2", "nights.fit=1", "scenario.step_s=900", "inversion.spin=known",
                           "inversion.n_normals=64"],
    "occultation": ["silhouette.size=24", "silhouette.pixel_m=0.5", "invert.iters=5"],
}
#: the groups an experiment of its own module does not use (its matrix is the groups it uses)
UNUSED = {"inversion": ("atmosphere", "solver", "denoiser"), "inversion_tumbling": ("atmosphere", "solver", "denoiser"),
          "occultation": ("atmosphere", "noise", "solver", "denoiser")}
#: options made quick (their numbers are not what these tests check)
QUICK = {
    ("solver", "pnp"): ["solver.max_iter=2", "solver.denoiser.n_iter=1"],
    ("solver", "tv"): ["solver.max_iter=50"], ("solver", "l1"): ["solver.max_iter=50"],
    ("solver", "landweber"): ["solver.max_iter=50"],
    ("denoiser", "sparse_ksvd"): ["denoiser.n_iter=1"], ("denoiser", "sparse_ksvd_pnp"): ["denoiser.n_iter=1"],
    ("atmosphere", "phase_screen"): ["atmosphere.n_radial=16", "atmosphere.n_angular=4", "atmosphere.n_layers=2"],
    ("atmosphere", "phase_screen_converged"): ["atmosphere.n_radial=16", "atmosphere.n_angular=4", "atmosphere.n_layers=2"],
}


def options(group):
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


def cfg_of(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


CASES = [(e, g, o) for e in EXPERIMENTS for g in GROUPS for o in options(g) if g not in UNUSED.get(e, ())]


@pytest.mark.parametrize("experiment, group, option", CASES, ids=[f"{e}-{g}={o}" for e, g, o in CASES])
def test_every_experiment_runs_with_every_option_of_every_group(tmp_path, experiment, group, option):
    over = [f"experiment={experiment}", f"{group}={option}", "threads=1", f"cache_dir={tmp_path / 'cache'}",
            *TINY[experiment], *QUICK.get((group, option), [])]
    if experiment == "realism" and group != "atmosphere":  # realism's own atmosphere, made quick
        over += QUICK[("atmosphere", "phase_screen")]
    met = run_experiment(cfg_of(*over), tmp_path / "run")
    assert met["status"] == "ok"
    saved = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert saved["status"] == "ok" and saved["files"]
    if experiment != "lightcurve" and not experiment.startswith("inversion"):
        assert math.isfinite(met["psnr"])
    # every stage's time is a seconds_<stage> key: together they are the run's time
    stages = sum(v for k, v in saved.items() if k.startswith("seconds_") and k != "seconds_startup")
    assert 0.9 * saved["seconds"] - 0.05 <= stages <= saved["seconds"] + 1e-6, (stages, saved["seconds"])


def test_grid_cells_are_copies_with_their_own_settings():
    """A cell's settings change that cell only; the base config and the other cells keep theirs."""
    from cssat.experiments.grid import cells

    cfg = cfg_of("experiment=realism", "grid.axes.0.values=[0.058]", "grid.axes.1.values=[2,14]")
    out = cells(cfg)
    assert len(out) == 4 * 2 * 4  # (paper, geo_moving, leo_pass, 0.058) × 2 magnitudes × 4 solvers
    assert cfg.noise.magnitude == 12.0 and cfg.atmosphere._target_.endswith("PhaseScreenAtmosphere")
    mags = {(lab["arcsec"], lab["magnitude"]): c.noise.magnitude for lab, c in out}
    assert mags[("paper", 2)] == 2 and mags[("paper", 14)] == 14
    paper = [c for lab, c in out if lab["arcsec"] == "paper"]
    assert all(c.atmosphere._target_.endswith("GaussianAtmosphere") for c in paper)
    assert all(c.solver.lam == "discrepancy" for lab, c in out if lab["solver"] == "tv")
    assert all(c.solver.epsilon == "discrepancy" for lab, c in out if lab["solver"] == "omp")
    assert all(c.solver._target_ == "cssat.recon.FluxOnly" for lab, c in out if lab["solver"] == "flux")
    assert cfg.solver._target_ != "cssat.recon.FluxOnly"  # the base config keeps its own solver
    unknown = [c for lab, c in out if lab["solver"] == "tv_phi_unknown"]
    assert all(c.reference._target_.endswith("Statistics") for c in unknown)
    assert all(c.reference._target_.endswith("Known") for lab, c in out if lab["solver"] != "tv_phi_unknown")
    moving = {lab["arcsec"]: c for lab, c in out if lab["solver"] == "tv"}
    assert moving["geo_moving"].forward._target_.endswith("MovingScene") and moving["geo_moving"].forward.dtype == "float64"
    assert moving[0.058].forward._target_.endswith("PixelSensing") and moving[0.058].geometry.slew_rad_s == 0
    assert moving["leo_pass"].geometry.slew_rad_s == 0.0132 and moving["leo_pass"].cs.m == 160


def test_the_solver_comparison_shares_each_measurement(tmp_path, monkeypatch):
    """One Φ per m, whatever the number of solvers (the draw is the expensive part at 128²)."""
    from cssat.experiments import forward

    draws = []
    orig = forward.PixelSensing.operator

    def counted(self, *args, **kwargs):
        draws.append(args[2])
        return orig(self, *args, **kwargs)

    monkeypatch.setattr(forward.PixelSensing, "operator", counted)
    met = run_experiment(cfg_of("experiment=solvers", *TINY["solvers"], "grid.axes.0.values=[0.3,0.6]", "threads=1"),
                         tmp_path)
    assert draws == [round(0.3 * 144), round(0.6 * 144)]
    assert sum(k.startswith("psnr_") and k.endswith(f"_m{round(0.6 * 144)}") for k in met) == 5


def test_solvers_take_a_measurement_as_their_problem():
    """``solver(measurement, y)`` (deepinv style) and ``solver(phi, y, shape)`` agree."""
    from cssat.data import load_target
    from cssat.physics import Measurement
    from cssat.recon import OMP, TV, Landweber, Problem
    from cssat.sparse import GaussianSensing

    x = torch.as_tensor(load_target("tess", 16), dtype=torch.float64)
    phi = GaussianSensing(200, 256, seed=0, dtype=torch.float64)
    meas = Measurement(phi, x_shape=(16, 16))
    y = meas(x)
    for solver in (OMP(), TV(max_iter=50), Landweber(max_iter=50)):
        a, _ = solver(meas, y)
        b, _ = solver(phi, y, (16, 16))
        c, _ = solver(Problem(phi, (16, 16)), y)
        assert a.shape == (16, 16) and torch.equal(a, b) and torch.equal(a, c)
    with pytest.raises(ValueError, match=r"^shape: the operator has 256 columns but no shape"):
        OMP()(Measurement(phi), y)
    with pytest.raises(ValueError, match=r"^shape: \(8, 8\) has 64 values but the operator has 256 columns"):
        OMP()(phi, y, (8, 8))


def test_projected_landweber_reaches_scipy_nnls_and_the_runner_owns_the_loop():
    """Converged, projected Landweber is the non-negative least-squares solution (scipy's NNLS);
    the shared runner records the objective ½‖Ax − y‖², stops on the relative change and on a
    callback."""
    from scipy.optimize import nnls

    from cssat.sparse.solvers import landweber

    g = torch.Generator().manual_seed(0)
    A = torch.randn(40, 16, generator=g, dtype=torch.float64)
    y = A @ (torch.rand(16, generator=g, dtype=torch.float64) - 0.3)  # some entries < 0: the bound binds
    x, info = landweber(A, y, max_iter=20000, rtol=1e-13, return_info=True)
    ref, _ = nnls(A.numpy(), y.numpy())
    np.testing.assert_allclose(x.numpy(), ref, atol=1e-8)
    assert info.converged and (x >= 0).all() and (torch.as_tensor(ref) == 0).any()
    r = A @ x - y
    assert info.objective[-1] == pytest.approx(float(0.5 * (r * r).sum()), rel=1e-6, abs=1e-12)
    _, short = landweber(A, y, max_iter=500, return_info=True, callback=lambda k, alg: k == 7)
    assert short.n_iter == 7 and not short.converged and len(short.objective) == 1  # k = 1 only


def test_numba_keeps_one_thread_at_threads_1():
    """At threads=1 a numba OMP call leaves torch and numba on one thread (numba's OpenMP layer
    used to reset the process's count to the cores)."""
    import subprocess
    import sys

    code = ("import torch; torch.set_num_threads(1)\n"
            "from cssat.sparse import batch_omp\nimport numba\n"
            "for _ in range(2): batch_omp(torch.randn(64, 100), torch.randn(5, 64), n_nonzero_coefs=5, backend='numba')\n"
            "print(torch.get_num_threads(), numba.get_num_threads())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1", "1"]
