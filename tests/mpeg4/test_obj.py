"""OBJ heads: round trip of our own files, foreign files, malformed lines."""

import numpy as np
import pytest

from mpeg4 import InputError
from mpeg4.io import load_head, read_obj, save_head, write_obj

from .test_gltf import small_head


def test_round_trip(tmp_path):
    head = small_head()
    warnings = write_obj(head, tmp_path / "h.obj")
    assert any("morph targets" in w for w in warnings) and any("animation tables" in w for w in warnings)
    for f in ("h.obj", "h.mtl", "h.fdp.json", "h_skin.png"):
        assert (tmp_path / f).exists()
    back = read_obj(tmp_path / "h.obj")
    assert list(back.parts) == list(head.parts)
    for name, p in head.parts.items():
        q = back.parts[name]
        assert np.abs(q.vertices - p.vertices).max() < 1e-9
        np.testing.assert_array_equal(q.triangles, p.triangles)
        assert q.colour == pytest.approx(p.colour, abs=1e-6)
        if p.centre is not None:
            np.testing.assert_allclose(q.centre, p.centre)
    assert np.abs(back.skin.uv - head.skin.uv).max() < 1e-9
    np.testing.assert_array_equal(back.skin.texture, head.skin.texture)
    assert back.feature_points == head.feature_points
    assert back.metadata == head.metadata
    # Through the extension dispatch too.
    save_head(head, tmp_path / "again.obj")
    assert load_head(tmp_path / "again.obj").fapu.as_dict() == pytest.approx(head.fapu.as_dict())


def test_foreign_obj_with_quads_and_seams(tmp_path):
    text = """# a quad whose corners carry two uv sets at one vertex
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5
g face
f 1/1 2/2 3/3 4/4
f 1/5 3/3 4/4
"""
    path = tmp_path / "quad.obj"
    path.write_text(text)
    head = read_obj(path)
    part = head.parts["face"]
    assert len(part.triangles) == 3
    assert part.n_vertices == 5  # vertex 1 duplicated for its second uv
    np.testing.assert_array_equal(part.vertices[:4], [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_array_equal(part.vertices[4], [0, 0, 0])
    np.testing.assert_array_equal(part.uv[4], [0.5, 0.5])


@pytest.mark.parametrize("line, message", [("v 1 2", r"bad.obj, line 2: malformed 'v' line"),
                                           ("f 1 2 9", r"bad.obj, line 2: malformed 'f' line")])
def test_malformed_lines(tmp_path, line, message):
    path = tmp_path / "bad.obj"
    path.write_text(f"v 0 0 0\n{line}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match=message):
        read_obj(path)
