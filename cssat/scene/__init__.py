"""Scene: orbit, Sun, observer, Earth shadow (sgp4/skyfield), attitude frames and satellite meshes.

Knows nothing of compressed sensing.
"""

from cssat.scene.attitude import nadir_pointing_frame, random_unit_vectors, to_body
from cssat.scene.mesh import Mesh, as_mesh, load_mesh, merge
from cssat.scene.models import MODELS, astra_like, box, cylinder, dish, get_model, panel, tess_like
from cssat.scene.orbit import (ASTRA_1KR_SYNTHETIC_TLE, TIMES_FORMS, Scenario, check_tle, earth_shadow_fraction,
                               make_scenario, utc_times)

__all__ = [
    "ASTRA_1KR_SYNTHETIC_TLE",
    "MODELS",
    "Mesh",
    "as_mesh",
    "Scenario",
    "astra_like",
    "box",
    "check_tle",
    "cylinder",
    "dish",
    "earth_shadow_fraction",
    "get_model",
    "load_mesh",
    "make_scenario",
    "utc_times",
    "TIMES_FORMS",
    "merge",
    "nadir_pointing_frame",
    "panel",
    "random_unit_vectors",
    "tess_like",
    "to_body",
]
