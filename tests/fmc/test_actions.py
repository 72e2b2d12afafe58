"""Blended high-level actions: envelopes, the blending rule, continuity, timeline files."""

import json

import numpy as np
import pytest

from fmc.actions import Action, actions_stream, blend, envelope, read_timeline
from mpeg4 import InputError


@pytest.mark.parametrize("shape", ["linear", "smooth", "exponential"])
def test_envelopes_rise_hold_and_fall(shape):
    a = Action({3: 100.0}, start=1.0, duration=2.0, envelope=shape, attack=0.5, release=0.5)
    t = np.array([0.5, 1.0, 1.25, 1.5, 2.0, 2.5, 2.75, 3.0, 3.5])
    e = envelope(a, t)
    assert e[0] == 0 and e[1] == 0 and e[-2] == 0 and e[-1] == 0
    assert e[3] == pytest.approx(1) and e[4] == pytest.approx(1) and e[5] == pytest.approx(1)
    assert 0 < e[2] < 1 and 0 < e[6] < 1


def test_blending_rule_on_hand_made_actions():
    # Two actions on the same FAP, both fully on: the weighted mean of I x value.
    a = Action({3: 400.0}, 0.0, 2.0, intensity=1.0, weight=3.0, attack=0, release=0)
    b = Action({3: 100.0, 49: 5000.0}, 0.0, 2.0, intensity=0.5, weight=1.0, attack=0, release=0)
    out = blend([a, b], np.array([1.0]))
    assert out[3][0] == pytest.approx((3 * 400 + 1 * 0.5 * 100) / 4)
    assert out[49][0] == pytest.approx(0.5 * 5000)  # only b sets FAP 49


def test_nothing_jumps_when_actions_start_or_end():
    actions = [Action({3: 500.0, (2, 1): 63.0}, 0.3, 1.5, intensity=0.9, envelope="linear", attack=0.2, release=0.4),
               Action({3: -200.0, 49: 8000.0}, 1.0, 1.2, weight=2.0, envelope="exponential", attack=0.1, release=0.3),
               Action({(1, 10): 63.0, 3: 300.0}, 0.8, 0.4, envelope="smooth", attack=0.1, release=0.1)]

    def largest_jump(fps):
        t = np.arange(0, 3.0, 1 / fps)
        return max(np.abs(np.diff(v)).max() for v in blend(actions, t).values())

    # Continuous curves: ten times the frame rate gives about a tenth of the largest jump
    # (a jump at an action's start or end would not shrink).
    coarse, fine = largest_jump(100), largest_jump(1000)
    assert fine < 0.15 * coarse


def test_stream_encodes_fading_visemes_and_expressions():
    a = Action({(1, 10): 63.0}, 0.0, 1.0, intensity=1.0, envelope="linear", attack=0.5, release=0.5)
    e = Action({(2, 6): 63.0}, 0.0, 1.0, intensity=0.5, attack=0, release=0)
    s = actions_stream([a, e], 1.0, fps=4)
    # t = 0.25: the envelope is 0.5; alone on its channel the viseme plays at e x I x 63
    # (its weight cancels), and the neutral viseme takes the rest.
    v = s.frame_values(1)
    assert v[(1, 10)] == pytest.approx(0.5 * 63) and v[(1, 0)] == pytest.approx(0.5 * 63)
    assert s.expression[2, 0] == 6 and s.expression[2, 1] == pytest.approx(0.5 * 63)


def test_timeline_file(tmp_path):
    path = tmp_path / "t.json"
    path.write_text(json.dumps({"fps": 10, "actions": [
        {"expression": "joy", "start": 0.0, "duration": 1.0, "intensity": 0.8},
        {"viseme": "A", "start": 0.2, "duration": 0.5},
        {"faps": {"head_yaw": 6000, "3": 150}, "start": 0.5, "duration": 1.0}]}))
    tl = read_timeline(path)
    assert tl.duration == pytest.approx(1.5) and len(tl.actions) == 3
    s = tl.stream()
    assert s.n_frames == 16 and s.fps == 10


@pytest.mark.parametrize("action, message", [
    ({"faps": {"99": 1}, "start": 0, "duration": 1}, r"actions\[0\].faps\['99'\]: unknown FAP"),
    ({"faps": {"open_jaw": -50}, "start": 0, "duration": 1}, "open_jaw is unidirectional; -50 is out of range"),
    ({"expression": "boredom", "start": 0, "duration": 1}, "unknown expression 'boredom'"),
    ({"viseme": 3, "start": 0}, "missing 'duration'"),
    ({"viseme": 3, "start": 0, "duration": 1, "intensity": 2}, "intensity 2.0 is outside 0..1"),
])
def test_bad_timelines(tmp_path, action, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"actions": [action]}))
    with pytest.raises(InputError, match=message):
        read_timeline(path)
