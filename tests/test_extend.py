"""Extending cssat without touching it: an atmosphere of your own (one module — here: this test
file — and one YAML on Hydra's search path), an experiment that recombines the pipeline's stages
(one YAML and nothing else), and an experiment module of your own."""

import json

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_module

from cssat.experiments import run_experiment
from cssat.physics import Atmosphere
from cssat.sparse import MatrixOperator


class SignAtmosphere(Atmosphere):
    """±1/√n weights (a Bernoulli sensing matrix), from the seed."""

    name = "sign"

    def operator(self, m, n, *, seed=0, dtype=None, device=None):
        g = torch.Generator().manual_seed(seed)
        w = (torch.randint(0, 2, (m, n), generator=g) * 2 - 1).to(dtype or torch.float32) / n ** 0.5
        return MatrixOperator(w.to(device))


def run(cfg, out_dir):
    """An experiment of one's own: the light curve of the target through the configured
    measurement, and its total flux (``run(cfg, out_dir) -> metrics``)."""
    from cssat.data import load_target
    from cssat.experiments.build import build
    from cssat.physics import Measurement

    n = cfg.target.size
    atm = build(cfg.atmosphere, "atmosphere")
    meas = Measurement(atm.operator(cfg.cs.m, n * n, seed=cfg.seed, dtype=torch.float64), build(cfg.noise, "noise"))
    x = torch.as_tensor(load_target(str(cfg.target.image), n), dtype=torch.float64)
    y = meas(x)
    np.save(out_dir / "y.npy", y.numpy())
    return {"psnr": None, "ssim": None, "flux": float(x.sum()), "y_norm": float(y.norm()), **atm.describe()}


def compose_with(tmp_path, *overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config",
                       overrides=[f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "threads=1", *overrides])


@pytest.fixture
def conf(tmp_path):
    for g in ("atmosphere", "experiment"):
        (tmp_path / "conf" / g).mkdir(parents=True)
    (tmp_path / "conf" / "atmosphere" / "sign.yaml").write_text(f"_target_: {__name__}.SignAtmosphere\n")
    (tmp_path / "conf" / "experiment" / "flux.yaml").write_text(
        "# @package _global_\n"
        f"experiment_name: flux\nexperiment_module: {__name__}\ntarget:\n  size: 16\ncs:\n  m: 50\n")
    # a YAML-only experiment: Simulation 1's stages, Φ estimated from references (Eq. 24), TV
    (tmp_path / "conf" / "experiment" / "mine.yaml").write_text(
        "# @package _global_\ndefaults:\n  - sim1\n  - _self_\n  - override /reference: full_rank\n"
        "  - override /solver: tv\n  - override /denoiser: none\n"
        "target:\n  size: 16\ncs:\n  m: 120\nfigures: [fig11_sim2]\n")
    return tmp_path


def test_an_atmosphere_of_your_own_in_simulation_1(conf):
    met = run_experiment(compose_with(conf, "atmosphere=sign", "target.size=16", "cs.m=200", "denoiser=none"), conf / "run")
    assert met["status"] == "ok" and met["atmosphere"] == "sign"
    arrays = np.load(conf / "run" / "arrays.npz")
    w = SignAtmosphere().operator(200, 256, seed=0).matrix()
    torch.testing.assert_close(torch.as_tensor(arrays["y"]), w @ torch.as_tensor(arrays["truth"], dtype=torch.float32).reshape(-1))


def test_an_experiment_of_your_own(conf):
    met = run_experiment(compose_with(conf, "experiment=flux", "atmosphere=sign"), conf / "run")
    saved = json.loads((conf / "run" / "metrics.json").read_text())
    assert saved["status"] == "ok" and saved["experiment"] == "flux" and saved["atmosphere"] == "sign"
    from cssat.data import load_target

    x = load_target("tess", 16)
    y = np.load(conf / "run" / "y.npy")
    w = SignAtmosphere().operator(50, 256, seed=0, dtype=torch.float64).matrix().numpy()
    np.testing.assert_allclose(y, w @ x.reshape(-1), rtol=1e-12)
    assert met["flux"] == pytest.approx(float(x.sum()))
    with pytest.raises(ValueError, match="^experiment_module"):
        run_experiment(compose_with(conf, "experiment=flux", "experiment_module=no.such.module"), conf / "bad")


def test_a_yaml_only_experiment_recombines_the_stages(conf):
    """``defaults: [sim1, _self_]`` plus overrides in a YAML of one's own runs as
    ``cssat experiment=mine``, no other file touched; the app names it after its file."""
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "cssat.app", "experiment=mine", "threads=1", "dtype=float64",
                          f"hydra.searchpath=[file://{conf / 'conf'}]", f"cache_dir={conf / 'cache'}",
                          f"hydra.run.dir={conf / 'mine'}"], capture_output=True, text=True, cwd=conf, timeout=300)
    assert res.returncode == 0, res.stderr
    met = json.loads((conf / "mine" / "metrics.json").read_text())
    assert met["status"] == "ok" and met["experiment"] == "mine"
    assert met["reference"] == "full_rank" and met["solver"] == "tv" and met["m"] == 120
    assert met["phi_relative_error"] < 1e-8 and met["reference_n"] == 256  # Eq. 24 is exact up to round-off
    assert (conf / "mine" / "figures" / "fig11_sim2.png").stat().st_size > 1000
    # a flat image at the truth's mean is what the total flux alone gives: TV from Φ̂ does better
    arrays = np.load(conf / "mine" / "arrays.npz")
    flat = np.full_like(arrays["truth"], arrays["truth"].mean())
    assert met["psnr"] > 10 * np.log10(1 / np.mean((flat - arrays["truth"]) ** 2)) + 3


