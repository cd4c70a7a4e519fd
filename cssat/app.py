"""The ``cssat`` console script: a Hydra app over ``conf/`` (packaged as ``cssat.conf``).

``cssat experiment=sim1 cs.m=4096`` runs one job; ``cssat -m ...`` sweeps. Outputs go to Hydra's
run directory (``outputs/<date>/<time>/`` by default), which this app passes down explicitly:
library code never reads Hydra state.
"""

from __future__ import annotations

import logging
import sys

import hydra
from omegaconf import DictConfig

log = logging.getLogger("cssat")


@hydra.main(version_base="1.3", config_path="pkg://cssat.conf", config_name="config")
def _hydra_main(cfg: DictConfig) -> float | None:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from cssat.experiments import ConfigError, run_experiment

    hc = HydraConfig.get()
    try:
        metrics = run_experiment(cfg, hc.runtime.output_dir)
    except Exception as err:
        if hc.mode == RunMode.MULTIRUN:
            # One failed job must not end the sweep: its metrics.json says status: failed.
            log.error("job %s failed: %s", hc.job.num, err)
            return None
        if isinstance(err, ConfigError):
            log.error("bad config: %s", err)
            sys.exit(2)
        raise
    key = cfg.get("optimized_metric", "psnr")
    value = metrics.get(key) if key else None
    return float(value) if isinstance(value, (int, float)) else None


def main() -> None:
    """Console-script entry point."""
    _hydra_main()


if __name__ == "__main__":
    main()
