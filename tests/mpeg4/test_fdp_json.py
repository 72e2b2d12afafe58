"""fdp.json: round trip, schema, one-line errors, mirrored-label detection."""

import json

import numpy as np
import pytest

from mpeg4 import FAPU, FeaturePointBinding, InputError
from mpeg4.io import FdpFile, ViewAnnotation, apply_fdp, fdp_from_head, read_fdp_json, write_fdp_json
from mpeg4.io.fdp_json import schema

from .test_gltf import small_head


def _sample():
    front = ViewAnnotation("front.jpg", 1000, 1200, {"3.5": np.array([600.25, 500.0]), "3.6": np.array([400.0, 502.5]),
                                                      "10.1": np.array([800.0, 520.0]), "10.2": np.array([200.0, 520.0])},
                           {"3.5": 0.9})
    side = ViewAnnotation("side.jpg", 900, 1200, {"9.3": np.array([100.0, 700.0])})
    return FdpFile(views={"front": front, "side": side},
                   points3d={"3.5": np.array([0.032, 0.036, 0.0964]), "3.6": np.array([-0.032, 0.036, 0.0964])},
                   bindings={"3.5": FeaturePointBinding("eye_l", (3, 4), (0.25, 0.75))},
                   texcoords={"3.5": np.array([0.6, 0.55])},
                   fapu=FAPU(0.01, 0.064, 0.045, 0.02, 0.05), metadata={"source": "test", "ipd_mm": 64})


def test_round_trip(tmp_path):
    fdp = _sample()
    path = write_fdp_json(tmp_path / "a.fdp.json", fdp)
    back = read_fdp_json(path)
    assert back.version == 1 and back.metadata == fdp.metadata and back.fapu == fdp.fapu
    for name, v in fdp.views.items():
        w = back.views[name]
        assert (w.image, w.width, w.height, w.confidence) == (v.image, v.width, v.height, v.confidence)
        for i, p in v.points.items():
            np.testing.assert_array_equal(w.points[i], p)
    np.testing.assert_array_equal(back.points3d["3.6"], fdp.points3d["3.6"])
    assert back.bindings == fdp.bindings
    np.testing.assert_array_equal(back.texcoords["3.5"], fdp.texcoords["3.5"])
    # Stable, catalogue-ordered output: writing again gives the same bytes.
    again = write_fdp_json(tmp_path / "b.fdp.json", back)
    assert open(again).read() == open(path).read()


def test_schema_ships_and_is_used():
    s = schema()
    assert s["properties"]["format"]["const"] == "mpeg4-fdp"
    import jsonschema

    jsonschema.Draft202012Validator.check_schema(s)


def test_head_round_trip_through_bindings(tmp_path):
    head = small_head()
    head.metadata["fit"] = {"ipd_m": np.float64(0.064), "scale": np.array([1.0, 1.02])}
    fdp = fdp_from_head(head)
    assert fdp.views == {} and set(fdp.points3d) == set(head.feature_points)
    b = head.feature_points["2.2"]
    np.testing.assert_allclose(fdp.points3d["2.2"], np.asarray(b.weights) @ head.skin.vertices[list(b.vertices)],
                               atol=1e-15)
    np.testing.assert_allclose(fdp.texcoords["2.2"], np.asarray(b.weights) @ head.skin.uv[list(b.vertices)],
                               atol=1e-15)
    assert "3.5" not in fdp.texcoords  # the eyes have no uv
    write_fdp_json(tmp_path / "h.fdp.json", fdp)
    back = read_fdp_json(tmp_path / "h.fdp.json")
    moved = apply_fdp(head, back)
    for i in head.feature_points:
        np.testing.assert_allclose(moved.fp_position(i), head.fp_position(i), atol=1e-9)
    assert back.fapu.ES0 == pytest.approx(head.fapu.ES0, abs=1e-9)
    assert back.metadata == {"source": "test", "n": 3, "fit": {"ipd_m": 0.064, "scale": [1.0, 1.02]}}
    assert max(float(np.abs(back.points3d[i] - p).max()) for i, p in fdp.points3d.items()) <= 5e-10


def _write(tmp_path, data, text=None):
    path = tmp_path / "bad.fdp.json"
    path.write_text(text if text is not None else json.dumps(data))
    return path


