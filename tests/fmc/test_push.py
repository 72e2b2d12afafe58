"""The lips' pushes (FAPs 16/17): the lip moves in depth with its point, and the lip
corners' crease does not turn over (fmc.push)."""

import numpy as np
import pytest

from fmc.author import author_from_shapes
from fmc.conformance import SurfaceChecks
from fmc.push import along_axis
from mpeg4 import apply_fat
from mpeg4.fat import fap_unit
from mpeg4.generic_head import load_generic_head
from mpeg4.head import SparseDisplacement

# The push and the FAPs that hold the lip corners (stretch and raise), whose points the
# separation keeps still: the fold came from the lip spreading into the held corners.
FAPS = (6, 7, 12, 13, 16)


@pytest.fixture(scope="module")
def authored():
    head = load_generic_head()
    head.fat, _ = author_from_shapes(head, faps=FAPS)
    return head


def _play(head, values):
    base = {name: p.vertices for name, p in head.parts.items()}
    return apply_fat(head.fat, base, values, head.fapu)


def test_along_axis_keeps_the_axis_component():
    d = {"skin": SparseDisplacement([2, 5], [[1.0, 2.0, 3.0], [-4.0, 0.5, -1.0]])}
    out = along_axis(d, np.array([0.0, 0.0, 2.0]))["skin"]
    assert out.indices.tolist() == [2, 5]
    np.testing.assert_allclose(out.vectors, [[0.0, 0.0, 3.0], [0.0, 0.0, -1.0]])


def test_push_moves_its_point_forward_only(authored):
    """At ±300 the lower lip's centre 2.3 moves 300 × MNS in depth, and the lip beside it
    (2.8, whose x no FAP governs) does not spread sideways (the fit spread it 2.8 mm at 300)."""
    for v in (-300.0, 300.0):
        moved = _play(authored, {16: v})
        d = authored.fp_position("2.3", moved) - authored.fp_position("2.3")
        assert d[2] == pytest.approx(v * fap_unit(16, authored.fapu), rel=0.02)
        side = authored.fp_position("2.8", moved) - authored.fp_position("2.8")
        assert abs(side[0]) < 0.2e-3, (v, side)


def test_push_does_not_fold_the_lip_corners(authored):
    """``push_b_lip`` alone at 300 turned 60 skin triangles over in the lip corners' crease
    and 120 at 600 before its field kept to depth; now a handful at most."""
    checks = SurfaceChecks(authored)
    assert checks.inverted(_play(authored, {16: 300.0})["skin"]) <= 5
    assert checks.inverted(_play(authored, {16: -300.0})["skin"]) == 0
    assert checks.inverted(_play(authored, {16: 600.0})["skin"]) <= 40
