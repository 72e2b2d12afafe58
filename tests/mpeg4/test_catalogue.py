import numpy as np
import pytest

from mpeg4 import catalogue as c
from mpeg4.errors import InputError


def test_counts_match_the_reference():
    assert len(c.FEATURE_POINTS) == 84
    assert c.FP_GROUP_SIZES == {2: 14, 3: 14, 4: 6, 5: 4, 6: 4, 7: 1, 8: 10, 9: 15, 10: 10, 11: 6}
    assert len(c.FAPS) == 68 and sorted(c.FAPS) == list(range(1, 69))
    assert len([v for v in c.VISEMES if v]) == 14 and c.VISEMES[0].name == "neutral"
    assert [e.name for i, e in sorted(c.EXPRESSIONS.items()) if i] == [
        "joy", "sadness", "anger", "fear", "disgust", "surprise"]
    assert sorted(c.FAPU_DEFINITIONS) == ["ENS0", "ES0", "IRISD0", "MNS0", "MW0"]
    assert c.ANGLE_UNIT == 1e-5


def test_fap_groups_and_units():
    sizes = {}
    for f in c.FAPS.values():
        sizes[f.group] = sizes.get(f.group, 0) + 1
    assert sizes == {1: 2, 2: 16, 3: 12, 4: 8, 5: 4, 6: 5, 7: 3, 8: 10, 9: 4, 10: 4}
    assert c.fap(3).unit == "MNS" and c.fap(3).direction == "U"
    np.testing.assert_array_equal(c.fap("open_jaw").axis_vector, [0, -1, 0])
    assert c.fap(19).unit == "IRISD"
    # Every translation FAP's feature point is a catalogued point.
    for f in c.FAPS.values():
        for fp in f.feature_points:
            assert fp in c.FEATURE_POINTS
        if f.kind == "translation":
            assert f.axis in ("+x", "-x", "+y", "-y", "+z", "-z")


def test_left_right_pairs_mirror_and_sides_agree():
    for fp in c.FEATURE_POINTS.values():
        if fp.side == "C":
            assert fp.mirror is None
        else:
            partner = c.FEATURE_POINTS[fp.mirror]
            assert partner.mirror == fp.id and {fp.side, partner.side} == {"L", "R"}


def test_left_right_fap_pairs_share_units_and_mirror_axes():
    # Reference section 3: stretch/squeeze/puff/pull pairs have opposite x signs.
    for a, b in [(6, 7), (37, 38), (39, 40), (53, 54), (61, 62), (67, 68)]:
        assert c.fap(a).unit == c.fap(b).unit
        assert c.fap(a).axis_vector[0] == -c.fap(b).axis_vector[0]
    for a, b in [(19, 20), (31, 32), (65, 66)]:
        assert c.fap(a).axis == c.fap(b).axis


def test_unknown_ids_give_one_line_errors():
    with pytest.raises(InputError, match=r"unknown feature point '12.1'.*fix: .*group"):
        c.feature_point("12.1")
    with pytest.raises(InputError, match="unknown FAP 69"):
        c.fap(69)
    err = pytest.raises(InputError, c.check_fp_id, "2.15", where="a.fdp.json, points").value
    assert str(err).startswith("a.fdp.json, points: unknown feature point '2.15'")
    assert "\n" not in str(err)
