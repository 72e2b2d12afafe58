"""Splitting vertices along seams keeps every per-vertex table in step."""

import numpy as np
import pytest

from mpeg4 import InputError
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable, apply_fat
from mpeg4.head import FeaturePointBinding, Head, Part, SparseDisplacement
from mpeg4.seams import split_vertices


def _head():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    skin = Part("skin", v, [[0, 1, 2], [1, 3, 2]])
    fps = {"2.1": FeaturePointBinding("skin", (1, 2), (0.5, 0.5))}
    targets = {"smile": {"skin": SparseDisplacement([1, 2], [[0, 0.1, 0], [0, 0, 0.2]])}}
    fat = FAT()
    fat.add(FaceDefTable(3, meshes=[FaceDefMesh("skin", [-10, 0, 10], [2], np.ones((1, 2, 3)) * 0.01)]))
    return Head({"skin": skin}, fps, targets, fat=fat, metadata={"name": "square"})


def test_duplicates_move_with_their_originals():
    head = _head()
    # Vertex 1 and 2 (the shared edge) are stored twice; the second triangle uses the copies.
    source = np.array([0, 1, 2, 3, 1, 2])
    tris = np.array([[0, 1, 2], [4, 3, 5]])
    uv = np.random.default_rng(0).random((6, 2))
    out = split_vertices(head, "skin", source, tris, uv=uv)
    skin = out.parts["skin"]
    np.testing.assert_array_equal(skin.vertices, head.skin.vertices[source])
    np.testing.assert_array_equal(out.fp_position("2.1"), head.fp_position("2.1"))
    moved = out.morphed({"smile": 1.0})["skin"]
    np.testing.assert_array_equal(moved, head.morphed({"smile": 1.0})["skin"][source])
    a = apply_fat(out.fat, {"skin": skin.vertices}, {3: 7.0}, _fapu())["skin"]
    b = apply_fat(head.fat, {"skin": head.skin.vertices}, {3: 7.0}, _fapu())["skin"]
    np.testing.assert_allclose(a, b[source])
    assert out.metadata["duplicated_vertices"]["skin"] == [1, 2]
    # A second split records the originals of the first one.
    again = split_vertices(out, "skin", np.r_[np.arange(6), [5]], np.array([[0, 1, 2], [4, 3, 6]]))
    assert again.metadata["duplicated_vertices"]["skin"] == [1, 2, 2]


def _fapu():
    from mpeg4.fapu import FAPU

    return FAPU(0.01, 0.06, 0.05, 0.02, 0.05)


def test_split_refuses_a_reordering_and_bad_indices():
    head = _head()
    with pytest.raises(InputError, match="original vertices first"):
        split_vertices(head, "skin", [1, 0, 2, 3], [[0, 1, 2]])
    with pytest.raises(InputError, match="outside"):
        split_vertices(head, "skin", [0, 1, 2, 3], [[0, 1, 9]])
    with pytest.raises(InputError, match="no part"):
        split_vertices(head, "hair", [0], [[0, 0, 0]])
