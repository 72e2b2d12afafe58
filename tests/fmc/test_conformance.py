"""FAPs act as the standard means together: parts move only as parts, inner and outer lip
FAPs share the lip, a stream that sets one contour moves the whole lip."""

import numpy as np
import pytest

from fmc.conformance import eyeball_centre_shift, fp_conformance, fp_prediction, part_leaks
from fmc.lip_contours import INNER_LOOP, OUTER_LOOP, innerness
from fmc.play import Player
from mpeg4 import FAPS, apply_fat
from mpeg4.generic_head import load_generic_head
from mpeg4.io.fap import LIP_CONTOUR_PAIRS, FapStream


@pytest.fixture(scope="module")
def shipped():
    return load_generic_head(with_fat=True)


def test_no_fap_moves_a_part_it_does_not_own(authored_head, shipped):
    """Every FAP at ±300, fresh and shipped tables: eyeballs, teeth, gums and tongue move
    only by their own FAPs, the jaw's and the head's (a lip corner once moved the right
    eyeball 8 mm through a pupil-dilation shape's noise)."""
    for head in (authored_head, shipped):
        leaks = part_leaks(head, 300.0)
        assert len(leaks) >= 60
        moved = {n: {p: round(m * 1e3, 3) for p, m in d.items()} for n, d in leaks.items() if d}
        assert not moved, moved


def test_eyeballs_keep_their_centres_in_a_busy_frame(shipped):
    values = {n: 300.0 for n in range(3, 69) if n not in (27, 28, 48, 49, 50)}
    values.update({23: 20000.0, 24: 20000.0, 25: -15000.0, 26: -15000.0})
    moved = apply_fat(shipped.fat, {n: p.vertices for n, p in shipped.parts.items()}, values, shipped.fapu)
    assert eyeball_centre_shift(shipped, moved) < 0.2e-3
    # The measure sees a moved eyeball.
    moved["eye_l"] = moved["eye_l"] + [0.0, 0.001, 0.0]
    assert eyeball_centre_shift(shipped, moved) == pytest.approx(1e-3, abs=0.2e-3)


def test_innerness_runs_from_the_inner_contour_to_the_outer(shipped):
    w = innerness(shipped)
    assert w.min() >= 0.0 and w.max() <= 1.0
    for i in INNER_LOOP:
        b = shipped.feature_points[i]
        assert np.allclose(w[list(b.vertices)], 1.0)
    for i in OUTER_LOOP:
        assert np.allclose(w[list(shipped.feature_points[i].vertices)], 0.0)
    between = (w > 0.05) & (w < 0.95)
    assert between.sum() > 100  # a smooth band across the lips, not a cut
    v = shipped.parts["skin"].vertices
    far = np.linalg.norm(v[:, :2] - shipped.fp_position("9.3")[:2], axis=1) < 0.01  # the nose tip
    assert np.all(w[far] == 0.0)


@pytest.mark.parametrize("inner", sorted(LIP_CONTOUR_PAIRS))
def test_inner_and_outer_lip_faps_together_move_the_lip_once(authored_head, inner):
    """FAP n and n + 47 together move the inner and the outer point each by value × FAPU
    along the axis (within max(10 %, 0.5 mm)); each alone moves its own contour and leaves
    the other's point within 0.5 mm."""
    head = authored_head
    outer = LIP_CONTOUR_PAIRS[inner]
    neutral = {n: p.vertices for n, p in head.parts.items()}
    for value in (-300.0, 300.0):
        ok, total = fp_conformance(head, {inner: value, outer: value})
        assert (ok, total) == (2, 2), value
        for own, other in ((inner, outer), (outer, inner)):
            moved = apply_fat(head.fat, neutral, {own: value}, head.fapu)
            fp_other = FAPS[other].feature_points[0]
            assert np.linalg.norm(head.fp_position(fp_other, moved) - head.fp_position(fp_other)) < 0.5e-3
            assert fp_conformance(head, {own: value}) == (1, 1)


