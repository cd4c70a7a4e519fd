"""The one pipeline: every experiment runs at its tiny size, every option of every group takes
effect (its setting recorded, its stage's output changed), stage times add up, grids are cells of
their own, solvers take the problem object."""

import functools
import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_module

import cssat.conf
from cssat.experiments import run_experiment
from cssat.smoke import TINY

CONF = Path(cssat.conf.__file__).parent
EXPERIMENTS = sorted(p.stem for p in (CONF / "experiment").glob("*.yaml"))
GROUPS = ("atmosphere", "noise", "solver", "denoiser")

#: the groups each forward model reads (measured: an option of any other group leaves every array
#: and table it writes unchanged — the light curve reconstructs nothing, the inversions have no
#: atmosphere or image solver, the occultation has its own forward model and solver); a model not
#: listed is tried with none
READS_BY_MODEL = {"PixelSensing": GROUPS, "SceneLightCurve": ("atmosphere", "noise"), "EGILightCurve": ("noise",),
                  "Shadow": (), "Observed": ()}


def _forward_model(experiment):
    """The class name of the forward model ``conf/experiment/<experiment>.yaml`` composes."""
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=[f"experiment={experiment}"]).forward._target_.rsplit(".", 1)[-1]


#: the groups each experiment reads: its forward model's (derived from conf/experiment/*.yaml)
READS = {e: READS_BY_MODEL.get(_forward_model(e), ()) for e in EXPERIMENTS}
#: options made quick (their numbers are not what these tests check)
QUICK = {
    ("solver", "pnp"): ["solver.max_iter=2", "solver.denoiser.n_iter=1"],
    ("solver", "tv"): ["solver.max_iter=50"], ("solver", "l1"): ["solver.max_iter=50"],
    ("solver", "landweber"): ["solver.max_iter=50"],
    ("denoiser", "sparse_ksvd_pnp"): ["denoiser.n_iter=1"],
}
#: a phase-screen atmosphere made quick: the settings realism's tiny size gives its own
QUICK[("atmosphere", "phase_screen")] = QUICK[("atmosphere", "phase_screen_converged")] = [
    x for x in TINY["realism"] if x.startswith("atmosphere.")]
#: the name metrics.json records for an option whose YAML is a variant of another's class
RECORDED = {("atmosphere", "phase_screen_converged"): "phase_screen", ("noise", "photometric_object"): "photometric",
            ("denoiser", "sparse_ksvd_pnp"): "sparse_ksvd", ("solver", "tv_shadow"): "tv"}
#: which array of sim1 a group's option changes first
CHANGES = {"atmosphere": "y", "noise": "y", "solver": "reconstruction", "denoiser": "denoised"}
#: the option each other experiment is tried with, per group it reads (one that is not its default)
OTHER = {"atmosphere": ("lognormal", "gaussian"), "noise": ("gaussian", "photometric"), "solver": ("landweber", "tv"),
         "denoiser": ("wavelet", "none")}


def options(group):
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


def cfg_of(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def tiny(experiment, group=None):
    """The experiment's tiny overrides; realism's phase-screen atmosphere made quick unless the
    atmosphere is what the case sets."""
    over = [x for x in TINY[experiment] if not x.startswith("atmosphere.")]
    if experiment == "realism" and group != "atmosphere":
        over += QUICK[("atmosphere", "phase_screen")]
    return [f"experiment={experiment}", "threads=1", *over]


@functools.lru_cache(maxsize=None)
def default_option(experiment, group):
    """The option of ``group`` that ``experiment`` composes by default (Hydra's runtime choice)."""
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"experiment={experiment}"], return_hydra_config=True)
    return cfg.hydra.runtime.choices[group]


def fingerprint(run_dir):
    """``{file: {array: hash}}`` of the run's arrays and tables (figures left out)."""
    out = {}
    for f in sorted(Path(run_dir).rglob("*")):
        if f.suffix == ".npz":
            with np.load(f) as a:
                out[f.name] = {k: hashlib.blake2b(a[k].tobytes(), digest_size=16).hexdigest() for k in a.files}
        elif f.suffix == ".csv":
            out[f.name] = hashlib.blake2b(f.read_bytes(), digest_size=16).hexdigest()
    return out


