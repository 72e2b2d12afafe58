import numpy as np
import pytest

from mpeg4 import FeaturePointBinding, Head, InputError, Part, SparseDisplacement


def _head():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0]])
    skin = Part("skin", v, [[0, 1, 2], [0, 2, 3]])
    fps = {"8.3": FeaturePointBinding.at_vertex("skin", 1), "8.4": FeaturePointBinding.at_vertex("skin", 3),
           "2.1": FeaturePointBinding("skin", (0, 1, 2), (0.2, 0.3, 0.5))}
    mt = {"smile": {"skin": SparseDisplacement([1, 3], [[0.1, 0, 0], [-0.1, 0, 0]])}}
    return Head({"skin": skin}, fps, mt)


def test_bound_points_follow_the_vertices():
    h = _head()
    np.testing.assert_allclose(h.fp_position("2.1"), [0.3, 0.5, 0])
    moved = h.with_vertices({"skin": h.skin.vertices + [0, 0, 1]})
    np.testing.assert_allclose(moved.fp_position("2.1"), [0.3, 0.5, 1])
    np.testing.assert_allclose(h.fp_position("2.1"), [0.3, 0.5, 0])  # the original is unchanged
    ids, arr = h.fp_array()
    assert ids == ["2.1", "8.3", "8.4"] and arr.shape == (3, 3)


def test_morph_targets_and_mirror_error():
    h = _head()
    out = h.morphed({"smile": 0.5})
    np.testing.assert_allclose(out["skin"][1], [1.05, 0, 0])
    np.testing.assert_allclose(h.mirror_error()["8.3"], 0.0)
    np.testing.assert_allclose(SparseDisplacement.from_dense(np.array([[0, 0, 0], [0, 2e-3, 0]]), 1e-3).indices, [1])


def test_bad_heads_are_rejected_with_clear_messages():
    with pytest.raises(InputError, match="part 'skin': a triangle index is outside 0..2"):
        Part("skin", np.zeros((3, 3)), [[0, 1, 3]])
    with pytest.raises(InputError, match=r"part 'skin': vertex \d+ \(of \d+ such\) has a NaN or infinite coordinate \(fix: "):
        Part("skin", [[0, 0, np.nan]] * 3, [[0, 1, 2]])
    skin = Part("skin", np.zeros((3, 3)), [[0, 1, 2]])
    with pytest.raises(InputError, match="feature point 2.1 is bound to vertex 5 of part 'skin', which has 3"):
        Head({"skin": skin}, {"2.1": FeaturePointBinding.at_vertex("skin", 5)})
    with pytest.raises(InputError, match="unknown feature point '2.99'"):
        Head({"skin": skin}, {"2.99": FeaturePointBinding.at_vertex("skin", 0)})
    with pytest.raises(InputError, match="the head has no feature point 3.5"):
        Head({"skin": skin}).fp_position("3.5")
    with pytest.raises(InputError, match="weights sum to"):
        FeaturePointBinding("skin", (0, 1), (0.5, 0.6))
    with pytest.raises(InputError, match="no morph target 'frown'"):
        Head({"skin": skin}).morphed({"frown": 1})


def test_atomic_write_keeps_normal_permissions_and_the_old_file_on_error(tmp_path):
    import os

    from mpeg4.io import atomic_write

    p = tmp_path / "a.txt"
    with atomic_write(p, "w") as f:
        f.write("one")
    umask = os.umask(0)
    os.umask(umask)
    assert (p.stat().st_mode & 0o777) == 0o666 & ~umask
    try:
        with atomic_write(p, "w") as f:
            f.write("two")
            raise RuntimeError("crash while writing")
    except RuntimeError:
        pass
    assert p.read_text() == "one" and len(list(tmp_path.iterdir())) == 1


def test_sparse_displacements_add():
    from mpeg4 import SparseDisplacement

    a = SparseDisplacement([0, 3], [[1.0, 0, 0], [0, 1.0, 0]])
    b = SparseDisplacement([3, 5], [[0, -1.0, 0], [0, 0, 2.0]])
    s = a + b
    np.testing.assert_array_equal(s.indices, [0, 5])  # vertex 3 cancels out
    np.testing.assert_array_equal(s.dense(6), a.dense(6) + b.dense(6))
