"""cssat — compressed sensing for satellite characterisation.

Layers (``../shared/DESIGN.md``): ``cssat.scene`` (orbits, attitudes, meshes), ``cssat.optics``
(BRDFs, light curves, rendering), ``cssat.data`` (targets, datasets), ``cssat.sparse``
(operators, batched OMP, K-SVD), ``cssat.reference`` (sensing-matrix estimation),
``cssat.physics`` (atmospheres, noise, measurements), ``cssat.recon`` (solvers, denoisers),
``cssat.metrics``, ``cssat.plots``, ``cssat.experiments`` and the Hydra app ``cssat.app``.
Every one is an attribute of ``cssat``, imported on first use, so ``import cssat`` stays fast.
``cssat.FieldError`` (a ``ValueError``) is what a bad input raises: its ``field`` names the input.
"""

from __future__ import annotations

import importlib

from cssat._checks import FieldError

__version__ = "0.1.0"

#: the subpackages and modules reachable as ``cssat.<name>`` (imported lazily)
SUBMODULES = ("scene", "optics", "data", "sparse", "reference", "physics", "recon", "inversion", "metrics", "plots",
              "experiments", "summary", "catalogue")
__all__ = [*SUBMODULES, "FieldError", "__version__"]


def __getattr__(name: str):
    if name in SUBMODULES:
        module = importlib.import_module(f"cssat.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module 'cssat' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *SUBMODULES})
