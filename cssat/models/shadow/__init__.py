"""The occultation's shadow forward model (``forward: shadow``): its config and its typed settings
(``star``, ``optics``, ``event``, ``array``, ``silhouette``, ``invert``:
:mod:`cssat.models.shadow.config`; the model: :class:`cssat.experiments.forward.shadow.Shadow`)."""
