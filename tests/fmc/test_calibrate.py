"""Cloned tables scaled so that their own feature point moves by value × FAPU on the target."""

import numpy as np
import pytest

from fmc.clone import LIMITS, calibrate_tables
from mpeg4 import FAPS, apply_fat
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable, fap_unit
from mpeg4.generic_head import load_generic_head


@pytest.fixture(scope="module")
def head():
    return load_generic_head(with_fat=True)


def _scaled(table, k):
    return FaceDefTable(table.fap, table.high_level,
                        [FaceDefMesh(m.part, m.borders, m.indices, m.displacements * k) for m in table.meshes],
                        list(table.transforms))


def _along(head, fat, n, value):
    fp = FAPS[n].feature_points[0]
    base = {k: p.vertices for k, p in head.parts.items()}
    moved = apply_fat(fat, base, {n: value}, head.fapu)
    return float((head.fp_position(fp, moved) - head.fp_position(fp)) @ FAPS[n].axis_vector)


def test_a_short_or_long_table_is_scaled_to_value_times_fapu_and_a_far_one_is_reported(head):
    """A lip corner's raise cloned 10 % short and a lid's close 15 % long move their point
    by exactly value × FAPU after calibration, both ways; a nose stretch at half its motion
    (a factor of 2, beyond the limits) is left as it was and reported."""
    fat = FAT(head.fat)
    fat.add(_scaled(head.fat[(12, 0)], 0.9))
    fat.add(_scaled(head.fat[(19, 0)], 1.15))
    fat.add(_scaled(head.fat[(61, 0)], 0.5))
    out, off = calibrate_tables(head, fat)
    for n in (12, 19):
        for v in (-300.0, 300.0):
            assert _along(head, out, n, v) == pytest.approx(v * fap_unit(n, head.fapu), rel=1e-9), (n, v)
    assert set(off) == {61}
    own = _along(head, head.fat, 61, 300.0) / (300.0 * fap_unit(61, head.fapu))
    assert off[61] == pytest.approx(2.0 / own, rel=1e-6) and off[61] > LIMITS[1]
    assert out[(61, 0)] is fat[(61, 0)]
    # Tables with transforms (eyeball turns) and high-level ones are never touched.
    assert out[(23, 0)] is fat[(23, 0)]
    assert all(out[k] is fat[k] for k in fat if k[1])


def test_tables_that_already_conform_keep_their_motion(head):
    fat = FAT(head.fat)
    exact, _ = calibrate_tables(head, fat)
    again, off = calibrate_tables(head, exact)
    for (n, hl), table in exact.items():
        if hl or not 3 <= n <= 68 or FAPS[n].kind != "translation" or table.transforms:
            continue
        for a, b in zip(table.meshes, again[(n, hl)].meshes):
            np.testing.assert_allclose(b.displacements, a.displacements, rtol=1e-9, atol=1e-15)


def test_a_lip_fap_is_scaled_with_the_partner_a_player_fills_in(head):
    """A lip FAP played alone brings its other contour's partner at the same value
    (fill_lip_contours). Cloned onto MakeHuman, the outer lower lip's table moved the inner
    point 2.8 by a tenth of its motion, and 2.8 went 10 % too far: the partner's share is
    counted in, so the two together move it by value × FAPU."""
    from mpeg4.io.fap import fill_lip_contours

    inner, outer = 10, 57
    fat = FAT(head.fat)
    t_in, t_out = head.fat[(inner, 0)], head.fat[(outer, 0)]
    # The outer table takes a tenth of the inner one's motion on top of its own.
    lent = FaceDefTable(outer, 0, [FaceDefMesh(a.part, a.borders, a.indices, a.displacements + 0.1 * b.displacements)
                                   for a, b in zip(*(_on(t_out, t_in)))], list(t_out.transforms))
    fat.add(lent)
    out, _ = calibrate_tables(head, fat)
    base = {k: p.vertices for k, p in head.parts.items()}
    for v in (-300.0, 300.0):
        played = {n: apply_fat(f, base, fill_lip_contours({inner: v}), head.fapu) for n, f in (("before", fat),
                                                                                               ("after", out))}
        move = {k: float((head.fp_position("2.8", m) - head.fp_position("2.8")) @ FAPS[inner].axis_vector)
                for k, m in played.items()}
        want = v * fap_unit(inner, head.fapu)
        assert abs(move["before"] / want - 1) > 0.05
        # Exact: the two tables are scaled together (a 2x2 solve per interval).
        assert move["after"] == pytest.approx(want, rel=1e-9)


def _on(a, b):
    """The meshes of tables ``a`` and ``b`` brought onto ``a``'s vertices (same parts and borders)."""
    out_a, out_b = [], []
    for ma in a.meshes:
        mb = next(m for m in b.meshes if m.part == ma.part)
        idx = np.union1d(ma.indices, mb.indices)
        da = np.zeros((len(idx),) + ma.displacements.shape[1:])
        db = np.zeros_like(da)
        da[np.searchsorted(idx, ma.indices)] = ma.displacements
        db[np.searchsorted(idx, mb.indices)] = mb.displacements
        out_a.append(FaceDefMesh(ma.part, ma.borders, idx, da))
        out_b.append(FaceDefMesh(mb.part, mb.borders, idx, db))
    return out_a, out_b
