"""recon.mark on a head made of many meshes: teeth, gums, tongue and a throat told apart,
the unit from the face's proportions, and parts a person names (--part ROLE=PART).

The head is built here: the generic head's parts as separate meshes under other names, its
mouth parts as another artist might have made them (wider, lower and further back), a
throat tube behind the tongue and, for the unit, shoulders and a chest below the neck. The
2D detector is :func:`recon.evaluate.synthetic.perfect_detector`.
"""

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from mpeg4.errors import InputError
from mpeg4.generic_head import load_generic_head
from mpeg4.head import Head, Part
from recon.evaluate.synthetic import perfect_detector
from recon.mark import check_given_parts, estimate_frame, mark, parse_part_options

FILE_NAMES = {"skin": "Head", "eye_l": "Eye_L", "eye_r": "Eye_R", "teeth_upper": "TeethTop",
              "teeth_lower": "TeethBottom", "gums_upper": "GumsTop", "gums_lower": "GumsBottom", "tongue": "Tongue"}


def multipart_head(scale: float, bust: bool = False) -> tuple[Head, dict]:
    """(the head in file units of 1/scale m, its true feature points in those units)."""
    g = load_generic_head()
    parts = {}
    for role, name in FILE_NAMES.items():
        v = g.parts[role].vertices
        if role not in ("skin", "eye_l", "eye_r"):  # another artist's mouth: wider, 1.5 mm lower and back
            c = v.mean(axis=0)
            v = (v - c) * [1.08, 1.0, 1.05] + c + [0.0, -0.0015, -0.0015]
        parts[name] = Part(name, v * scale, g.parts[role].triangles)
    tube = trimesh.creation.cylinder(radius=0.013, segment=[[0, -0.035, 0.025], [0, -0.13, 0.0]], sections=24)
    parts["Throat"] = Part("Throat", np.asarray(tube.vertices) * scale, np.asarray(tube.faces))
    if bust:  # the mesh 2.5 times as tall as the head
        box = trimesh.creation.box(extents=[0.45, 0.5, 0.25])
        parts["Body"] = Part("Body", (np.asarray(box.vertices) + [0, -0.45, -0.02]) * scale, np.asarray(box.faces))
    return Head(parts, {}, {}), {i: g.fp_position(i) * scale for i in g.feature_points}


@pytest.fixture(scope="module")
def in_mm():
    head, truth = multipart_head(1000.0)
    return head, truth, mark(head, detect=perfect_detector(truth), passes=1)


def test_mouth_parts_are_told_apart_and_the_throat_keeps_its_name(in_mm):
    _, _, result = in_mm
    assert {role: s.source for role, s in result.fdp.parts.items()} == FILE_NAMES
    assert all(s.vertices is None for s in result.fdp.parts.values())  # each taken whole
    assert "Throat" in result.head.parts  # no role: static, under its own name
    assert result.head.feature_points["6.1"].part == "tongue"
    assert "gums_upper: part 'GumsTop'" in result.notes


def test_the_unit_of_a_bust_in_its_own_units_comes_from_the_face():
    """A head-and-shoulders mesh in its own units: its size alone would make the head a
    third of its size; the eyes' distance makes it the right size."""
    scale = 1 / 0.12  # CANDIDE-like units: about ±1 for the head
    head, truth = multipart_head(scale, bust=True)
    assert estimate_frame(head).scale * scale < 0.5  # what the size alone says
    result = mark(head, detect=perfect_detector(truth), passes=1)
    assert result.frame.scale * scale == pytest.approx(1.0, rel=0.05)  # measured 0.9995
    es0 = np.linalg.norm(result.head.fp_position("3.5") - result.head.fp_position("3.6"))
    g = load_generic_head()
    assert es0 == pytest.approx(np.linalg.norm(g.fp_position("3.5") - g.fp_position("3.6")), rel=0.05)
    assert any(n.startswith("unit: none of m, cm, mm (the face's eyes") for n in result.notes)
    assert result.reliable, [p.message for p in result.problems]


def test_a_metric_unit_the_size_got_wrong_is_put_right_by_the_face():
    """A head in centimetres on a 1.1 m body: by its size the mesh would be in millimetres
    (a head 10 times too small); its eyes say centimetres. (The axes are given: at a tenth
    of its size the nose is no narrower than the body's corners, and the frame needs the nose.)"""
    head, truth = multipart_head(100.0, bust=True)
    body = head.parts["Body"]
    head.parts["Body"] = Part("Body", body.vertices * [1.0, 2.2, 1.0] + [0.0, -40.0, 0.0], body.triangles)
    assert estimate_frame(head, up="+y", forward="+z").unit == "mm"
    result = mark(head, detect=perfect_detector(truth), passes=1, up="+y", forward="+z")
    assert result.frame.unit == "cm" and result.frame.scale == pytest.approx(0.01)
    assert any(n.startswith("unit: cm (from the face") for n in result.notes)


def test_parts_a_person_names_take_the_place_of_those_found(in_mm):
    head, truth, _ = in_mm
    result = mark(head, detect=perfect_detector(truth), passes=1, parts={"tongue": None, "gums_upper": "Throat"})
    sources = {role: s.source for role, s in result.fdp.parts.items()}
    assert "tongue" not in sources and sources["gums_upper"] == "Throat"
    assert {"GumsTop", "Tongue"} <= set(result.head.parts)  # taken by no role now: their own names
    assert sources["teeth_upper"] == "TeethTop"  # the rest as found
    assert "tongue: none (given)" in result.notes and "gums_upper: part 'Throat' (given)" in result.notes


def test_bad_part_options_are_refused_before_any_work(tmp_path):
    assert parse_part_options(["teeth_upper=Top", "tongue=none", "gums_lower="]) == {
        "teeth_upper": "Top", "tongue": None, "gums_lower": None}
    for opt, words in ((["tongue"], "is not ROLE=PART"), (["throat=Tube"], "'throat' is not a part's role"),
                       (["tongue=A", "tongue=B"], "twice")):
        with pytest.raises(InputError, match=words):
            parse_part_options(opt)
    head, _ = multipart_head(1000.0)
    with pytest.raises(InputError, match="the mesh has no part 'Tube'") as e:
        check_given_parts(head, {"tongue": "Tube"})
    assert "Throat" in e.value.fix
    with pytest.raises(InputError, match="two roles"):
        check_given_parts(head, {"tongue": "Throat", "gums_lower": "Throat"})
    # The command refuses it at once, naming the mesh's parts.
    from chain.cli import app
    from mpeg4.io import save_head

    path = tmp_path / "multi.glb"
    save_head(head, path)
    out = CliRunner().invoke(app, ["mark", str(path), "--part", "tongue=Tube"])
    assert isinstance(out.exception, InputError) and "Throat" in out.exception.fix
