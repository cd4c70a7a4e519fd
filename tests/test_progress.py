"""Progress bars (tqdm) of the long stages: shown on request, silent off a terminal, and they do
not change a single number (issue 14)."""

import re

import numpy as np
import pytest
import torch

from cssat.sparse import batch_omp


def last_count(err: str, desc: str) -> tuple[int, int]:
    """The last ``n/total`` a tqdm bar named ``desc`` printed."""
    counts = re.findall(re.escape(desc) + r"[^\r\n]*?(\d+)/(\d+)", err)
    assert counts, f"no bar {desc!r} in {err!r}"
    return tuple(int(c) for c in counts[-1])


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_omp_bar_counts_the_atoms_selected_on_either_path(backend, capsys):
    g = torch.Generator().manual_seed(0)
    D = torch.randn(64, 128, generator=g, dtype=torch.float64)
    Y = torch.randn(40, 64, generator=g, dtype=torch.float64)
    quiet, qinfo = batch_omp(D, Y, n_nonzero_coefs=12, backend=backend, precompute=True, return_info=True, progress=False)
    assert capsys.readouterr().err == ""
    loud, info = batch_omp(D, Y, n_nonzero_coefs=12, backend=backend, precompute=True, return_info=True, progress=True)
    err = capsys.readouterr().err
    done, total = last_count(err, "OMP (gram, 40 signals, K=12)")
    assert total == 40 * 12 and done == int(info.n_iter.sum())
    torch.testing.assert_close(loud, quiet, rtol=0, atol=0)  # a bar changes no number
    batch_omp(D, Y, n_nonzero_coefs=12, backend=backend)  # default: not a terminal here, so silent
    assert capsys.readouterr().err == ""


def test_every_long_stage_has_a_bar(capsys):
    from cssat.optics import render
    from cssat.recon import L1, TV, PnP, SparseKSVD, TVDenoiser
    from cssat.scene import box
    from cssat.sparse import GaussianSensing

    x = torch.zeros(16, 16, dtype=torch.float64)
    x[4:12, 6:10] = 1.0
    phi = GaussianSensing(120, 256, seed=1, dtype=torch.float64)
    y = phi(x.reshape(-1))
    L1(max_iter=20, progress=True)(phi, y, (16, 16))
    TV(max_iter=20, progress=True)(phi, y, (16, 16))
    PnP(TVDenoiser(), max_iter=4, progress=True)(phi, y, (16, 16))
    SparseKSVD(n_iter=3, n_train=500, progress=True)(x + 0.05 * torch.randn(16, 16, dtype=torch.float64))
    sun = torch.tensor([[0.0, 0.0, 1.0]] * 5, dtype=torch.float64)
    render(box((1, 1, 1)), sun, sun, 8, progress=True)
    err = capsys.readouterr().err
    assert last_count(err, "FISTA")[0] >= 1
    assert last_count(err, "TV (Chambolle-Pock)")[0] >= 1
    assert last_count(err, "PnP") == (4, 4)
    assert last_count(err, "K-SVD") == (3, 3)
    assert last_count(err, "rendering 5 views") == (5, 5)


def test_bad_progress_values_are_named():
    from cssat.recon import OMP

    with pytest.raises(ValueError, match="progress: expected true, false or null"):
        OMP(progress="yes")
    with pytest.raises(ValueError, match="progress: expected true, false or null"):
        batch_omp(np.eye(3), np.ones(3), n_nonzero_coefs=1, progress=1)


def test_the_config_flag_reaches_the_objects_and_not_the_hash():
    from hydra import compose, initialize_config_module

    from cssat.experiments import config_sha
    from cssat.experiments.build import build_denoiser, build_solver

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        on = compose(config_name="config", overrides=["progress=true"])
        off = compose(config_name="config", overrides=["progress=false"])
    assert build_solver(on.solver, 100, 256).progress is True and build_denoiser(on.denoiser).progress is True
    assert build_solver(off.solver, 100, 256).progress is False
    assert config_sha(on) == config_sha(off)  # a bar does not change the results: resume still skips
