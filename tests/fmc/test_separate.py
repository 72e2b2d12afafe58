"""Tables that leave other FAPs' points still: each FAP alone moves only its own point among
the feature points the FAPs govern, FAPs given together add up as the standard says, and
the correction is smooth, local and blind to seams."""

import numpy as np
import pytest

from fmc.author import JAW_FAPS
from fmc.conformance import fp_conformance
from fmc.play import Player
from fmc.separate import CHAINS, REACH, correction_basis, held_rows, separate_tables
from mpeg4 import FAPS, apply_fat
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable, fap_unit
from mpeg4.generic_head import load_generic_head
from mpeg4.seams import seam_copies, split_vertices
from mpeg4.surface import contour_path


@pytest.fixture(scope="module")
def shipped():
    return load_generic_head(with_fat=True)


def _neutral(head):
    return {n: p.vertices for n, p in head.parts.items()}


def test_each_fap_alone_leaves_the_other_faps_points(shipped):
    """Every low-level table but the jaw's, at ±300, moves every other FAP's point by under
    0.01 mm along that FAP's axis (the shipped tables are stored to 2 µm), and its own by
    its value × FAPU (within 10 %): before, the cheek puff moved the lip corners 2.6 times
    as far as its own point and the chin raiser lifted the lower lip 5.4 mm."""
    rows = held_rows(shipped)
    assert len(rows) >= 45
    base = _neutral(shipped)
    worst = {}
    for n, own, axis in rows:
        if n in JAW_FAPS:
            continue
        for v in (-300.0, 300.0):
            moved = apply_fat(shipped.fat, base, {n: v}, shipped.fapu)
            d_own = (shipped.fp_position(own, moved) - shipped.fp_position(own)) @ axis
            if abs(d_own) > 1e-9:  # a table defined on this side
                assert d_own == pytest.approx(v * fap_unit(n, shipped.fapu), rel=0.10), (n, v)
            for m, fp, a in rows:
                if (fp, tuple(a)) == (own, tuple(axis)):
                    continue
                off = abs((shipped.fp_position(fp, moved) - shipped.fp_position(fp)) @ a)
                worst[(n, m)] = max(worst.get((n, m), 0.0), off)
    bad = {k: round(1e3 * w, 3) for k, w in worst.items() if w > 1e-5}
    assert not bad, bad


def test_faps_given_together_move_each_point_by_its_own(shipped):
    """Xface's pride at its peak, its jaw left out (the jaw carries the chin boss, on
    purpose: fmc.decouple): the chin raised (depress_chin 300) while the lower lip goes
    down by 147 units, the cheeks lift, the corners stretch. Every feature point a FAP of
    the frame governs lands within max(10 %, 0.5 mm) of its FAPs' value × FAPU (28 % of
    pride's frames did before)."""
    frame = {4: 10, 5: -147, 6: 62, 7: 62, 8: 10, 9: 10, 10: -147, 11: -147, 12: 50, 13: 50, 16: -5,
             17: -15, 18: 300, 41: 110, 42: 110, 51: 15, 52: -147, 53: 62, 54: 62, 55: 15, 56: 15, 57: -147, 58: -147,
             59: 50, 60: 50}
    player = Player(shipped)
    ok, total = fp_conformance(shipped, frame, moved=player.part_vertices(player.vertices(frame)))
    assert total >= 18 and ok == total


def _spread_table(head, n, fp, radius=0.03):
    """A table for FAP ``n`` that moves a broad patch around ``fp`` along the FAP's axis,
    as a sculpted shape does (and its neighbours' points with it)."""
    skin = head.skin.vertices
    w = np.exp(-(np.linalg.norm(skin - head.fp_position(fp), axis=1) / radius) ** 2)
    idx = np.flatnonzero(w > 1e-4)
    unit = fap_unit(n, head.fapu)
    d = (w[idx, None] * FAPS[n].axis_vector)[:, None, :] * (1e-3 / (100 * unit))  # 1 mm per 100 units
    return FaceDefTable(n, 0, [FaceDefMesh("skin", np.array([0.0, 512.0]), idx, d)])


