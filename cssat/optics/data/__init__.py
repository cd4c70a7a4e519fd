"""Package data of :mod:`cssat.optics.passbands`: the Sun's spectrum and filter curves (text tables;
their sources and licences in ``PROVENANCE.md``)."""