@pytest.fixture(scope="module")
def default_runs(tmp_path_factory):
    """Each experiment's default run at its tiny size, run once for the module: ``{name: dir}``."""
    root, done = tmp_path_factory.mktemp("defaults"), {}

    def get(experiment):
        if experiment not in done:
            d = root / experiment
            run_experiment(cfg_of(*tiny(experiment), f"cache_dir={root / 'cache'}"), d)
            done[experiment] = d
        return done[experiment]

    return get


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_runs_at_its_tiny_size(default_runs, experiment):
    """A complete result set; every stage's time is a ``seconds_<stage>`` key, together the run's time."""
    saved = json.loads((default_runs(experiment) / "metrics.json").read_text())
    assert saved["status"] == "ok" and saved["files"]
    if experiment in ("sim1", "sim2", "sim3", "solvers", "realism"):
        assert any(k.startswith("psnr") and isinstance(v, float) and math.isfinite(v) for k, v in saved.items())
    stages = sum(v for k, v in saved.items() if k.startswith("seconds_") and k != "seconds_startup")
    assert 0.9 * saved["seconds"] - 0.05 <= stages <= saved["seconds"] + 1e-6, (stages, saved["seconds"])


SIM1_CASES = [(g, o) for g in GROUPS for o in options(g)]


@pytest.mark.parametrize("group, option", SIM1_CASES, ids=[f"{g}={o}" for g, o in SIM1_CASES])
def test_every_option_takes_effect(tmp_path, default_runs, group, option):
    """Each option of each group, once, on sim1 (which reads all four): its name is recorded in
    metrics.json, and the array its stage makes differs from the default run's — or, for the
    default option, equals it bit for bit (same config and seed, same numbers)."""
    base = default_runs("sim1")
    is_default = option == default_option("sim1", group)
    over = [*tiny("sim1"), f"{group}={option}", f"cache_dir={tmp_path / 'cache'}",
            *([] if is_default else QUICK.get((group, option), []))]
    met = run_experiment(cfg_of(*over), tmp_path / "run")
    assert met["status"] == "ok"
    assert met[group] == RECORDED.get((group, option), option)
    key = CHANGES[group]
    with np.load(base / "arrays.npz") as a, np.load(tmp_path / "run" / "arrays.npz") as b:
        same = np.array_equal(a[key], b[key])
    assert same == is_default, f"{group}={option}: {key} {'equals' if same else 'differs from'} the default run's"


OTHER_CASES = [(e, g) for e in EXPERIMENTS if e != "sim1" for g in READS[e]]


@pytest.mark.parametrize("experiment, group", OTHER_CASES, ids=[f"{e}-{g}" for e, g in OTHER_CASES])
def test_every_experiment_reads_its_groups(tmp_path, default_runs, experiment, group):
    """Each other experiment honours each group it reads: one option that is not its default
    changes what it writes (its arrays or tables) and is recorded where the experiment records it."""
    option = next(o for o in OTHER[group] if o != default_option(experiment, group))
    met = run_experiment(cfg_of(*tiny(experiment, group), f"{group}={option}", *QUICK.get((group, option), []),
                                f"cache_dir={tmp_path / 'cache'}"), tmp_path / "run")
    assert met["status"] == "ok"
    if group in met:
        assert met[group] == RECORDED.get((group, option), option)
    assert fingerprint(tmp_path / "run") != fingerprint(default_runs(experiment)), f"{group}={option} changed nothing"


def test_the_groups_an_experiment_does_not_read_change_nothing(tmp_path, default_runs):
    """The other side of READS: the light curve with another solver and denoiser writes the same
    table (so those cases are not in the option matrix)."""
    met = run_experiment(cfg_of(*tiny("lightcurve"), "solver=tv", "denoiser=wavelet"), tmp_path / "run")
    assert met["status"] == "ok"
    assert fingerprint(tmp_path / "run") == fingerprint(default_runs("lightcurve"))


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
