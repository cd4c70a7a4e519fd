"""Shadows resolved below a facet (``shadow_mask(resolution_m=...)``): against trimesh's own
midpoint subdivision, against an analytic shadow area, and their refusals."""

import math

import numpy as np
import pytest
import torch
import trimesh

from cssat import FieldError
from cssat.optics.photometry import facet_brightness, shadow_mask
from cssat.optics.shadow_sampling import barycentric_points
from cssat.scene.mesh import Mesh, merge


def _plate_under_box(half=1.0, box=(1.0, 1.0, 0.1), height=0.3):
    """A 2·half square plate at z = 0 facing +z (two triangles) and a closed box above it."""
    v = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], float)
    plate = Mesh(v, np.array([[0, 1, 2], [0, 2, 3]]), 0.5, 0.0, name="plate")
    b = trimesh.creation.box(extents=box)
    b.apply_translation([0, 0, height + box[2] / 2])
    return merge([plate, Mesh(np.asarray(b.vertices), np.asarray(b.faces), 0.5, 0.0, name="box")])


@pytest.mark.parametrize("level", [0, 1, 2, 3])
def test_points_are_the_centroids_of_trimesh_midpoint_subdivision(level):
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    v, f = tri, np.array([[0, 1, 2]])
    for _ in range(level):
        v, f = trimesh.remesh.subdivide(v, f)
    want = v[f].mean(axis=1)[:, :2]
    got = (barycentric_points(level) @ tri)[:, :2]
    assert len(got) == 4**level
    key = lambda a: a[np.lexsort(np.round(a, 9).T)]  # noqa: E731
    np.testing.assert_allclose(key(got), key(want), atol=1e-12)


def _subdivided(mesh, times):
    """``mesh`` split ``times`` times at its edges' midpoints by trimesh, and each child's parent."""
    v, f, parent = mesh.vertices, mesh.faces, np.arange(len(mesh.faces))
    for _ in range(times):
        v, f, index = trimesh.remesh.subdivide(v, f, return_index=True)
        new_parent = np.empty(len(f), dtype=int)
        for old, children in index.items():
            new_parent[children] = parent[old]
        parent = new_parent
    return Mesh(v, f, 0.5, 0.0), parent


@pytest.mark.parametrize(("res", "level"), [(0.75, 2), (0.375, 3)])
def test_fraction_equals_the_subdivided_mesh_centroid_rays(res, level):
    """The fraction a facet is lit and seen = the mean centroid visibility of its children in the
    mesh split ``level`` times by trimesh (every facet of this scene needs ``level`` splits for
    edges ≤ ``res``: an independent construction)."""
    mesh = _plate_under_box(box=(1.4, 1.4, 1.0))
    edges = np.linalg.norm(mesh.vertices[mesh.faces] - np.roll(mesh.vertices[mesh.faces], 1, axis=1), axis=2)
    assert np.all(np.ceil(np.log2(edges.max(axis=1) / res)) == level)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(40, 3)) * [0.4, 0.4, 1.0]
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    sun = d / np.linalg.norm(d, axis=1, keepdims=True)
    o = sun + rng.normal(scale=0.15, size=sun.shape)
    obs = o / np.linalg.norm(o, axis=1, keepdims=True)
    got = shadow_mask(mesh, sun, obs, resolution_m=res).numpy()
    fine, parent = _subdivided(mesh, level)
    assert np.all(np.bincount(parent) == 4**level)
    child = shadow_mask(fine, sun, obs).numpy().astype(float)
    want = np.stack([child[:, parent == i].mean(axis=1) for i in range(len(mesh.faces))], axis=1)
    front = ((sun @ mesh.normals.T) > 0) & ((obs @ mesh.normals.T) > 0)
    assert got.dtype == np.float64 and got.min() >= 0 and got.max() <= 1
    assert np.all(got[~front] == 0)
    plate = slice(0, 2)  # where the shadows fall
    assert 0.05 < got[:, plate][front[:, plate]].mean() < 0.95  # partly shadowed: a real test
    np.testing.assert_allclose(got, want, atol=1.01 / 4**level)  # a grazing child ray may differ (float32 rays)
    assert np.abs(got - want).mean() < 1e-3


def test_lit_fraction_converges_to_the_analytic_shadow_area():
    """The Sun 30° from the zenith in x, the observer along it: the box's shadow on the 2 × 2 m
    plate is a 1 × (1 + t·tan 30°) rectangle, so the plate is 1 − (1 + t tan 30°)/4 lit and seen."""
    t, th = 0.1, math.radians(30.0)
    mesh = _plate_under_box(box=(1.0, 1.0, t))
    s = np.array([[math.sin(th), 0.0, math.cos(th)]])
    want = 1 - (1 + t * math.tan(th)) / 4
    fine = shadow_mask(mesh, s, s, resolution_m=0.005).numpy()[0, :2].mean()  # capped at 64 splits an edge
    centroid = shadow_mask(mesh, s, s).numpy()[0, :2].astype(float).mean()
    assert abs(fine - want) < 0.01
    assert abs(centroid - want) > 0.2  # one ray a facet: each half of the plate wholly lit or dark


def test_light_curve_uses_the_fraction():
    mesh = _plate_under_box()
    th = math.radians(30.0)
    s = torch.tensor([[math.sin(th), 0.0, math.cos(th)]], dtype=torch.float64)
    b = facet_brightness(mesh, s, s, shadows=True, shadow_resolution_m=0.05)
    frac = shadow_mask(mesh, s, s, resolution_m=0.05)
    bare = facet_brightness(mesh, s, s)
    torch.testing.assert_close(b, bare * frac, rtol=1e-12, atol=0)


@pytest.mark.parametrize("bad", [0, -0.1, float("nan"), float("inf"), "0.1", True])
def test_bad_resolution_is_refused_by_name(bad):
    s = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(FieldError, match="resolution_m"):
        shadow_mask(_plate_under_box(), s, s, resolution_m=bad)


def test_resolution_without_shadows_is_refused():
    s = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(FieldError, match="shadow_resolution_m.*shadows=True"):
        facet_brightness(_plate_under_box(), s, s, shadow_resolution_m=0.1)
