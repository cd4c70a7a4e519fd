"""cssat's Hydra configs (``pkg://cssat.conf``). Importing it stores the forward models' typed
configs in Hydra's ConfigStore as the ``forward`` group's options (:mod:`cssat.models`)."""

from cssat.models import register_configs

register_configs()
