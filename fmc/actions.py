"""High-level actions on a timeline, blended into one FAP stream.

An action is a snapshot of FAP values (an expression, a viseme, or any low-level FAPs)
played from ``start`` for ``duration`` seconds at an ``intensity``, faded in over
``attack`` and out over ``release`` seconds by one of three envelope shapes:

- ``linear``: straight ramps;
- ``smooth``: ``3r² − 2r³`` ramps (zero slope at both ends);
- ``exponential``: ``(1 − e^{−5r}) / (1 − e^{−5})`` — fast onset, slow settle.

Several actions at once are blended per FAP over the actions that set it:
``FAP = Σ w·I·FAP / Σ w`` with each action's weight ``w`` and intensity ``I`` both scaled
by its envelope ``e(t)``, so an action entering or leaving moves every FAP continuously
(its share of the weights and its own contribution both start and end at 0).

Timeline files (JSON), written by hand::

    {"fps": 25, "duration": 3.0,
     "actions": [
       {"expression": "joy", "start": 0.2, "duration": 2.5, "intensity": 0.8,
        "envelope": "smooth", "attack": 0.4, "release": 0.6},
       {"viseme": "A", "start": 1.0, "duration": 0.3},
       {"faps": {"head_yaw": 6000, "3": 150}, "start": 0.5, "duration": 2.0, "weight": 2}
     ]}

``expression`` and ``viseme`` take a number or a name from the catalogue; ``faps`` maps
FAP numbers or names to values in FAPU (AU for rotations). Defaults: intensity 1, weight
1, envelope ``smooth``, attack and release 0.2 s (at most half the duration).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from mpeg4.catalogue import EXPRESSIONS, VISEMES, fap
from mpeg4.errors import InputError, require_file
from mpeg4.io.fap import FPS_RANGE, FapStream

__all__ = ["ENVELOPES", "Action", "envelope", "blend", "actions_stream", "read_timeline", "Timeline"]

ENVELOPES = ("linear", "smooth", "exponential")
#: Most frames a timeline file may ask for (over 11 hours at 25 fps).
MAX_FRAMES = 1_000_000


@dataclass
class Action:
    """One action: channel values at full intensity, and when and how it plays.

    ``values`` maps a FAP number (3..68) to its value in FAPU, or ``(1, viseme)`` /
    ``(2, expression)`` to an intensity 0..63.
    """

    values: dict
    start: float
    duration: float
    intensity: float = 1.0
    weight: float = 1.0
    envelope: str = "smooth"
    attack: float = 0.2
    release: float = 0.2
    name: str = ""

    def __post_init__(self):
        if self.envelope not in ENVELOPES:
            raise InputError(f"unknown envelope {self.envelope!r}", where=self.name or None,
                             fix=f"use one of {', '.join(ENVELOPES)}")
        if not self.duration > 0:
            raise InputError(f"duration {self.duration} is not positive", where=self.name or None)
        if not 0 <= self.intensity <= 1:
            raise InputError(f"intensity {self.intensity} is outside 0..1", where=self.name or None)
        if not self.weight > 0:
            raise InputError(f"weight {self.weight} is not positive", where=self.name or None)
        self.attack = min(max(self.attack, 0.0), self.duration / 2)
        self.release = min(max(self.release, 0.0), self.duration / 2)


def envelope(action: Action, t: np.ndarray) -> np.ndarray:
    """(T,) envelope of an action at times ``t`` (seconds), in [0, 1]."""
    t = np.asarray(t, dtype=np.float64)
    end = action.start + action.duration
    rise = np.ones_like(t) if action.attack == 0 else (t - action.start) / action.attack
    fall = np.ones_like(t) if action.release == 0 else (end - t) / action.release
    r = np.clip(np.minimum(rise, fall), 0.0, 1.0)
    r[(t < action.start) | (t > end)] = 0.0
    if action.envelope == "linear":
        return r
    if action.envelope == "smooth":
        return r * r * (3.0 - 2.0 * r)
    return (1.0 - np.exp(-5.0 * r)) / (1.0 - math.exp(-5.0))


def blend(actions: list[Action], times: np.ndarray) -> dict:
    """Channel → (T,) blended value at ``times``; 0 where no action is on (see module doc)."""
    times = np.asarray(times, dtype=np.float64)
    num: dict = {}
    den: dict = {}
    for a in actions:
        e = envelope(a, times)
        w = a.weight * e
        for ch, v in a.values.items():
            num[ch] = num.get(ch, 0.0) + w * a.intensity * e * float(v)
            den[ch] = den.get(ch, 0.0) + w
    return {ch: np.divide(num[ch], den[ch], out=np.zeros_like(times), where=den[ch] > 0) for ch in num}


def actions_stream(actions: list[Action], duration: float, fps: float = 25.0, name: str = "actions") -> FapStream:
    """The blended actions sampled as a FAP stream (every channel ever used is set in every
    frame, so nothing depends on how a player treats unset FAPs)."""
    n = int(math.floor(duration * fps + 1e-9)) + 1
    times = np.arange(n) / fps
    channels = blend(actions, times)
    values = np.full((n, 68), np.nan)
    vis = {k[1]: v for k, v in channels.items() if isinstance(k, tuple) and k[0] == 1}
    exps = {k[1]: v for k, v in channels.items() if isinstance(k, tuple) and k[0] == 2}
    for k, v in channels.items():
        if not isinstance(k, tuple):
            values[:, k - 1] = v
    viseme = np.full((n, 4), np.nan)
    if vis:
        # Two slots and a blend: the strongest visemes, with the neutral viseme 0 taking
        # whatever intensity the active ones leave, so a viseme can fade.
        for i in range(n):
            cand = {v: float(w[i]) for v, w in vis.items()}
            cand[0] = cand.get(0, 0.0) + max(0.0, 63.0 - sum(cand.values()))
            (v1, w1), (v2, w2) = (sorted(cand.items(), key=lambda kv: -kv[1]) + [(0, 0.0)])[:2]
            viseme[i] = [v1, v2, 63.0 * w1 / (w1 + w2) if w1 + w2 > 0 else 63.0, 0]
    expression = np.full((n, 6), np.nan)
    if exps:
        for i in range(n):
            (e1, i1), (e2, i2) = (sorted(((e, float(w[i])) for e, w in exps.items()), key=lambda kv: -kv[1])
                                  + [(0, 0.0), (0, 0.0)])[:2]
            expression[i] = [e1, min(63.0, i1), e2, min(63.0, i2), 0, 0]
    return FapStream(fps, np.arange(n), values, viseme, expression, name=name)


@dataclass
class Timeline:
    """A parsed timeline file."""

    actions: list[Action]
    duration: float
    fps: float = 25.0
    name: str = "timeline"

    def stream(self) -> FapStream:
        return actions_stream(self.actions, self.duration, self.fps, self.name)


def _lookup(table, key, what, where):
    if isinstance(key, int) or (isinstance(key, str) and key.isdigit()):
        k = int(key)
        if k in table:
            return k
    else:
        for k, item in table.items():
            if str(key).lower() in (item.name.lower(), item.name.lower().replace("_", " ")):
                return k
            if what == "viseme" and str(key) in getattr(item, "phonemes", ()):
                return k
    names = ", ".join(f"{k} {v.name}" for k, v in list(table.items())[:8])
    raise InputError(f"unknown {what} {key!r}", where=where, fix=f"use a number or a name ({names} ...)")


def _action(d: dict, where: str) -> Action:
    if not isinstance(d, dict):
        raise InputError("an action must be an object", where=where)
    kinds = [k for k in ("expression", "viseme", "faps") if k in d]
    if len(kinds) != 1:
        raise InputError("an action needs exactly one of 'expression', 'viseme', 'faps'", where=where,
                         fix='e.g. {"expression": "joy", "start": 0.5, "duration": 2}')
    if kinds[0] == "expression":
        values = {(2, _lookup(EXPRESSIONS, d["expression"], "expression", f"{where}.expression")): 63.0}
    elif kinds[0] == "viseme":
        values = {(1, _lookup(VISEMES, d["viseme"], "viseme", f"{where}.viseme")): 63.0}
    else:
        values = {}
        if not isinstance(d["faps"], dict) or not d["faps"]:
            raise InputError("'faps' must map FAP numbers or names to values", where=f"{where}.faps")
        for key, v in d["faps"].items():
            place = f"{where}.faps[{key!r}]"
            try:
                f = fap(int(key) if str(key).isdigit() else key)
            except (InputError, KeyError, ValueError):
                raise InputError(f"unknown FAP {key!r}", where=place,
                                 fix="use a number 3..68 or a name such as open_jaw, head_yaw") from None
            if f.id < 3:
                raise InputError(f"FAP {f.id} is high-level", where=place, fix="use 'viseme' or 'expression' actions")
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"value {v!r} is not a number", where=place)
            if f.direction == "U" and v < 0:
                raise InputError(f"{f.name} is unidirectional; {v} is out of range", where=place,
                                 fix="give a value >= 0")
            if abs(v) > 200000:
                raise InputError(f"value {v} is out of range", where=place, fix="FAP values are in FAPU (AU for angles); "
                                                                              "a whole-face range is about +-1024")
            values[f.id] = float(v)
    try:
        numbers = [float(d["start"]), float(d["duration"]), float(d.get("intensity", 1.0)),
                   float(d.get("weight", 1.0))]
        fades = [float(d.get("attack", 0.2)), float(d.get("release", 0.2))]
    except KeyError as e:
        raise InputError(f"missing {e.args[0]!r}", where=where,
                         fix="every action has 'start' and 'duration' in seconds") from None
    except (TypeError, ValueError):
        raise InputError("start, duration, intensity, weight, attack and release must be numbers", where=where) from None
    return Action(values, *numbers, d.get("envelope", "smooth"), *fades, name=where)


def read_timeline(path) -> Timeline:
    """Read a timeline JSON file (see the module docstring)."""
    from mpeg4.io.strict_json import read_json

    path = require_file(path, "timeline file")
    data = read_json(path, "timeline file")
    if not isinstance(data, dict) or not isinstance(data.get("actions"), list):
        raise InputError("expected an object with an 'actions' list", where=path)
    actions = [_action(a, f"{path}, actions[{k}]") for k, a in enumerate(data["actions"])]
    end = max((a.start + a.duration for a in actions), default=0.0)
    for k, a in enumerate(actions):
        if not all(math.isfinite(x) for x in (a.start, a.duration, a.intensity, a.weight)):
            raise InputError("start, duration, intensity and weight must be finite", where=f"{path}, actions[{k}]")
    try:
        duration, fps = float(data.get("duration", end)), float(data.get("fps", 25.0))
    except (TypeError, ValueError):
        raise InputError("duration and fps must be numbers", where=path) from None
    lo, hi = FPS_RANGE
    if not lo <= fps <= hi:
        raise InputError(f"fps {fps:g} is outside {lo:g}..{hi:g}", where=f"{path}, fps", fix="e.g. 25")
    if not 0 <= duration * fps <= MAX_FRAMES:
        raise InputError(f"a duration of {duration:g} s at {fps:g} fps is not 0..{MAX_FRAMES} frames",
                         where=f"{path}, duration", fix="give the timeline's length in seconds")
    return Timeline(actions, duration, fps, name=os.path.splitext(os.path.basename(path))[0])
