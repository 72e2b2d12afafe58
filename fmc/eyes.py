"""Eyes alive: blinks and gaze shifts from a small seeded automaton.

Two independent processes run over the timeline:

- blinking: intervals between blinks drawn from a gamma distribution (mean 3.5 s, at
  least 1 s); each blink closes both upper lids (FAPs 19/20) and lifts the lower ones a
  little (21/22) over 70 ms, holds 30 ms and opens over 120 ms;
- gaze: the eyes fixate a point for a random while (0.6–2.5 s) then jump (a saccade of
  40 ms) to a new one within ±6° sideways and ±4° vertically; while the head speaks the
  next fixation is the centre (looking at the listener).

Everything comes from one ``numpy`` generator seeded by the caller, so a given seed gives
the same eyes every time.
"""

from __future__ import annotations

import numpy as np

__all__ = ["eyes_alive"]

_CLOSE, _HOLD, _OPEN = 0.07, 0.03, 0.12
_SACCADE = 0.04
_AU_PER_DEG = np.pi / 180 / 1e-5


def _blink_shape(t: np.ndarray, start: float) -> np.ndarray:
    u = t - start
    closing = np.clip(u / _CLOSE, 0, 1)
    opening = np.clip(1 - (u - _CLOSE - _HOLD) / _OPEN, 0, 1)
    return np.where(u < _CLOSE + _HOLD, closing, opening) * ((u >= 0) & (u <= _CLOSE + _HOLD + _OPEN))


def eyes_alive(duration: float, fps: float, seed: int = 0, speaking=()) -> dict[int, np.ndarray]:
    """FAP number → (F,) values (FAPU / AU) for blinks and gaze over ``duration`` seconds.

    Parameters
    ----------
    duration, fps : float
    seed : int
        Seed of the random timings.
    speaking : sequence of (start, end)
        Intervals (s) while the head speaks: fixations starting then look at the centre.
    """
    rng = np.random.default_rng(seed)
    n = int(np.floor(duration * fps + 1e-9)) + 1
    t = np.arange(n) / fps
    lids = np.zeros(n)
    when = float(rng.uniform(0.3, 1.5))
    while when < duration:
        lids = np.maximum(lids, _blink_shape(t, when))
        when += max(1.0, float(rng.gamma(4.0, 3.5 / 4.0)))
    yaw = np.zeros(n)
    pitch = np.zeros(n)
    start, cur = 0.0, np.zeros(2)
    while start < duration:
        talking = any(a <= start < b for a, b in speaking)
        target = np.zeros(2) if talking else np.array([rng.uniform(-6, 6), rng.uniform(-4, 4)])
        hold = float(rng.uniform(0.6, 2.5))
        u = np.clip((t - start) / _SACCADE, 0, 1)
        seg = (t >= start) & (t < start + hold)
        pos = cur[None] + (target - cur)[None] * u[:, None]
        yaw[seg], pitch[seg] = pos[seg, 0], pos[seg, 1]
        cur, start = target, start + hold
    out = {19: 1024.0 * lids, 20: 1024.0 * lids, 21: 200.0 * lids, 22: 200.0 * lids,
           23: yaw * _AU_PER_DEG, 24: yaw * _AU_PER_DEG, 25: pitch * _AU_PER_DEG, 26: pitch * _AU_PER_DEG}
    return out
