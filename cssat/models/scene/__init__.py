"""The scene forward model (``forward: scene``): its config (the model:
:class:`cssat.experiments.forward.scene.SceneLightCurve`)."""
