"""Package discovery for setuptools (the metadata is in ``pyproject.toml``).

``setuptools.find_packages`` finds every package of the source tree, so none is left out of the
wheel when one is added: ``cssat/`` as ``cssat.*``, and the top-level ``conf/`` as ``cssat.conf.*``
(Hydra's config module, ``pkg://cssat.conf``, read from any working directory); the joblib launcher
of ``cssat/_hydra_plugin/`` ships as ``hydra_plugins.cssat_launcher``, where Hydra looks for
plugins. A ``[tool.setuptools.packages.find]`` table cannot rename ``conf`` to ``cssat.conf``.
"""

from setuptools import find_packages, setup

code = find_packages(include=["cssat", "cssat.*"])
conf = ["cssat.conf"] + [f"cssat.conf.{p}" for p in find_packages("conf")]
setup(
    packages=code + conf + ["hydra_plugins.cssat_launcher"],
    package_dir={"cssat.conf": "conf", "hydra_plugins.cssat_launcher": "cssat/_hydra_plugin"},
)
