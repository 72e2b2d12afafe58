"""Sibson coordinates: invariants, and stolen Voronoi volumes computed independently."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull, Voronoi

from mpeg4.errors import InputError
from recon.shape.sibson import NaturalNeighbours, sibson_coordinates

CUBE = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)


def _controls(seed, n=40):
    rng = np.random.default_rng(seed)
    return np.vstack([CUBE, rng.random((n, 3))]), rng


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(5, 60))
def test_partition_of_unity_positivity_and_linear_precision(seed, n):
    controls, rng = _controls(seed, n)
    q = rng.random((300, 3))
    w = sibson_coordinates(q, controls)
    assert w.shape == (300, len(controls))
    assert w.data.min() >= 0
    np.testing.assert_allclose(np.asarray(w.sum(axis=1)).ravel(), 1, atol=1e-9)
    np.testing.assert_allclose(w @ controls, q, atol=1e-9)  # reproduces x, y, z
    a = rng.standard_normal((3, 2))
    np.testing.assert_allclose(w @ (controls @ a + 7), q @ a + 7, atol=1e-8)  # any affine function


def test_exact_interpolation_at_control_points():
    controls, _ = _controls(3)
    w = sibson_coordinates(controls, controls).toarray()
    np.testing.assert_array_equal(w, np.eye(len(controls)))


def _cell_volume(vor, k):
    region = vor.regions[vor.point_region[k]]
    assert -1 not in region and region
    return ConvexHull(vor.vertices[region]).volume


def test_equal_to_stolen_voronoi_volumes():
    # Inner points inside a far enclosing shell: their Voronoi cells are bounded, so the
    # stolen volumes can be measured directly as old cell minus new cell.
    rng = np.random.default_rng(7)
    inner = rng.random((60, 3))
    shell = np.array([[x, y, z] for x in (-3, 0.5, 4) for y in (-3, 0.5, 4) for z in (-3, 0.5, 4)
                      if (x, y, z) != (0.5, 0.5, 0.5)], float)
    controls = np.vstack([inner, shell])
    old = Voronoi(controls)
    checked = 0
    for x in 0.3 + 0.4 * rng.random((12, 3)):
        new = Voronoi(np.vstack([controls, x]))
        w = sibson_coordinates(x[None], controls).toarray()[0]
        if (w[len(inner):] > 0).any():
            continue  # a shell point is a neighbour: its cell is unbounded
        vx = _cell_volume(new, len(controls))
        stolen = np.zeros(len(controls))
        for i in np.flatnonzero(w > 0):
            stolen[i] = _cell_volume(old, i) - _cell_volume(new, i)
        np.testing.assert_allclose(w, stolen / vx, atol=1e-9)
        checked += 1
    assert checked >= 8


def test_continuous_across_delaunay_faces():
    controls, _ = _controls(11, 30)
    nn = NaturalNeighbours(controls)
    tri = nn.simplices[0]
    p = controls[tri]
    face_point = p[:3].mean(axis=0)  # on the face shared with a neighbour tetrahedron
    normal = np.cross(p[1] - p[0], p[2] - p[0])
    normal /= np.linalg.norm(normal)
    steps = np.array([-1e-6, -1e-8, 0.0, 1e-8, 1e-6])
    w = nn.coordinates(face_point + steps[:, None] * normal).toarray()
    assert np.abs(np.diff(w, axis=0)).max() < 1e-4
    np.testing.assert_allclose(w @ controls, face_point + steps[:, None] * normal, atol=1e-7)


def test_cospherical_controls_are_handled():
    # The 8 cube corners are cospherical: Delaunay is ambiguous there, Sibson is not. The
    # centre lies on the planes of several Delaunay faces at once, the hardest case for
    # Watson's sums; the nudged fallback keeps it within 1e-6.
    w = sibson_coordinates([[0.5, 0.5, 0.5], [0.25, 0.5, 0.75]], CUBE).toarray()
    np.testing.assert_allclose(w[0], 1 / 8, atol=1e-6)
    np.testing.assert_allclose(w @ CUBE, [[0.5, 0.5, 0.5], [0.25, 0.5, 0.75]], atol=1e-9)


def test_degenerate_control_sets_get_clear_errors():
    flat = np.c_[np.random.default_rng(0).random((10, 2)), np.zeros(10)]
    with pytest.raises(InputError, match="coplanar"):
        NaturalNeighbours(flat)
    dup = np.vstack([CUBE, CUBE[2]])
    with pytest.raises(InputError, match="control points c and 2 coincide|coincide"):
        NaturalNeighbours(dup, names=list("abcdefgh") + ["c"])
    with pytest.raises(InputError, match="outside the convex hull"):
        sibson_coordinates([[2.0, 0.5, 0.5]], CUBE)
