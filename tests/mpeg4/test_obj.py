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
    assert back.parts["eye_l"].uv is None and back.parts["eye_l"].texture is None
    np.testing.assert_array_equal(back.skin.texture, head.skin.texture)
    assert back.feature_points == head.feature_points
    assert max(float(np.abs(back.fp_position(i) - head.fp_position(i)).max()) for i in head.feature_points) < 1e-9
    assert back.metadata == head.metadata
    assert not back.morph_targets and back.fat is None
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


def test_foreign_obj_groups_negative_indices_and_materials(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl tex\nKd 0.5 0.5 0.5\nmap_Kd -s 1 1 1 t.png\n")
    import cv2

    img = np.zeros((4, 6, 3), np.uint8)
    img[0, 0] = (10, 20, 30)  # RGB
    cv2.imwrite(str(tmp_path / "t.png"), img[..., ::-1])
    text = """mtllib m.mtl
o a
g a
usemtl red
v 0 0 0
v 1 0 0
v 1 1 0
vn 0 0 1
f 1//1 2//1 3//1
g b
usemtl tex
v 2 0 0
v 3 0 0
v 3 1 0
v 2 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f -4/-4 -3/-3 -2/-2 -1/-1
"""
    path = tmp_path / "two.obj"
    path.write_text(text)
    head = read_obj(path)
    assert list(head.parts) == ["a", "b"]
    a, b = head.parts["a"], head.parts["b"]
    assert a.colour == (1, 0, 0) and a.uv is None and a.n_vertices == 3
    np.testing.assert_array_equal(b.vertices, [[2, 0, 0], [3, 0, 0], [3, 1, 0], [2, 1, 0]])
    np.testing.assert_array_equal(b.triangles, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_array_equal(b.uv, [[0, 0], [1, 0], [1, 1], [0, 1]])
    assert b.texture.shape == (4, 6, 3) and tuple(b.texture[0, 0]) == (10, 20, 30)


def test_faces_without_groups_form_the_skin(tmp_path):
    path = tmp_path / "plain.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 2 0\nf 1 2 3 4 5\n")
    head = read_obj(path)
    assert list(head.parts) == ["skin"]
    np.testing.assert_array_equal(head.skin.triangles, [[0, 1, 2], [0, 2, 3], [0, 3, 4]])


def test_sidecar_from_another_mesh_is_refused(tmp_path):
    head = small_head()
    write_obj(head, tmp_path / "h.obj")
    moved = head.with_vertices({"skin": head.skin.vertices + [0, 0.01, 0]})
    write_obj(moved, tmp_path / "other.obj")
    (tmp_path / "h.fdp.json").write_bytes((tmp_path / "other.fdp.json").read_bytes())
    with pytest.raises(InputError, match=r'h.fdp.json, bindings\["2.2"\]: feature point 2.2 is bound 10.00 mm away'):
        read_obj(tmp_path / "h.obj")


@pytest.mark.parametrize("line, message", [("v 1 2", r"bad.obj, line 2: malformed 'v' line: 'v 1 2' \(fix: "),
                                           ("v 1 2 x", r"bad.obj, line 2: malformed 'v' line"),
                                           ("vt", r"bad.obj, line 2: malformed 'vt' line"),
                                           ("f 1 2", r"bad.obj, line 2: malformed 'f' line"),
                                           ("f 1/7 2 3", r"bad.obj, line 2: malformed 'f' line"),
                                           ("f 1 2 9", r"bad.obj, line 2: malformed 'f' line")])
def test_malformed_lines(tmp_path, line, message):
    path = tmp_path / "bad.obj"
    path.write_text(f"v 0 0 0\n{line}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match=message) as e:
        read_obj(path)
    assert "\n" not in str(e.value)


def test_missing_and_empty_files(tmp_path):
    with pytest.raises(InputError, match=r"nope.obj: head file not found"):
        read_obj(tmp_path / "nope.obj")
    (tmp_path / "empty.obj").write_text("v 0 0 0\n")
    with pytest.raises(InputError, match=r"empty.obj: the file has no faces"):
        read_obj(tmp_path / "empty.obj")