def test_a_broad_table_keeps_its_own_point_and_is_corrected_only_near_the_points(shipped):
    head = shipped.copy()
    head.fat = FAT(shipped.fat)
    head.fat.add(_spread_table(head, 41, "5.3"))  # the left cheek, with the lid and the lips around it
    out = separate_tables(head, keep=JAW_FAPS)
    base = _neutral(head)
    before = apply_fat(head.fat, base, {41: 400.0}, head.fapu)["skin"]
    after = apply_fat(out, base, {41: 400.0}, head.fapu)["skin"]
    own = np.asarray(head.feature_points["5.3"].vertices)
    assert np.allclose(after[own], before[own], atol=1e-12)  # its own point exactly as it was
    changed = np.linalg.norm(after - before, axis=1) > 1e-9
    points = np.array([head.fp_position(fp) for fp in {fp for _, fp, _ in held_rows(head)}])
    far = np.linalg.norm(head.skin.vertices[:, None] - points[None], axis=2).min(axis=1) > REACH
    assert changed.any() and not (changed & far).any()
    # The lower lid and the lip corner it had moved stay now.
    for fp, axis in (("3.3", 1), ("8.3", 1)):
        b = np.asarray(head.feature_points[fp].vertices)
        assert abs(before[b][:, axis].mean() - base["skin"][b][:, axis].mean()) > 1e-4
        assert abs(after[b][:, axis].mean() - base["skin"][b][:, axis].mean()) < 1e-8
    # Smooth: no edge stretches or shrinks more than the uncorrected table's worst.
    t = np.asarray(head.skin.triangles)
    e = np.unique(np.sort(np.r_[t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1), axis=0)
    rest = np.linalg.norm(base["skin"][e[:, 0]] - base["skin"][e[:, 1]], axis=1)
    ok = rest > 1e-9
    strain = lambda v: np.abs(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)[ok] / rest[ok] - 1).max()
    assert strain(after) < 0.5


def test_the_correction_is_one_at_its_point_nothing_at_the_others_and_straight_along_a_chain(shipped):
    points = sorted({fp for _, fp, _ in held_rows(shipped)})
    basis = correction_basis(shipped, points)
    for k, fp in enumerate(points):
        v = list(shipped.feature_points[fp].vertices)
        assert np.allclose(basis[v, k], 1.0)
        assert np.allclose(np.delete(basis[v], k, axis=1), 0.0)
    chain = next(c for c in CHAINS if c[0] == "8.3" and c[1] == "8.7")
    path = contour_path(shipped, chain)[1]  # 8.7 to 8.2
    s = np.r_[0, np.cumsum(np.linalg.norm(np.diff(shipped.skin.vertices[path], axis=0), axis=1))]
    s /= s[-1]
    # (a point inside a triangle holds its three vertices, one of which may lie on the path)
    bound = np.isin(path, np.concatenate([b.vertices for b in shipped.feature_points.values()]))
    assert (~bound).sum() >= 5
    assert np.allclose(basis[path[~bound], points.index("8.2")], s[~bound])
    assert np.allclose(basis[path[~bound], points.index("8.7")], 1 - s[~bound])


def test_seam_copies_are_corrected_alike(shipped):
    """A textured head stores a seam's vertices twice: both copies get one correction."""
    head = shipped.copy()
    skin = head.skin
    # Cut the skin along the midline below the nose (through the lips and the chin).
    v = skin.vertices
    t = np.asarray(skin.triangles)
    x0 = head.fp_position("2.2")[0]
    right = v[t].mean(axis=1)[:, 0] < x0
    seam = np.unique(t[right][np.abs(v[t[right]][..., 0] - x0) < 1e-9])
    seam = np.unique(np.r_[seam, np.flatnonzero((np.abs(v[:, 0] - x0) < 2e-3) & (v[:, 1] < head.fp_position("9.15")[1]))])
    inner = np.isin(t, seam) & right[:, None]
    source = np.r_[np.arange(len(v)), seam]
    new_index = {int(s): len(v) + i for i, s in enumerate(seam)}
    t2 = t.copy()
    t2[inner] = [new_index[int(i)] for i in t[inner]]
    split = split_vertices(head, "skin", source, t2)
    first, inverse = seam_copies(split.skin.vertices)
    assert len(first) == len(v)  # the copies are one place each
    out = separate_tables(split, keep=JAW_FAPS)
    moved = apply_fat(out, _neutral(split), {18: 300.0, 52: -150.0}, split.fapu)["skin"]
    assert np.allclose(moved[len(v):], moved[seam], atol=1e-9)
