"""Attitude: body frames of a three-axis stabilised satellite, and random view geometries.

A body frame is a rotation ``R (T, 3, 3)`` whose *rows* are the body axes expressed in the
inertial (GCRS) frame, so ``v_body = R @ v_inertial``.
"""

from __future__ import annotations

import numpy as np

from cssat._checks import FieldError

__all__ = ["nadir_pointing_frame", "to_body", "random_unit_vectors"]


def nadir_pointing_frame(r_sat: np.ndarray, v_sat: np.ndarray) -> np.ndarray:
    """The paper's three-axis stabilised attitude (Fig. 3b), ``(T, 3, 3)``.

    * body +z points to the geocentre (the antennas face the Earth): ``z = −r/|r|``;
    * body +y is perpendicular to the orbital plane, along the negative orbit normal
      ``y = −(r × v)/|r × v|`` (south for a prograde equatorial orbit): the solar-array axis;
    * body +x completes the right-handed frame, ``x = y × z`` (along the velocity for a circular orbit).

    ``r_sat`` (km) and ``v_sat`` (km/s) are ``(T, 3)`` geocentric inertial vectors.
    """
    r = np.asarray(r_sat, dtype=np.float64)
    v = np.asarray(v_sat, dtype=np.float64)
    z = -r / np.linalg.norm(r, axis=1, keepdims=True)
    h = np.cross(r, v)
    hn = np.linalg.norm(h, axis=1, keepdims=True)
    if np.any(hn == 0):
        raise FieldError("v_sat", "velocity parallel to position, the orbital plane is undefined")
    y = -h / hn
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=1)


def to_body(frame: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Express inertial ``vectors (T, 3)`` in the body ``frame (T, 3, 3)``: ``(T, 3)``."""
    return np.einsum("tij,tj->ti", frame, vectors)


def random_unit_vectors(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` directions uniform on the unit sphere, ``(n, 3)``, from the given generator."""
    v = rng.standard_normal((n, 3))
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    while np.any(norm < 1e-12):  # measure-zero, but keep the result exact
        bad = (norm < 1e-12)[:, 0]
        v[bad] = rng.standard_normal((int(bad.sum()), 3))
        norm = np.linalg.norm(v, axis=1, keepdims=True)
    return v / norm