def test_a_stream_of_one_contour_moves_the_whole_lip(shipped):
    """A frame that sets only the inner (or only the outer) FAP plays as if both were set
    to it; a frame that sets both plays them as given."""
    player = Player(shipped)
    values = np.full((3, 68), np.nan)
    values[0, 12 - 1] = 300.0                      # inner only
    values[1, 59 - 1] = 300.0                      # outer only
    values[2, [12 - 1, 59 - 1]] = (300.0, 0.0)     # both: the outer held still
    stream = FapStream.from_values(values)
    frames = list(player.play(stream))
    both = player.vertices({12: 300.0, 59: 300.0})
    assert np.abs(frames[0] - both).max() < 1e-12
    assert np.abs(frames[1] - both).max() < 1e-12
    assert np.abs(frames[2] - player.vertices({12: 300.0, 59: 0.0})).max() < 1e-12
    assert np.abs(frames[2] - frames[0]).max() > 1e-3
    held = stream.held()
    assert held.values[0, 59 - 1] == 300.0 and held.values[1, 12 - 1] == 300.0 and held.values[2, 59 - 1] == 0.0


def test_prediction_adds_up_the_faps_of_a_point(shipped):
    pred = fp_prediction(shipped, {12: 100.0, 6: 50.0, 3: 0.0, 48: 1000.0})
    motion, axes = pred["2.4"]
    mns, mw = shipped.fapu.MNS0 / 1024, shipped.fapu.MW0 / 1024
    assert np.allclose(motion, [50 * mw, 100 * mns, 0.0]) and axes.tolist() == [True, True, False]
    assert set(pred) == {"2.4"}



def test_the_jaw_does_not_move_the_lips_a_frame_sets(shipped):
    """open_jaw moves the jaw, not the lips: with the lip FAPs set, the lower lip moves by its
    own value (a Xface frame: jaw 713, lower lip −866 moved the lip by both); with none set,
    the lips ride on the jaw and the mouth opens."""
    player = Player(shipped)
    mns = shipped.fapu.MNS0 / 1024
    frame = {3: 700.0, 5: -800.0, 52: -800.0, 10: -800.0, 11: -800.0}
    parts = player.part_vertices(player.vertices(frame))
    drop = shipped.fp_position("2.3", parts)[1] - shipped.fp_position("2.3")[1]
    assert drop == pytest.approx(-800 * mns, rel=0.10)
    chin = shipped.fp_position("2.1", parts)[1] - shipped.fp_position("2.1")[1]
    assert chin == pytest.approx(-700 * mns, rel=0.10)
    alone = player.part_vertices(player.vertices({3: 700.0}))
    assert shipped.fp_position("2.3", alone)[1] - shipped.fp_position("2.3")[1] < -0.5 * 700 * mns


def test_a_thrust_moves_the_chin_by_its_own_value_whatever_the_opening_does(shipped):
    """The jaw opens by turning, which draws the chin back; a frame that also thrusts the
    jaw puts the chin forward by the thrust's value (it was 6 mm behind that at jaw 400 and
    thrust 100); without a thrust the opening keeps its draw."""
    player = Player(shipped)
    mns = shipped.fapu.MNS0 / 1024
    both = player.part_vertices(player.vertices({3: 400.0, 14: 100.0}))
    d = shipped.fp_position("2.1", both) - shipped.fp_position("2.1")
    assert d[2] == pytest.approx(100 * mns, rel=0.10) and d[1] == pytest.approx(-400 * mns, rel=0.10)
    assert fp_conformance(shipped, {3: 400.0, 14: 100.0}, moved=both) == (1, 1)
    alone = player.part_vertices(player.vertices({3: 400.0}))
    assert shipped.fp_position("2.1", alone)[2] - shipped.fp_position("2.1")[2] < -0.004  # measured -8.5 mm


