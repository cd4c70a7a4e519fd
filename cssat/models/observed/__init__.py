"""The measured-file forward model (``forward: observed``): its config (the model:
:class:`cssat.experiments.forward.observed.Observed`)."""
