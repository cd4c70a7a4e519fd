"""The occultation's shadow forward model (``forward: shadow``): its config (the model:
:class:`cssat.experiments.forward.shadow.Shadow`)."""
