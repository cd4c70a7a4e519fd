import pytest
import torch


def pytest_configure(config):
    config.addinivalue_line("markers", "cuda: needs a CUDA device (skipped where torch.cuda.is_available() is false)")


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
