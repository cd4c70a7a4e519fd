"""The EGI forward model (``forward: egi``): its config (the model:
:class:`cssat.experiments.forward.egi.EGILightCurve`)."""
