"""cssat — compressed sensing for satellite characterisation.

Layers (``../shared/DESIGN.md``): ``cssat.sparse`` (operators, batched OMP), ``cssat.metrics``,
``cssat.data`` (targets), ``cssat.experiments`` and the Hydra app ``cssat.app``.
Submodules are imported on first use so ``import cssat`` stays fast.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"
__all__ = ["sparse", "metrics", "data", "experiments", "__version__"]


def __getattr__(name: str):
    if name in ("sparse", "metrics", "data", "experiments"):
        return importlib.import_module(f"cssat.{name}")
    raise AttributeError(f"module 'cssat' has no attribute {name!r}")
