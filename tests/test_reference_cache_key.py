"""The reference-image cache serves an entry only to a run that would render the same images:
a mesh whose arrays track the Sun and the same mesh with its arrays fixed, or another glint
model, are different sets (a stale entry once fed the old defaults' images to new runs)."""

import numpy as np


def test_the_cache_tells_apart_array_tracking_and_the_glint_model(tmp_path, monkeypatch):
    from cssat.experiments.refsets import reference_set
    from cssat.optics import photometry
    from cssat.scene.models import astra_like

    args = dict(size=8, n=3, seed=0, noise=0.0, shadows=False, progress=False)
    sun, read = reference_set(str(tmp_path), mesh=astra_like(array_tracking="sun"), **args)
    assert not read
    again, read = reference_set(str(tmp_path), mesh=astra_like(array_tracking="sun"), **args)
    assert read and np.array_equal(again.numpy(), sun.numpy())  # the same set: from the cache
    fixed, read = reference_set(str(tmp_path), mesh=astra_like(array_tracking="fixed"), **args)
    assert not read  # another set: rendered, not served the Sun-tracking entry
    fresh, _ = reference_set(None, mesh=astra_like(array_tracking="fixed"), **args)
    assert np.array_equal(fixed.numpy(), fresh.numpy()) and not np.array_equal(fixed.numpy(), sun.numpy())
    other = "paper" if photometry.DEFAULT_GLINT != "paper" else "physical"
    monkeypatch.setattr(photometry, "DEFAULT_GLINT", other)
    _, read = reference_set(str(tmp_path), mesh=astra_like(array_tracking="sun"), **args)
    assert not read  # the glint model is part of the key
    assert len(list(tmp_path.glob("refs-*.npy"))) == 3
