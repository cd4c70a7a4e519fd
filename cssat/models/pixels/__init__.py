"""The paper's pixel sensing (``forward: pixels``): its config (the model:
:class:`cssat.experiments.forward.PixelSensing`)."""
