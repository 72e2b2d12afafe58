"""GLB round trips, validity (Khronos validator) and bad files."""

import numpy as np
import pytest
import trimesh

from mpeg4 import (FAT, FaceDefMesh, FaceDefTable, FaceDefTransform, FeaturePointBinding, Head, InputError, Part,
                   SparseDisplacement, apply_fat)
from mpeg4.io import load_head, read_glb, save_head, write_glb


def small_head(textured=True, with_fat=True):
    rng = np.random.default_rng(0)
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.09)
    skin_v = sphere.vertices * [0.8, 1.0, 0.9]
    uv = np.c_[0.5 + 0.5 * np.arctan2(skin_v[:, 0], skin_v[:, 2]) / np.pi, 0.5 + skin_v[:, 1] / 0.2]
    tex = rng.integers(0, 255, (16, 24, 3), dtype=np.uint8)
    skin = Part("skin", skin_v, sphere.faces, uv=uv if textured else None, texture=tex if textured else None,
                colour=(0.9, 0.75, 0.65))
    eye = trimesh.creation.icosphere(subdivisions=1, radius=0.012)
    eyes = [Part(n, eye.vertices + c, eye.faces, colour=(1, 1, 1), centre=c)
            for n, c in (("eye_l", np.array([0.032, 0.03, 0.07])), ("eye_r", np.array([-0.032, 0.03, 0.07])))]
    teeth = Part("teeth_lower", sphere.vertices[:40] * 0.2 + [0, -0.03, 0.06], sphere.faces[:10] % 40)
    order = np.argsort(skin_v[:, 1])
    # Feature points: pupils on the eyes, the rest on skin (one barycentric).
    top, bottom, front = int(eye.vertices[:, 1].argmax()), int(eye.vertices[:, 1].argmin()), int(eye.vertices[:, 2].argmax())
    fps = {"3.5": FeaturePointBinding.at_vertex("eye_l", front), "3.6": FeaturePointBinding.at_vertex("eye_r", front),
           "3.1": FeaturePointBinding.at_vertex("eye_l", top), "3.3": FeaturePointBinding.at_vertex("eye_l", bottom),
           "9.15": FeaturePointBinding.at_vertex("skin", int(order[80])),
           "2.2": FeaturePointBinding("skin", (int(order[60]), int(order[61]), int(order[62])), (0.2, 0.3, 0.5)),
           "8.3": FeaturePointBinding.at_vertex("skin", int(skin_v[:, 0].argmax())),
           "8.4": FeaturePointBinding.at_vertex("skin", int(skin_v[:, 0].argmin()))}
    morph = {"jawOpen": {"skin": SparseDisplacement([1, 4, 9], rng.normal(0, 0.003, (3, 3))),
                         "teeth_lower": SparseDisplacement(np.arange(40), np.tile([0, -0.01, 0], (40, 1)))},
             "eyeLookUp_L": {"eye_l": SparseDisplacement(np.arange(10), rng.normal(0, 0.001, (10, 3)))}}
    head = Head([skin, *eyes, teeth], fps, morph, metadata={"source": "test", "n": 3})
    if with_fat:
        fat = FAT()
        fat.add(FaceDefTable(3, meshes=[FaceDefMesh("skin", [-200, 0, 300, 1000], [2, 3, 7],
                                                    rng.normal(0, 1e-3, (3, 3, 3)))],
                             transforms=[FaceDefTransform("teeth_lower", "rotation", [0, -0.02, 0.0], [1, 0, 0], 1.0)]))
        fat.add(FaceDefTable(23, transforms=[FaceDefTransform("eye_l", "rotation", [0.032, 0.03, 0.07],
                                                              [0, 1, 0], 1.0)]))
        fat.add(FaceDefTable(49, transforms=[FaceDefTransform(None, "rotation", [0, -0.02, -0.01], [0, 1, 0], 1.0)]))
        fat.add(FaceDefTable(1, 4, meshes=[FaceDefMesh("skin", [0, 63], [10, 11], rng.normal(0, 1e-4, (2, 1, 3)))]))
        head.fat = fat
    return head


