"""The target's feature points moving as the source's: points inside a coarse target
triangle shift their vertices alike (:func:`fmc.clone.skin.shift_bound_points`)."""

from types import SimpleNamespace

import numpy as np
from scipy import sparse

from fmc.clone.skin import shift_bound_points
from mpeg4.head import FeaturePointBinding as B


def test_a_point_inside_a_coarse_triangle_moves_as_the_source_point():
    """Points bound to several target vertices, otherwise than on the source, each shift
    their vertices by one offset: the point then takes the source point's weights exactly,
    the rows still sum to one, and a point's vertices keep their differences (also where
    two points share a vertex, solved together)."""
    rng = np.random.default_rng(3)
    w = rng.random((7, 5))
    w /= w.sum(axis=1, keepdims=True)
    source = SimpleNamespace(feature_points={"2.1": B("skin", (0,), (1.0,)), "2.2": B("skin", (1, 2), (0.5, 0.5)),
                                             "2.3": B("skin", (4,), (1.0,))})
    target = SimpleNamespace(feature_points={"2.1": B("skin", (1, 2, 3), (0.2, 0.5, 0.3)),
                                             "2.2": B("skin", (3, 4), (0.6, 0.4)),
                                             "2.3": B("skin", (6,), (1.0,))})
    out = shift_bound_points(sparse.csr_matrix(w), source, target).toarray()
    for fp in ("2.1", "2.2"):
        a, b = source.feature_points[fp], target.feature_points[fp]
        want = np.zeros(5)
        want[list(a.vertices)] = a.weights
        np.testing.assert_allclose(np.asarray(b.weights) @ out[list(b.vertices)], want, atol=1e-12)
    np.testing.assert_allclose(out.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(out[1] - out[2], w[1] - w[2], atol=1e-12)
    # A point on one vertex (pinned elsewhere) and vertices of no point are left alone.
    np.testing.assert_array_equal(out[[0, 5, 6]], w[[0, 5, 6]])
    # So is a vertex pinned to another point: the others of each point make up for it.
    held = shift_bound_points(sparse.csr_matrix(w), source, target, held=[3]).toarray()
    np.testing.assert_array_equal(held[3], w[3])
    for fp in ("2.1", "2.2"):
        a, b = source.feature_points[fp], target.feature_points[fp]
        want = np.zeros(5)
        want[list(a.vertices)] = a.weights
        np.testing.assert_allclose(np.asarray(b.weights) @ held[list(b.vertices)], want, atol=1e-12)
