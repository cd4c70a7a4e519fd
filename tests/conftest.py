import os

# One BLAS/OpenMP thread a process before numpy and torch load: the suite runs one worker process
# per core (pytest-xdist), and a worker whose BLAS starts a thread per core oversubscribes the
# machine (spin-waiting threads; measured 10-20x slower on a busy 2-core machine). A value the
# user set is kept; numba's own pool (NUMBA_NUM_THREADS) is left alone: tests compare its
# parallel kernels with the serial ones.
for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402
import torch  # noqa: E402


def pytest_configure(config):
    config.addinivalue_line("markers", "cuda: needs a CUDA device (skipped where torch.cuda.is_available() is false)")
    config.addinivalue_line("markers", "slow: over ~10 s each (CI runs them; `pytest -m 'not slow'` leaves them out "
                                       "while developing)")


def pytest_collection_modifyitems(config, items):
    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="no CUDA device")
    for item in items:
        if "cuda" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(autouse=True)
def _few_threads():
    # Tests run on a shared 2-core machine: oversubscription is 20x slower.
    torch.set_num_threads(1)
    yield


def dot_test(op, dtype=torch.float64, batch=3, seed=0):
    """<A x, y> == <x, Aᵀ y> for random x, y: returns the relative mismatch."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(batch, op.n_in, generator=g, dtype=dtype)
    y = torch.randn(batch, op.n_out, generator=g, dtype=dtype)
    lhs = (op(x) * y).sum()
    rhs = (x * op.adjoint(y)).sum()
    return float((lhs - rhs).abs() / (lhs.abs() + rhs.abs()))


def run_cli(args, cwd):
    """The ``cssat`` console script run in this process: ``cssat.app.main()`` with ``sys.argv``
    set, in ``cwd``; returns ``(exit code, the non-empty lines it printed or logged)``. An exception
    escaping ``main()`` — a traceback, in a process of its own — fails the test. For what a run
    refuses or writes; what needs a process of its own (the console script's exit status, kills,
    signals, byte-reproducibility across processes) is tested with subprocesses."""
    import contextlib
    import io
    import os
    import sys

    from hydra.core.global_hydra import GlobalHydra

    from cssat import app, summary

    out, old_argv, old_cwd = io.StringIO(), sys.argv, os.getcwd()
    sys.argv, code = ["cssat", *map(str, args)], 0
    summary.SWEEP_FAILED = False
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            app.main()
    except SystemExit as err:
        code = 0 if err.code is None else err.code if isinstance(err.code, int) else 1
    finally:
        sys.argv = old_argv
        os.chdir(old_cwd)
        GlobalHydra.instance().clear()
        torch.set_num_threads(1)
    return code, [ln for ln in out.getvalue().splitlines() if ln.strip()]


def cfg_of(*overrides):
    """The composed config of the command-line ``overrides`` (as the app composes it)."""
    from hydra import compose, initialize_config_module

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


#: the inversion experiment at a tiny size with its attitude known (an oracle): a light curve of two nights
INVERSION_TINY = ["experiment=inversion", "nights.n=2", "nights.fit=1", "scenario.step_s=600", "inversion.spin=known",
                  "inversion.n_normals=64", "threads=1",
                  "attitude.epoch_utc=2020-04-01T12:00:00"]  # the spin's phase epoch: the same for a file starting at night


@pytest.fixture(scope="session")
def inversion_sim(tmp_path_factory):
    """``(metrics, out_dir)`` of one simulated run of :data:`INVERSION_TINY` (read, never written
    to, by the tests that share it: its ``lightcurve.csv`` is a measured light curve for them)."""
    from cssat.experiments import run_experiment

    out = tmp_path_factory.mktemp("inversion_sim") / "sim"
    return run_experiment(cfg_of(*INVERSION_TINY), out), out