TOY_MODEL = '''"""A forward model of one's own: y = A x with a Gaussian A (2n, n) and a positive x (n,)."""
from dataclasses import dataclass

import numpy as np
import torch

from cssat._checks import int_param
from cssat.experiments.build import build_solver
from cssat.experiments.files import write_npz
from cssat.experiments.forward.base import ForwardModel
from cssat.models import register


@dataclass
class ToyConfig:
    _target_: str = "cssat_ext_demo.toy.Toy"
    n: int = 16

    def __post_init__(self):
        int_param(self.n, "forward.n", 2, 1000)


class Toy(ForwardModel):
    name = "toy"
    needs = {"measure": ("plan",), "solve": ("plan", "measure"), "score": ("measure", "solve"),
             "write": ("measure", "solve", "score")}

    def __init__(self, **settings):
        self.config = ToyConfig(**settings)

    def plan(self, cfg, run):
        self.n = self.config.n
        self.solver = build_solver(cfg.solver, 2 * self.n, self.n)

    def measure(self, run):
        rng = np.random.default_rng(run.seed)
        self.A = rng.normal(size=(2 * self.n, self.n))
        self.x = np.abs(rng.normal(size=self.n))
        self.y = self.A @ self.x

    def solve(self, run):
        from cssat.sparse import MatrixOperator
        from cssat.sparse.problem import Problem

        xhat, self.info = self.solver(Problem(MatrixOperator(torch.as_tensor(self.A)), (self.n,)), torch.as_tensor(self.y))
        self.xhat = xhat.numpy()

    def score(self, run):
        return {"psnr": None, "ssim": None, "n": self.n, "solver": self.solver.name,
                "relative_error": float(np.linalg.norm(self.xhat - self.x) / np.linalg.norm(self.x))}

    def write(self, run, metrics):
        write_npz(run.out_dir / "arrays.npz", A=self.A, x=self.x, y=self.y, xhat=self.xhat)


register("toy", ToyConfig)
'''

TOY_SOLVER = '''"""A solver of one's own: least squares, solver(problem, y) -> (x, info)."""
import torch


class LeastSquares:
    name = "lstsq"
    unknown = "any"

    def __call__(self, problem, y):
        A = problem.operator.matrix()
        x = torch.linalg.lstsq(A, y[:, None].to(A.dtype)).solution[:, 0]
        return x.reshape(problem.x_shape), {"solver_iterations": 1}
'''

TOY_EXPERIMENT = """# @package _global_
# A YAML-only experiment: the forward model and the solver of one's own package.
defaults:
  - override /forward: toy
  - override /solver: lstsq
  - _self_

experiment_name: toy
optimized_metric: null
tiny:
  - "forward.n=8"
forward:
  n: 24
"""


def test_a_forward_model_a_solver_and_a_yaml_experiment_of_your_own(tmp_path, monkeypatch):
    """One package of one's own (on sys.path, nothing of cssat edited): a forward model with its
    typed config registered as forward/toy, a solver in the solver group, and an experiment that is
    one YAML; run end to end through the library at the YAML's own tiny size."""
    import importlib

    from hydra.core.config_store import ConfigStore
    from hydra.errors import ConfigCompositionException

    from cssat._checks import FieldError
    from cssat.models import FORWARD_CONFIGS, unregister
    from cssat.smoke import TINY, tiny_overrides

    pkg = tmp_path / "pkg" / "cssat_ext_demo"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "toy.py").write_text(TOY_MODEL)
    (pkg / "solvers.py").write_text(TOY_SOLVER)
    conf = tmp_path / "conf"
    (conf / "solver").mkdir(parents=True)
    (conf / "experiment").mkdir()
    (conf / "solver" / "lstsq.yaml").write_text("_target_: cssat_ext_demo.solvers.LeastSquares\n")
    (conf / "experiment" / "toy.yaml").write_text(TOY_EXPERIMENT)
    monkeypatch.syspath_prepend(str(tmp_path / "pkg"))
    try:
        importlib.import_module("cssat_ext_demo.toy")  # registers forward/toy

        def compose_toy(*overrides):
            return compose_with(tmp_path, "experiment=toy", *overrides)

        tiny = tiny_overrides("toy", conf)
        assert tiny == ["forward.n=8"] and "toy" not in TINY  # its size read from its own YAML
        met = run_experiment(compose_toy(*tiny), tmp_path / "run")
        assert met["status"] == "ok" and met["experiment"] == "toy" and met["solver"] == "lstsq" and met["n"] == 8
        a = np.load(tmp_path / "run" / "arrays.npz")
        assert a["A"].shape == (16, 8)
        np.testing.assert_allclose(a["y"], a["A"] @ a["x"], rtol=1e-12)
        # least squares on a consistent, full-rank system returns the truth (numpy's own solve as the reference)
        np.testing.assert_allclose(a["xhat"], np.linalg.lstsq(a["A"], a["y"], rcond=None)[0], rtol=1e-8, atol=1e-10)
        assert met["relative_error"] < 1e-8
        assert {"seconds_setup", "seconds_measure", "seconds_solve", "seconds_score", "seconds_write"} <= set(met)
        # the YAML's own default size, and the typed config's schema and checks
        assert compose_toy().forward.n == 24
        with pytest.raises(ConfigCompositionException, match="forward.m"):
            compose_toy("forward.m=3")
        with pytest.raises(FieldError, match=r"^forward\.n: must be in \[2, 1000\], got 1"):
            run_experiment(compose_toy("forward.n=1"), tmp_path / "bad")
    finally:
        unregister("toy")
    assert "toy" not in FORWARD_CONFIGS and "toy.yaml" not in ConfigStore.instance().repo["forward"]
