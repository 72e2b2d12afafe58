"""Eyes alive: seeded blinks and gaze, centred while speaking."""

import numpy as np

from fmc.eyes import eyes_alive


def test_seeded_blinks_and_gaze():
    a = eyes_alive(10.0, 50.0, seed=4)
    b = eyes_alive(10.0, 50.0, seed=4)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    lids = a[19]
    closed = np.flatnonzero(np.diff((lids > 1000).astype(int)) == 1)
    assert 1 <= len(closed) <= 8  # a blink every few seconds
    assert lids.min() == 0 and lids.max() == 1024
    assert np.abs(a[23]).max() > 1000 and np.abs(a[23]).max() <= 6 * np.pi / 180 / 1e-5 + 1
    # Saccades are fast but not instantaneous: at most 6 degrees per 20 ms frame.
    assert np.abs(np.diff(a[23])).max() <= 12 * np.pi / 180 / 1e-5 * 0.02 / 0.04 + 1


def test_gaze_centres_while_speaking():
    a = eyes_alive(8.0, 50.0, seed=1, speaking=[(0.0, 8.0)])
    t = np.arange(len(a[23])) / 50.0
    assert np.abs(a[23][t > 0.1]).max() < 1e-9 and np.abs(a[25][t > 0.1]).max() < 1e-9
