"""The brows' tables, each way relaxed whole (fmc.brow_crease): a lowered brow does not push
the skin through the upper lid's crease, a raised one does not crush the forehead, and the
six pieces still add up."""

import numpy as np
import pytest

from fmc.author import author_from_shapes
from fmc.brow_raise import BROW_POINTS
from fmc.conformance import SurfaceChecks
from mpeg4 import apply_fat
from mpeg4.fat import fap_unit
from mpeg4.generic_head import load_generic_head

BROWS = tuple(range(31, 37))


@pytest.fixture(scope="module")
def authored():
    head = load_generic_head()
    # Without the other FAPs' tables: the brows' own fields, as authored (no separation).
    head.fat, _ = author_from_shapes(head, faps=BROWS, separate=False, unfold=False, bound=False)
    return head


def _moved(head, values):
    base = {name: p.vertices for name, p in head.parts.items()}
    return apply_fat(head.fat, base, values, head.fapu)


def test_lowered_brows_do_not_fold_the_lid_crease(authored):
    """Run backwards, the raise turned 11 skin triangles over in the crease by 3.13 with
    ``raise_l_m_eyebrow`` alone at -150 and 44 at -300, the outer brow 46 at -300; the four
    inner and middle brows at -156 (Greta's anger) 34, all six at -200 112. Now none."""
    checks = SurfaceChecks(authored)
    for values in ({33: -150.0}, {33: -300.0}, {35: -300.0}, {31: -300.0},
                   dict.fromkeys((31, 32, 33, 34), -156.0), dict.fromkeys(BROWS, -200.0)):
        skin = _moved(authored, values)["skin"]
        assert checks.inverted(skin) == 0, values
        assert checks.stretch(skin) < 2.0, values


def test_raised_brows_fold_the_forehead_less(authored):
    """Greta's surprise raises the brows by 410 to 560: 41 triangles turned over around
    4.3/4.4 with the sculpted raise (17 with ``raise_l_m_eyebrow`` alone at 600); 8 and 12
    with the whole raise relaxed; none since the forehead fades and slides
    (:func:`fmc.brow_crease.forehead_motion`)."""
    checks = SurfaceChecks(authored)
    surprise = {31: 460.0, 32: 460.0, 33: 560.0, 34: 520.0, 35: 410.0, 36: 410.0}
    assert checks.inverted(_moved(authored, surprise)["skin"]) <= 2
    assert checks.inverted(_moved(authored, {33: 600.0})["skin"]) <= 2
    for v in (150.0, 300.0):
        assert checks.inverted(_moved(authored, {33: v})["skin"]) == 0


def test_each_brow_point_moves_its_own_way(authored):
    """Each piece moves its point by value × ENS up or down (along the FAP's axis, as the
    conformance judges it; raised, the point slides back over the brow ridge with the
    forehead, a third of its rise for the middle brow, as the sculpted raise has it; lowered
    it moves straight down) and leaves the other brow points still, so all six together move
    each point by its own value."""
    head = authored
    for v in (-300.0, 300.0):
        for n, fp in zip((36, 34, 32, 31, 33, 35), BROW_POINTS):
            moved = _moved(head, {n: v})
            d = head.fp_position(fp, moved) - head.fp_position(fp)
            rise = v * fap_unit(n, head.fapu)
            np.testing.assert_allclose(d[:2], [0.0, rise], atol=0.02 * abs(rise))
            assert (-0.5 * rise < d[2] <= 0.0) if v > 0 else abs(d[2]) < 0.02 * abs(rise), (n, v, d)
            for other in BROW_POINTS:
                if other != fp:
                    assert np.linalg.norm(head.fp_position(other, moved) - head.fp_position(other)) < 0.3e-3
