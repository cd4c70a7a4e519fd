"""Refusals found by a hostile pass: each names its key, at once, with a reason a reader can act on."""

import errno

import numpy as np
import pytest

from cssat._checks import FieldError


def test_a_surface_reflecting_more_light_than_arrives_is_refused():
    from cssat.optics.brdf import PaperBRDF
    from cssat.scene.mesh import Mesh
    from cssat.scene.models import get_model

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    with pytest.raises(FieldError, match=r"cd \+ cs = 1\.8 > 1") as e:
        Mesh(v, f, 0.9, 0.9)
    assert e.value.field == "mesh.cs"
    Mesh(v, f, 0.8, 0.2)  # all the light, and no more: allowed
    with pytest.raises(FieldError, match=r"cd \+ cs = 1\.8") as e:
        PaperBRDF(cd=0.9, cs=0.9)
    assert e.value.field == "cs"
    with pytest.raises(FieldError, match=r"cd \+ cs = 1\.1") as e:
        get_model("astra_like", cd=0.9)  # cs keeps its default 0.2
    assert e.value.field == "cs"


@pytest.mark.parametrize("make, key", [
    (lambda A: A.Spin(period_s=0.0), "attitude.period_s"),
    (lambda A: A.Spin(period_s="fast"), "attitude.period_s"),
    (lambda A: A.Spin(pole_lat_deg=91.0), "attitude.pole_lat_deg"),
    (lambda A: A.Spin(frame="galactic"), "attitude.frame"),
    (lambda A: A.Tumbling(inertia_kg_m2=[1.0, 2.0]), "attitude.inertia_kg_m2"),
    (lambda A: A.Tumbling(inertia_kg_m2=["a", "b", "c"]), "attitude.inertia_kg_m2"),
    (lambda A: A.Tumbling(q0=[0.0, 0.0, 1.0]), "attitude.q0"),
    (lambda A: A.Tumbling(omega0_rad_s=["x", 0, 0]), "attitude.omega0_rad_s"),
    (lambda A: A.Quaternions(["2020-04-01T00:00:00", "2020-04-02T00:00:00"], [[0, 0, 0, 1]]), "attitude.quaternions"),
])
def test_attitude_errors_name_their_key(make, key):
    import cssat.scene.attitudes as A

    with pytest.raises(FieldError) as e:
        make(A)
    assert e.value.field == key, e.value


def test_a_denoiser_step_past_its_blocks_is_refused_when_configured():
    from cssat.recon.denoisers import SparseKSVD

    with pytest.raises(FieldError, match="must not exceed the block size 8") as e:
        SparseKSVD(step=100)  # before any image is seen
    assert e.value.field == "step"
    with pytest.raises(FieldError, match=r"\(4, 4\)"):
        SparseKSVD(step=[1, 5], block_size=[4, 4])
    SparseKSVD(step=[1, 2], block_size=[4, 4])


@pytest.mark.parametrize("err, says", [
    (OSError(errno.ENOSPC, ""), "No space left on device"),
    (OSError(), "OSError (the system gave no reason)"),
    (OSError(errno.ENOSPC, "No space left on device", "/data/out/x.npz"), "/data/out/x.npz: No space left on device"),
])
def test_a_full_disk_is_said_in_words(err, says):
    from cssat.app import _os_error

    line = _os_error(err, "outputs/run")
    assert says in line and line.split(": ", 1)[1].strip()