def test_lids_and_lips_stop_where_they_meet(shipped):
    """Top lid 1080 and bottom lid 600 (IRISD units) would re-open the eye with the lids
    passed; the limits stop them where they meet, and say so. --no-limits plays them."""
    from fmc.conformance import lid_overlap

    frame = {19: 1080.0, 21: 600.0, 4: 300.0, 5: 300.0}
    limited = Player(shipped)
    parts = limited.part_vertices(limited.vertices(frame))
    assert lid_overlap(shipped, parts) < 0.5e-3
    gap = shipped.fp_position("2.2", parts)[1] - shipped.fp_position("2.3", parts)[1]
    assert gap > -(0.1 * shipped.fapu.MNS0 + 1e-3)  # lips press in by at most a tenth of MNS0
    assert any("close_t_l_eyelid" in k for k in limited.decode.clamped)
    assert any("lower_t_midlip" in k for k in limited.decode.clamped)
    free = Player(shipped, limits=False)
    parts = free.part_vertices(free.vertices(frame))
    assert lid_overlap(shipped, parts) > 2e-3 and not free.decode.clamped
    gap = shipped.fp_position("2.2", parts)[1] - shipped.fp_position("2.3", parts)[1]
    assert gap < -(0.1 * shipped.fapu.MNS0 + 3e-3)


def test_a_lip_keeps_its_height_between_its_contours(shipped):
    """Greta's anger raises the lower lip's outer contour by 609 and its inner one by 182:
    the outer contour would pass over the inner one (the lip turned inside out, folded at
    the corners). The limits keep a quarter of the lip's neutral height between them (as
    their own FAPs move them: the neighbours' tables take a little of it), and say so; a
    lowering that keeps the lip's shape is played as given."""
    from fmc.limits import LIP_KEEP, Limits

    frame = {10: 182.0, 57: 609.0, 11: 182.0, 58: 609.0}
    h0 = shipped.fp_position("2.8")[1] - shipped.fp_position("8.7")[1]
    limited = Player(shipped)
    parts = limited.part_vertices(limited.vertices(frame))
    for inner, outer in (("2.8", "8.7"), ("2.9", "8.8")):
        h = shipped.fp_position(inner, parts)[1] - shipped.fp_position(outer, parts)[1]
        assert h > 0.6 * LIP_KEEP * h0, (inner, h, h0)  # the neighbours' tables left out (0.86 when written)
    assert sum("kept a lip's height" in k for k in limited.decode.clamped) == 2
    free = Player(shipped, limits=False)
    parts = free.part_vertices(free.vertices(frame))
    assert shipped.fp_position("2.8", parts)[1] - shipped.fp_position("8.7", parts)[1] < 0
    assert Limits(shipped)({10: -300.0, 57: -300.0}) == ({10: -300.0, 57: -300.0}, [])


def test_eyeball_turns_are_clamped_to_a_range_of_motion(shipped):
    from fmc.limits import TURN_LIMITS_DEG, Limits

    limits = Limits(shipped)
    au = np.radians(148.0) / 1e-5
    values, changed = limits({23: au, 49: -au, 3: 100.0})
    assert np.degrees(values[23] * 1e-5) == pytest.approx(TURN_LIMITS_DEG[23])
    assert np.degrees(values[49] * 1e-5) == pytest.approx(-TURN_LIMITS_DEG[49])
    assert values[3] == 100.0 and len(changed) == 2
    assert limits({23: 1000.0}) == ({23: 1000.0}, [])


def test_the_brows_squeeze_stops_short_of_the_midline(shipped):
    """A squeeze of 220 on both brows would draw each inner brow point past the midline; the
    limits stop each while it keeps a quarter of its neutral distance from it, and say so."""
    from fmc.limits import MIDLINE_KEEP

    frame = {37: 220.0, 38: 220.0}
    x0 = {i: shipped.fp_position(i)[0] for i in ("4.1", "4.2")}
    limited = Player(shipped)
    parts = limited.part_vertices(limited.vertices(frame))
    for i, x in x0.items():
        got = shipped.fp_position(i, parts)[0]
        assert np.sign(got) == np.sign(x) and abs(got) > 0.8 * MIDLINE_KEEP * abs(x), (i, got, x)
    assert sum("stopped short of the midline" in k for k in limited.decode.clamped) == 2
    free = Player(shipped, limits=False)
    parts = free.part_vertices(free.vertices(frame))
    assert all(abs(shipped.fp_position(i, parts)[0]) < 0.5 * MIDLINE_KEEP * abs(x) or
               np.sign(shipped.fp_position(i, parts)[0]) != np.sign(x) for i, x in x0.items())
    # A squeeze within the limit is played as given.
    from fmc.limits import Limits

    assert Limits(shipped)({37: 60.0, 38: 60.0}) == ({37: 60.0, 38: 60.0}, [])