def _base():
    return {"format": "mpeg4-fdp", "version": 1,
            "views": {"front": {"image": "f.jpg", "width": 100, "height": 100,
                                "points": {"3.5": [60, 50], "3.6": [40, 50]}}}}


@pytest.mark.parametrize("change, text, message", [
    (None, '{"format": "mpeg4-fdp", "version": 1,', r"bad.fdp.json: not valid JSON: .* line 1, column 38 .*fix: "),
    (None, '{"format": "mpeg4-fdp",\n "version": 1\n "views": {}}', r"bad.fdp.json: not valid JSON: .* line 3, column 2"),
    (lambda d: d.update(version=7), None,
     r"bad.fdp.json, version: version 7 is not one this reader knows \(1\) \(fix: update"),
    (lambda d: d.pop("version"), None, r"bad.fdp.json, top level: no 'version' \(this reader knows version 1\)"),
    (lambda d: d["views"]["front"]["points"].update({"12.1": [1, 1]}), None,
     r"bad.fdp.json, views.front.points: unknown feature point '12.1': not one of the 84 MPEG-4 feature points "
     r"\(fix: .*'group.index'"),
    (lambda d: d.update(points3d={"3.15": [0, 0, 0]}), None, r"bad.fdp.json, points3d: unknown feature point '3.15'"),
    (lambda d: d["views"]["front"]["points"].update({"2.1": ["12", 3]}), None,
     r'bad.fdp.json, views.front.points\["2.1"\]: expected \[x, y\] numbers, found \["12", 3\] '
     r'\(fix: each point is \[x, y\] in pixels\)'),
    (lambda d: d["views"]["front"]["points"].update({"2.1": [150, 3]}), None,
     r'bad.fdp.json, views.front.points\["2.1"\]: pixel \(150, 3\) lies outside the 100x100 image \(fix: '),
    (lambda d: d["views"]["front"]["points"].update({"2.1": [10, -0.6]}), None, r"pixel \(10, -0.6\) lies outside"),
    (lambda d: d.update(points3d={"9.3": [0, 0]}), None,
     r'bad.fdp.json, points3d\["9.3"\]: expected \[x, y, z\] numbers, found \[0, 0\] .*fix: each 3D point is'),
    (lambda d: d.update(texcoords={"9.3": [0, 0, 1]}), None, r'texcoords\["9.3"\]: expected \[u, v\] numbers'),
    (lambda d: d.update(points3d={"9.3": [0, float("nan"), 0]}), None,
     r'bad.fdp.json, line \d+, column \d+: NaN is not a finite number \(fix: '),
    (lambda d: d["views"]["front"]["points"].update({"2.1": [float("inf"), 3]}), None,
     r'bad.fdp.json, line \d+, column \d+: Infinity is not a finite number'),
    (lambda d: d.update(format="something"), None, r"bad.fdp.json, format: 'format' is 'something', expected 'mpeg4-fdp'"),
    (lambda d: d.update(colour=1), None, r"bad.fdp.json, top level: Additional properties .*fix: remove the unknown key"),
    (lambda d: d.update(bindings={"2.1": {"part": "skin", "vertices": [1, 2], "weights": [0.5, 0.6]}}), None,
     r'bindings\["2.1"\]: 2 vertices with weights summing to 1.1 \(fix: give one weight per vertex'),
])
def test_bad_files_give_one_line_errors(tmp_path, change, text, message):
    data = _base()
    if change:
        change(data)
    with pytest.raises(InputError, match=message) as e:
        read_fdp_json(_write(tmp_path, data, text))
    assert "\n" not in str(e.value)


def _front(**points):
    data = _base()
    data["views"]["front"]["points"].update({k.replace("_", "."): v for k, v in points.items()})
    return data


