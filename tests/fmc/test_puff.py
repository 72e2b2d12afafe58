"""The cheek puffs (FAPs 39/40) on the shipped generic head: the cheek moves with its point,
no further, and swells without turning the skin over."""

import numpy as np
import pytest

from fmc.conformance import SurfaceChecks, region_over_fp
from fmc.puff import governed_points, puff_field
from mpeg4 import apply_fat
from mpeg4.fat import fap_unit
from mpeg4.generic_head import load_generic_head

PUFFS = {39: ("5.1", "8.3"), 40: ("5.2", "8.4")}  # FAP: (its cheek point, the lip corner beside it)


@pytest.fixture(scope="module")
def shipped():
    return load_generic_head(with_fat=True)


def _play(head, n, v):
    base = {name: p.vertices for name, p in head.parts.items()}
    return apply_fat(head.fat, base, {n: v}, head.fapu)


@pytest.mark.parametrize("n", sorted(PUFFS))
def test_the_cheek_moves_with_its_point_and_no_further(shipped, n):
    """At ±512 the cheek point moves by 512 × ES outwards along x, and no skin vertex further
    than 1.3 times it (the table before moved the skin beside the lip corner 2.5 times as
    far, 83 mm)."""
    fp = PUFFS[n][0]
    outwards = np.sign(shipped.fp_position(fp)[0])
    for v in (-512.0, 512.0):
        moved = _play(shipped, n, v)
        d = shipped.fp_position(fp, moved) - shipped.fp_position(fp)
        assert d[0] == pytest.approx(v * fap_unit(n, shipped.fapu) * outwards, rel=0.01)
        assert region_over_fp(shipped, n, v) <= 1.3, (n, v)


def test_the_puff_swells_without_folding(shipped):
    """Outwards no triangle turns over up to 512 (1,431 did) and no edge stretches beyond
    4 times its length (68 before). Inwards none turns over while the cheek point stays
    outside its lip corner, whose x the corner's stretch FAP holds (past it the skin
    between must fold, whatever the table)."""
    checks = SurfaceChecks(shipped)
    es = shipped.fapu.ES0 / 1024
    for n, (fp, corner) in PUFFS.items():
        skin = _play(shipped, n, 512.0)["skin"]
        assert checks.inverted(skin) == 0, n
        assert checks.stretch(skin) <= 4.0, n
        inward = abs(shipped.fp_position(fp)[0] - shipped.fp_position(corner)[0]) / es
        assert inward > 150  # the limit is not trivially small
        for v in (-60.0, -0.95 * inward):  # Greta's disgust and joy use -60 and -50
            assert checks.inverted(_play(shipped, n, v)["skin"]) == 0, (n, v)


def test_the_field_is_the_points_hat(shipped):
    """The field is the goal at the point, nothing at every other governed point, and
    points along the goal everywhere (a horizontal displacement, as the standard says)."""
    goal = np.array([0.02, 0.0, 0.0])
    d = puff_field(shipped, "5.1", goal)["skin"]
    dense = d.dense(shipped.skin.n_vertices)
    moved = {"skin": shipped.skin.vertices + dense}
    own = shipped.fp_position("5.1", moved) - shipped.fp_position("5.1")
    assert np.allclose(own, goal, atol=1e-6)
    for fp in governed_points(shipped):
        if fp != "5.1":
            off = shipped.fp_position(fp, moved) - shipped.fp_position(fp)
            assert np.linalg.norm(off) < 1e-5, fp
    assert np.abs(dense[:, 1:]).max() == 0.0
    assert np.linalg.norm(dense, axis=1).max() <= np.linalg.norm(goal) * 1.0001