def test_a_brow_point_inside_a_triangle_stops_with_its_innermost_vertex(shipped):
    """An inner brow point bound inside a triangle (a coarse mesh) moves the triangle with
    it: the squeeze stops while the corner nearest the midline keeps its share, not the
    point (MakeHuman's triangles are 8 mm wide: their inner corners crossed the midline)."""
    from fmc.limits import MIDLINE_KEEP, Limits
    from mpeg4.head import FeaturePointBinding

    head = shipped.copy()
    skin = head.skin.vertices
    v = head.feature_points["4.1"].vertices[0]
    x0 = skin[v, 0]
    # A vertex on the same side, 3-6 mm nearer the midline, shares the point's binding.
    near = np.flatnonzero((np.sign(skin[:, 0]) == np.sign(x0)) & (np.abs(x0) - np.abs(skin[:, 0]) > 0.003)
                          & (np.abs(x0) - np.abs(skin[:, 0]) < 0.006) & (np.linalg.norm(skin - skin[v], axis=1) < 0.008))
    inner = near[np.argmin(np.abs(skin[near, 0]))]
    head.feature_points["4.1"] = FeaturePointBinding("skin", (int(v), int(inner)), (0.9, 0.1))
    unit = abs(Limits(shipped).midline[37] / ((1 - MIDLINE_KEEP) * abs(x0)))
    assert Limits(head).midline[37] == pytest.approx((1 - MIDLINE_KEEP) * abs(skin[inner, 0]) * unit)
    assert Limits(head).midline[38] == pytest.approx(Limits(shipped).midline[38])


def test_the_limits_settle_all_pairs_at_once(shipped):
    """Limits are a projection: a frame they changed passes through them unchanged, however
    hard the contours are pushed into each other (lips meeting squeeze a lip past its own
    height, its height pushes the lips together again), so none is left violated."""
    from fmc.limits import Limits

    limits = Limits(shipped)
    rng = np.random.default_rng(3)
    lips = (4, 5, 8, 9, 10, 11, 12, 13, 51, 52, 55, 56, 57, 58, 59, 60)
    for _ in range(40):
        frame = {n: float(v) for n, v in zip(lips, rng.uniform(-1000, 1000, len(lips)))}
        once, changed = limits(frame)
        again, changed_again = limits(once)
        assert changed
        np.testing.assert_allclose([again[n] for n in lips], [once[n] for n in lips], atol=0.05)


def test_brows_and_cheeks_are_held_to_their_range(shipped):
    """Greta's surprise raises the brows 560 units (26 mm on the generic head): the limits
    hold them to a quarter of ENS0, where the brow points rise 12 mm, not through a ridge
    of forehead; the skin above the lid crease stretches less than half as far."""
    from fmc.conformance import SurfaceChecks
    from fmc.limits import RANGE_LIMITS, Limits

    surprise = {31: 460.0, 32: 460.0, 33: 560.0, 34: 520.0, 35: 410.0, 36: 410.0, 41: 400.0}
    values, changed = Limits(shipped)(surprise)
    assert all(values[n] == pytest.approx(1024 * RANGE_LIMITS[n][1]) for n in surprise)
    assert len(changed) == len(surprise)
    assert Limits(shipped)({31: -500.0})[0][31] == pytest.approx(1024 * RANGE_LIMITS[31][0])
    assert Limits(shipped)({31: 100.0, 41: -50.0}) == ({31: 100.0, 41: -50.0}, [])
    checks = SurfaceChecks(shipped)
    limited, free = Player(shipped), Player(shipped, limits=False)
    rise = {}
    for name, player in (("limited", limited), ("free", free)):
        parts = player.part_vertices(player.vertices(surprise))
        rise[name] = 1e3 * (shipped.fp_position("4.3", parts) - shipped.fp_position("4.3"))[1]
        rise[name + " stretch"] = checks.stretch(parts["skin"])
    assert rise["limited"] == pytest.approx(0.25 * 1e3 * shipped.fapu.ENS0, rel=0.1)
    assert rise["free"] > 2 * rise["limited"]
    assert rise["limited stretch"] - 1 < 0.6 * (rise["free stretch"] - 1), rise