def test_ears_labelled_by_the_viewer_are_recognised(tmp_path):
    # 10.7/10.8 swapped (the face's left lobe drawn on the image's left) while 3.5/3.6 are right.
    data = _front(**{"10_7": [20, 70], "10_8": [80, 70]})
    with pytest.raises(InputError, match=r"views.front.points: ear pairs 10.7/10.8 are on the opposite sides while "
                                         r"all 1 non-ear pairs .*viewer's left/right.*fix: swap the ids"):
        read_fdp_json(_write(tmp_path, data))
    data = _front(**{"10_1": [10, 50], "10_2": [90, 50], "10_5": [12, 60], "10_6": [88, 60]})
    with pytest.raises(InputError, match=r"ear pairs 10.1/10.2, 10.5/10.6 are on the opposite sides"):
        read_fdp_json(_write(tmp_path, data))
    # Same in 3D: x > 0 is the face's left.
    data = _base()
    data["points3d"] = {"3.5": [0.03, 0, 0], "3.6": [-0.03, 0, 0], "10.7": [-0.07, -0.02, 0], "10.8": [0.07, -0.02, 0]}
    with pytest.raises(InputError, match=r"points3d: ear pairs 10.7/10.8 are on the opposite sides"):
        read_fdp_json(_write(tmp_path, data))


def test_whole_file_in_the_viewers_convention_is_recognised(tmp_path):
    data = _base()
    data["points3d"] = {"3.5": [-0.03, 0, 0], "3.6": [0.03, 0, 0], "8.3": [-0.02, 0, 0], "8.4": [0.02, 0, 0],
                        "4.1": [-0.01, 0, 0], "4.2": [0.01, 0, 0], "10.7": [-0.07, 0, 0], "10.8": [0.07, 0, 0]}
    with pytest.raises(InputError, match=r"points3d: 4 of 4 left/right pairs have the left point at the smaller 3D x: "
                                         r"the file seems to use the mirrored \(viewer's left/right\) convention"):
        read_fdp_json(_write(tmp_path, data))
    data = _front(**{"3_5": [40, 50], "3_6": [60, 50]})
    with pytest.raises(InputError, match=r"views.front.points: 1 of 1 .*convention \(or the photo is mirrored"):
        read_fdp_json(_write(tmp_path, data))
    # A single swapped pair among correct ones is named as such.
    data = _front(**{"8_3": [30, 80], "8_4": [70, 80], "4_1": [55, 30], "4_2": [45, 30], "4_3": [70, 28],
                     "4_4": [30, 28]})
    with pytest.raises(InputError, match=r"left/right pairs 8.3/8.4 have the left point at the smaller front-photo x "
                                         r"\(fix: swap"):
        read_fdp_json(_write(tmp_path, data))


def test_face_convention_is_accepted(tmp_path):
    data = _front(**{"10_1": [90, 50], "10_2": [10, 50], "10_7": [85, 70], "10_8": [15, 70]})
    data["points3d"] = {"3.5": [0.03, 0, 0], "3.6": [-0.03, 0, 0], "10.7": [0.07, 0, 0], "10.8": [-0.07, 0, 0]}
    back = read_fdp_json(_write(tmp_path, data))
    assert back.views["front"].points["10.1"][0] == 90 and back.points3d["10.8"][0] == -0.07
    # The side view cannot tell left from right and is not checked.
    data["views"]["side"] = {"points": {"10.1": [10, 10], "10.2": [90, 10]}}
    read_fdp_json(_write(tmp_path, data))


def test_apply_fdp_rejects_another_meshs_points(tmp_path):
    head = small_head()
    fdp = fdp_from_head(head)
    fdp.points3d["8.3"] = fdp.points3d["8.3"] + [0, 0.002, 0]
    with pytest.raises(InputError, match=r'x.fdp.json, bindings\["8.3"\]: feature point 8.3 is bound 2.00 mm away'):
        apply_fdp(head, fdp, where="x.fdp.json")
    fdp = fdp_from_head(head)
    fdp.bindings["2.2"] = FeaturePointBinding("skin", (10_000,), (1.0,))
    with pytest.raises(InputError, match=r'x.fdp.json, bindings\["2.2"\]: feature point 2.2 is bound to vertex 10000'):
        apply_fdp(head, fdp, where="x.fdp.json")


def test_writer_refuses_nan(tmp_path):
    fdp = _sample()
    fdp.points3d["3.6"] = np.array([np.nan, 0, 0])
    with pytest.raises(InputError, match=r'n.fdp.json, points3d\["3.6"\]\[0\]: not a finite number'):
        write_fdp_json(tmp_path / "n.fdp.json", fdp)
    assert not (tmp_path / "n.fdp.json").exists()


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="nope.fdp.json: feature point file not found"):
        read_fdp_json(tmp_path / "nope.fdp.json")
