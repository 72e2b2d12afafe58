"""Fast playback equals the reference decoder, and plays .fap streams."""

import numpy as np
import pytest

from fmc.play import Player
from mpeg4 import InputError, apply_fat
from mpeg4.generic_head import load_generic_head
from mpeg4.io import parse_fap
from mpeg4.neck import neck_fade


@pytest.fixture(scope="module")
def head(authored_head):
    return authored_head


def test_player_equals_apply_fat(head):
    player = Player(head)
    neutral = {n: p.vertices for n, p in head.parts.items()}
    fade = neck_fade(head).fade  # the head turns fade over the neck in both
    rng = np.random.default_rng(0)
    for _ in range(6):
        faps = rng.choice(np.arange(3, 69), 12, replace=False)
        values = {int(f): float(rng.uniform(-900, 900)) for f in faps}  # beyond the ±512 borders too
        values.update({int(f): float(rng.uniform(-30000, 30000)) for f in (23, 25, 48, 49, 50) if rng.random() < 0.6})
        values[(1, int(rng.integers(0, 15)))] = float(rng.uniform(0, 63))
        values[(2, int(rng.integers(0, 7)))] = float(rng.uniform(0, 63))
        # The player fills a lip FAP's missing inner/outer partner, as streams mean it.
        a = apply_fat(head.fat, neutral, player.decode(values), head.fapu, neck_fade=fade)
        b = player.part_vertices(player.vertices(values))
        assert max(np.abs(a[n] - b[n]).max() for n in a) < 1e-12


def test_plays_a_fap_stream_with_held_values(head):
    mask = " ".join("1" if k in (3, 49) else "0" for k in range(1, 69))
    only3 = " ".join("1" if k == 3 else "0" for k in range(1, 69))
    text = f"# jaw opens while the head turns\n2.1 demo 25 3\n{mask}\n0 0 0\n{mask}\n1 512 10000\n{only3}\n2 256\n"
    stream = parse_fap(text)
    player = Player(head)
    frames = list(player.play(stream))
    assert len(frames) == 3
    np.testing.assert_allclose(frames[0], player.neutral, atol=1e-15)
    chin = head.feature_points["2.1"]
    skin = player.slices["skin"]

    def chin_y(f):
        return (np.asarray(chin.weights) @ f[skin][list(chin.vertices)])[1]

    assert chin_y(frames[1]) < chin_y(frames[0]) - 0.005  # the jaw dropped
    # Frame 2 sets FAP 3 only: the head turn (49) is held from frame 1.
    expected = player.vertices({3: 256.0, 49: 10000.0})
    np.testing.assert_allclose(frames[2], expected, atol=1e-12)


def test_head_without_tables():
    with pytest.raises(InputError, match="no Facial Animation Tables"):
        Player(load_generic_head())


def test_fast_overlaps_equal_the_reference_rule():
    from fmc.play import _overlaps
    from mpeg4.fat import signed_overlaps

    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 5))
        b = np.sort(rng.choice(np.arange(-1000, 1001, 50), n + 1, replace=False)).astype(float)
        if not b[0] <= 0 <= b[-1]:
            b[0 if b[0] > 0 else -1] = 0.0
            b = np.sort(b)
        if len(np.unique(b)) != len(b):
            continue
        for value in (float(rng.uniform(-2000, 2000)), 0.0, float(b[0]), float(b[-1])):
            np.testing.assert_allclose(_overlaps(tuple(b), value), signed_overlaps(b, value), atol=1e-12)
