"""Extending cssat without touching it: an atmosphere and an experiment of your own, each one
module (here: this test file) and one YAML on Hydra's search path."""

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
    from cssat.experiments.build import build_measurement

    n = cfg.target.size
    meas, atm = build_measurement(cfg, cfg.cs.m, n * n, cfg.seed, torch.float64, "cpu")
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
        "# @package _global_\ndefaults:\n  - /target@target: tess\n  - _self_\n"
        f"experiment_name: flux\nexperiment_module: {__name__}\ntarget:\n  size: 16\ncs:\n  m: 50\n")
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
