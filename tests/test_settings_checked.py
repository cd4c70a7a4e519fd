"""Issue 35, point 5 (in part): the occultation's and the inversion's settings refused before any
work, in one line naming the full key — values a sign check let through (a throughput of 2 and a
negative read noise raised the score; exposures and apertures that ended in a MemoryError; a
cadence that grew past 4 GB)."""

from __future__ import annotations

import pytest

from cssat.smoke import TINY

OCC = ["experiment=occultation", *TINY["occultation"]]  # the smoke run's tiny sizes
INV = ["experiment=inversion", *TINY["inversion"]]


@pytest.mark.parametrize("base, bad, field", [
    (OCC, "array.throughput=2", "array.throughput"),
    (OCC, "array.read_noise_e=-1", "array.read_noise_e"),
    (OCC, "invert.shape_iters=-1", "invert.shape_iters"),
    (OCC, "array.exposure_s=1e-12", "array.exposure_s"),
    (OCC, "array.exposure_s=100", "array.exposure_s"),
    (OCC, "array.aperture_m=1000", "array.aperture_m"),
    (OCC, "array.n_slots=0", "array.n_slots"),
    (OCC, "array.n_slots=1", "array.n_slots"),  # one telescope: no held-out test (was refused after the truth, naming
    (OCC, "array.fill=1e-6", "array.fill"),  # an internal positions_m)
    (INV, "inversion.parametric.booms=true", "inversion.parametric.booms"),  # without shape=parametric: was ignored
    (OCC, "silhouette.ground=9", "silhouette.ground"),
    (INV, "inversion.n_poles=0", "inversion.n_poles"),
    (INV, "inversion.max_period_s=10", "inversion.max_period_s"),
    (INV, "scenario.step_s=0.001", "scenario.step_s"),
    (INV, "scenario.step_s=0.1", "memory"),
])
def test_refused_before_work_naming_the_full_key(tmp_path, base, bad, field):
    from conftest import run_cli

    code, lines = run_cli([*base, bad, f"hydra.run.dir={tmp_path / 'r'}"], tmp_path)
    assert code == 2, lines
    refusal = [ln for ln in lines if "bad input:" in ln]
    assert len(refusal) == 1 and f"bad input: {field}:" in refusal[0], lines
    assert not list(tmp_path.glob("r/*.npz"))  # nothing computed, nothing written but the failed status


def test_the_egi_operator_counts_in_the_memory_estimate(tmp_path):
    """20,000 normals over the tiny inversion's 193 steps: ~25 MB of facet arrays, ~62 MB for
    G and its weighted copy. Under a 50 MB limit the run is refused before any work, and the
    refusal names the EGI operator's part (without it the facets alone would pass)."""
    from conftest import run_cli

    code, lines = run_cli([*INV, "inversion.n_normals=20000", "memory_limit_gb=0.05", f"hydra.run.dir={tmp_path / 'r'}"],
                          tmp_path)
    refusal = [ln for ln in lines if "bad input:" in ln]
    assert code == 2 and len(refusal) == 1 and "bad input: memory:" in refusal[0], lines
    assert "EGI operator and its weighted copy (T, K) 0.06" in refusal[0], refusal