def test_round_trip_keeps_everything(tmp_path, validate_gltf):
    head = small_head()
    path = tmp_path / "h.glb"
    write_glb(head, path)
    back = read_glb(path)
    assert list(back.parts) == list(head.parts)
    for name, p in head.parts.items():
        q = back.parts[name]
        assert np.abs(q.vertices - p.vertices).max() < 1e-6
        np.testing.assert_array_equal(q.triangles, p.triangles)
        assert q.colour == pytest.approx(p.colour, abs=1e-6)
        if p.centre is not None:
            np.testing.assert_allclose(q.centre, p.centre, atol=1e-7)
    np.testing.assert_allclose(back.skin.uv, head.skin.uv, atol=1e-6)
    np.testing.assert_array_equal(back.skin.texture, head.skin.texture)
    for i in head.feature_points:
        assert back.feature_points[i] == head.feature_points[i]
        assert np.abs(back.fp_position(i) - head.fp_position(i)).max() < 1e-6
    assert set(back.morph_targets) == set(head.morph_targets)
    for name, t in head.morph_targets.items():
        for part, d in t.items():
            np.testing.assert_array_equal(back.morph_targets[name][part].indices, d.indices)
            np.testing.assert_allclose(back.morph_targets[name][part].vectors, d.vectors, atol=1e-7)
    assert back.metadata == head.metadata
    # The tables play back the same.
    neutral = {n: p.vertices for n, p in head.parts.items()}
    neutral_back = {n: p.vertices for n, p in back.parts.items()}
    for values in ({3: 500.0}, {3: -350.0, 23: 20000.0}, {(1, 4): 40.0, 3: 1200.0, 49: -15000.0}):
        a = apply_fat(head.fat, neutral, values, head.fapu)
        b = apply_fat(back.fat, neutral_back, values, back.fapu)
        for n in a:
            assert np.abs(a[n] - b[n]).max() < 2e-6
    report = validate_gltf(path)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"][:5]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"][:5]


def test_eyes_are_nodes_at_their_centres(tmp_path):
    import pygltflib

    head = small_head(textured=False, with_fat=False)
    path = save_head(head, tmp_path / "h.glb")
    g = pygltflib.GLTF2().load(path)
    eye = next(n for n in g.nodes if n.name == "eye_l")
    np.testing.assert_allclose(eye.translation, head.parts["eye_l"].centre)
    mesh = g.meshes[eye.mesh]
    assert mesh.extras["targetNames"] == ["eyeLookUp_L"]  # only the targets that move it
    assert g.meshes[g.nodes[0].mesh].extras["targetNames"] == ["jawOpen", "eyeLookUp_L"]


def test_sparse_targets_keep_files_small(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=0.1)  # 40962 vertices
    n = len(sphere.vertices)
    rng = np.random.default_rng(1)
    targets = {f"t{k}": {"skin": SparseDisplacement(rng.choice(n, 2000, replace=False), rng.normal(0, 1e-3, (2000, 3)))}
               for k in range(50)}
    head = Head([Part("skin", sphere.vertices, sphere.faces)], {}, targets)
    path = write_glb(head, tmp_path / "big.glb")
    size = (tmp_path / "big.glb").stat().st_size
    base = n * 24 + len(sphere.faces) * 12  # positions + normals, indices
    sparse = 50 * 2000 * 16  # index + vec3 per moved vertex
    assert size < 1.05 * (base + sparse) + 20000
    assert read_glb(path).morph_targets["t7"]["skin"].indices.tolist() == sorted(targets["t7"]["skin"].indices.tolist())


def test_foreign_glb_from_trimesh_loads(tmp_path):
    scene = trimesh.Scene()
    box = trimesh.creation.box((0.1, 0.2, 0.3))
    scene.add_geometry(box, node_name="thing", transform=trimesh.transformations.translation_matrix([1, 2, 3]))
    path = tmp_path / "foreign.glb"
    scene.export(path)
    head = load_head(path)
    assert len(head.parts) == 1 and not head.feature_points
    part = next(iter(head.parts.values()))
    np.testing.assert_allclose(part.vertices.mean(axis=0), [1, 2, 3], atol=1e-6)


def test_feature_points_read_from_the_json_chunk_alone(tmp_path):
    from mpeg4.io.gltf import read_glb_feature_points

    head = small_head()
    path = tmp_path / "h.glb"
    write_glb(head, path)
    fps = read_glb_feature_points(path)
    assert list(fps) == list(head.fp_positions())
    for i, p in head.fp_positions().items():
        np.testing.assert_allclose(fps[i], p, atol=1e-9)
    scene = trimesh.Scene(trimesh.creation.box((0.1, 0.2, 0.3)))
    scene.export(tmp_path / "foreign.glb")
    assert read_glb_feature_points(tmp_path / "foreign.glb") == {}
    (tmp_path / "junk.glb").write_bytes(b"not a head")
    with pytest.raises(InputError, match="not a glTF file"):
        read_glb_feature_points(tmp_path / "junk.glb")


def test_bad_files_give_one_line_errors(tmp_path):
    with pytest.raises(InputError, match="head file not found"):
        load_head(tmp_path / "missing.glb")
    junk = tmp_path / "junk.glb"
    junk.write_bytes(b"this is not a glb file at all")
    with pytest.raises(InputError, match="junk.glb: not a readable glTF/GLB"):
        load_head(junk)
    good = write_glb(small_head(), tmp_path / "good.glb")
    data = open(good, "rb").read()
    cut = tmp_path / "cut.glb"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cut.glb"):
        load_head(cut)
    with pytest.raises(InputError, match="cannot write heads as '.stl'"):
        save_head(small_head(), tmp_path / "x.stl")
