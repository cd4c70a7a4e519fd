"""Pixel sensing of a scene that moves (``forward: moving``): its config (the model:
:class:`cssat.experiments.motion.MovingScene`)."""
