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
    fdp = fdp_from_head(head)
    write_fdp_json(tmp_path / "h.fdp.json", fdp)
    back = read_fdp_json(tmp_path / "h.fdp.json")
    moved = apply_fdp(head, back)
    for i in head.feature_points:
        np.testing.assert_allclose(moved.fp_position(i), head.fp_position(i), atol=1e-9)
    assert back.fapu.ES0 == pytest.approx(head.fapu.ES0, abs=1e-9)


def _write(tmp_path, data, text=None):
    path = tmp_path / "bad.fdp.json"
    path.write_text(text if text is not None else json.dumps(data))
    return path


def _base():
    return {"format": "mpeg4-fdp", "version": 1,
            "views": {"front": {"image": "f.jpg", "width": 100, "height": 100,
                                "points": {"3.5": [60, 50], "3.6": [40, 50]}}}}


@pytest.mark.parametrize("change, text, message", [
    (None, '{"format": "mpeg4-fdp", "version": 1,', r"bad.fdp.json: not valid JSON: .* line 1, column"),
    (lambda d: d.update(version=7), None, r"bad.fdp.json, version: version 7 is not one this reader knows \(1\)"),
    (lambda d: d["views"]["front"]["points"].update({"12.1": [1, 1]}), None,
     r"bad.fdp.json, views.front.points: unknown feature point '12.1'"),
    (lambda d: d["views"]["front"]["points"].update({"2.1": ["12", 3]}), None,
     r'bad.fdp.json, views.front.points\["2.1"\]\[0\]: .*(fix: each point is \[x, y\] in pixels)'),
    (lambda d: d["views"]["front"]["points"].update({"2.1": [150, 3]}), None,
     r'views.front.points\["2.1"\]: pixel \(150, 3\) lies outside the 100x100 image'),
    (lambda d: d.update(points3d={"9.3": [0, 0]}), None, r'points3d\["9.3"\]: .*fix: each 3D point is \[x, y, z\]'),
    (lambda d: d.update(format="something"), None, r"'format' is 'something', expected 'mpeg4-fdp'"),
])
def test_bad_files_give_one_line_errors(tmp_path, change, text, message):
    data = _base()
    if change:
        change(data)
    with pytest.raises(InputError, match=message) as e:
        read_fdp_json(_write(tmp_path, data, text))
    assert "\n" not in str(e.value)


def test_mirrored_labels_are_recognised(tmp_path):
    data = _base()
    data["views"]["front"]["points"].update({"10.1": [10, 50], "10.2": [90, 50], "10.5": [12, 60], "10.6": [88, 60]})
    with pytest.raises(InputError, match=r"ear points 10.x are on the opposite sides .*10.1, 10.5"):
        read_fdp_json(_write(tmp_path, data))
    data = _base()
    data["points3d"] = {"3.5": [-0.03, 0, 0], "3.6": [0.03, 0, 0], "8.3": [-0.02, 0, 0], "8.4": [0.02, 0, 0],
                        "4.1": [-0.01, 0, 0], "4.2": [0.01, 0, 0]}
    with pytest.raises(InputError, match="seems to name sides by the viewer's left and right"):
        read_fdp_json(_write(tmp_path, data))
    data = _base()
    data["views"]["front"]["points"].update({"10.1": [90, 50], "10.2": [10, 50]})
    read_fdp_json(_write(tmp_path, data))  # the face's own convention: accepted


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="nope.fdp.json: feature point file not found"):
        read_fdp_json(tmp_path / "nope.fdp.json")
