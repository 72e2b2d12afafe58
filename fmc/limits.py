"""Limits a face has: lids and lips stop where they meet, eyes and head turn so far.

A stream may ask for more than a face can do: Greta's anger lowers the upper lip by 290
and raises the lower one by 609 units, which would push the lips 25 mm through each other;
real streams turn an eyeball by 148°. :class:`Limits` changes such values before they are
played, and says what it changed:

- **Meeting pairs** (:data:`MEETING_PAIRS`): an upper and a lower lid margin, an upper and a
  lower lip point. Where a frame would move the lower point above the upper one, both stop
  where they meet, each giving way by half. Lips may press into each other by a tenth of
  MNS0 (about 3 mm), which also covers what a lip FAP's neighbours do to its point, left
  out of this estimate; lids not at all. Where each point goes is
  its own FAP's value (or, for a lip FAP the stream never set, where the jaw carries it)
  plus what the frame's visemes and expressions do to it.
- **A lip's own contours** (:data:`LIP_PAIRS`): the outer contour of the upper lip stays
  above its inner contour, and the lower lip's below, by :data:`LIP_KEEP` of its neutral
  height at least, each giving way by half: Greta's anger raises the lower lip's outer
  contour three times as far as its inner one, which turned the lip over at its corners.
- **The midline** (:data:`MIDLINE_FAPS`): the brows' squeeze pulls each inner brow point
  (4.1, 4.2) towards the midline; it stops while the point keeps :data:`MIDLINE_KEEP` of
  its neutral distance from it (skin is left between the brows: a squeeze of 220 once moved
  the skin between them 14 mm sideways, through the other brow's), or rather its innermost
  vertex, for a point inside a triangle: MakeHuman's inner brow points lie in triangles
  8 mm wide, which the squeeze moves whole (:func:`fmc.clone.skin.shift_bound_points`),
  and their inner corners crossed the midline: 8 triangles turned over between the brows.
- **Ranges** (:data:`RANGE_LIMITS`): the brows move at most a quarter of ENS0 either way (12
  mm on the generic head), the cheeks rise at most a quarter. Maximal frontalis
  contraction lifts the brow's middle by 7.6 to 9.0 mm on average (Cruz and Cruz, Arq.
  Bras. Oftalmol. 2004, pp. 237-240: the means of three age groups, 81 people); the
  sculpted whole-brow raise the tables come from lifts it 10.3 mm, its frown lowers it
  3.7 mm, and its cheek squint and smile together lift the cheek 9.8 mm. Greta's surprise
  asks for 560 units (26 mm): the forehead rose in a ridge over the brows and the skin
  above the lid crease stretched to five times its length (three at the limit, which the
  sculpted raise also gives). The lowering's bound is generous (the frown lowers the brow
  3.7 mm; Greta's anger asks 7.4): it only stops a brow driven into the eye.
- **Turns** (:data:`TURN_LIMITS_DEG`): eyeball and head rotations clamped to a range of
  motion. The standard gives none; these are this project's choice, round figures inside
  a typical adult's range (eyes about 45° each way, the head 80° of yaw, 60° of pitch,
  40° of roll). The head turns about 7.1 and the turn fades over the neck to nothing at
  the shoulders (:mod:`mpeg4.neck`); on the generic head no neck triangle turns over up
  to 80° of yaw and 40° of pitch or roll, while pitch at its 60° limit folds the sides of
  the neck (32 triangles at +60°: ``tests/fmc/test_neck.py``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FAPS
from mpeg4.fat import fap_unit
from mpeg4.head import Head

from .author import JAW_FAPS
from .decouple import effect_of, table_effect

__all__ = ["MEETING_PAIRS", "LIP_PAIRS", "LIP_KEEP", "MIDLINE_FAPS", "MIDLINE_KEEP", "RANGE_LIMITS",
           "TURN_LIMITS_DEG", "Limits"]

#: (upper FAP, lower FAP) whose points must not pass each other: lids, then inner and
#: outer lip contours (centre, left and right midpoints).
MEETING_PAIRS = ((19, 21), (20, 22), (4, 5), (8, 10), (9, 11), (51, 52), (55, 57), (56, 58))

#: (upper FAP, lower FAP) of the same lip's two contours (centre, left and right
#: midpoints): the upper lip's outer contour above its inner one, the lower lip's inner
#: contour above its outer one. A stream that raises the lower lip's outer contour by 609
#: and its inner one by 182 (Greta's anger) would turn the lip inside out.
LIP_PAIRS = ((51, 4), (55, 8), (56, 9), (5, 52), (10, 57), (11, 58))
#: Passes over the lips' pairs at most: each pass moves both lips of a pair by halves, so
#: lips pressed from both sides settle geometrically; a handful suffice.
LIMIT_PASSES = 20

#: Share of its neutral height a lip keeps between its contours at the most (this project's
#: choice: a lip is squeezed thinner, not through itself).
LIP_KEEP = 0.25

#: FAPs that move their point towards the face's midline when positive: the brows' squeeze.
MIDLINE_FAPS = (37, 38)
#: Share of its neutral distance from the midline an inner brow point keeps at the most
#: squeeze (the project's choice: the brows draw together, they do not meet).
MIDLINE_KEEP = 0.25

#: FAP → (lowest, highest) motion of its point, as a share of its FAPU's neutral length
#: (ENS0 for both; None: no limit), the project's round figures above the measured range
#: (see the module's docstring): the brows' raisers 31-36 and the cheeks' lifts 41, 42.
RANGE_LIMITS: dict[int, tuple[float | None, float | None]] = {
    **{n: (-0.25, 0.25) for n in range(31, 37)}, 41: (None, 0.25), 42: (None, 0.25)}

#: Largest turn, degrees each way, per rotation FAP.
TURN_LIMITS_DEG = {23: 45.0, 24: 45.0, 25: 40.0, 26: 40.0, 48: 60.0, 49: 80.0, 50: 40.0}


class Limits:
    """Values a face can play (see the module's docstring).

    Parameters
    ----------
    head : Head
        Its feature points give the neutral heights of the meeting pairs' points.
    """

    def __init__(self, head: Head):
        self.pairs = []
        points = []
        for upper, lower in LIP_PAIRS + MEETING_PAIRS:
            fu, fl = FAPS[upper].feature_points[0], FAPS[lower].feature_points[0]
            if fu in head.feature_points and fl in head.feature_points:
                # Height of each point per unit value (the FAPs move along ±y).
                if (upper, lower) in LIP_PAIRS:  # a negative press: kept apart
                    press = -LIP_KEEP * max(0.0, float(head.fp_position(fu)[1] - head.fp_position(fl)[1]))
                else:
                    press = 0.0 if FAPS[upper].unit == "IRISD" else 0.1 * head.fapu.MNS0
                self.pairs.append((upper, lower, float(head.fp_position(fu)[1]), float(head.fp_position(fl)[1]),
                                   fap_unit(upper, head.fapu) * FAPS[upper].axis_vector[1],
                                   fap_unit(lower, head.fapu) * FAPS[lower].axis_vector[1], press))
                points += [(head.feature_points[fu], np.array([0.0, 1.0, 0.0])),
                           (head.feature_points[fl], np.array([0.0, 1.0, 0.0]))]
        fat = head.fat if head.fat is not None else {}
        # The heights the jaw and the high-level tables give the pairs' points.
        self._jaw = {j: table_effect(head, fat[(j, 0)], points) for j in JAW_FAPS if (j, 0) in fat}
        self._high = {key: table_effect(head, t, points) for key, t in fat.items() if key[0] in (1, 2)}
        self._n_points = len(points)
        # Each range in FAP values: a share of the FAPU's neutral length is 1024 × the share.
        self.ranges = {n: tuple(None if r is None else 1024.0 * r for r in rng)
                       for n, rng in RANGE_LIMITS.items()}
        self.turns = {n: np.radians(deg) / fap_unit(n, head.fapu) for n, deg in TURN_LIMITS_DEG.items()}
        self.midline = {}
        for n in MIDLINE_FAPS:
            fp = FAPS[n].feature_points[0]
            towards = -fap_unit(n, head.fapu) * FAPS[n].axis_vector[0]  # towards x = 0 per unit, metres
            x0 = float(head.fp_position(fp)[0]) if fp in head.feature_points else 0.0
            if x0 * towards > 0:  # positive values move the point towards the midline
                # The point's innermost vertex keeps the share: on a coarse mesh the point
                # lies inside a triangle that reaches closer to the midline and moves with it.
                b = head.feature_points[fp]
                xs = head.parts[b.part].vertices[list(b.vertices), 0]
                inner = float(np.abs(xs[np.sign(xs) == np.sign(x0)]).min(initial=abs(x0)))
                self.midline[n] = (1.0 - MIDLINE_KEEP) * min(abs(x0), inner) / abs(towards)

    def __call__(self, values: Mapping) -> tuple[dict, list[str]]:
        """One frame's values within the limits, and what was changed.

        Parameters
        ----------
        values : mapping
            FAP → value, as :meth:`fmc.play.Player.vertices` takes them.

        Returns
        -------
        values : dict
        changed : list of str
            One short phrase per limit that acted.
        """
        out = dict(values)
        changed = []
        if self.pairs and any(out.get(pair[0]) or out.get(pair[1]) for pair in self.pairs):
            jaw = effect_of(self._jaw, out, self._n_points)
            high = {k: v for k, v in out.items() if isinstance(k, tuple)}
            high = effect_of(self._high, high, self._n_points) if high else np.zeros(self._n_points)
            # Until none acts (bounded): lips that meet may then squeeze a lip past its
            # own keep, and the keep push the lips into each other again.
            for _ in range(LIMIT_PASSES):
                acted = False
                for p, (upper, lower, y_u, y_l, k_u, k_l, press) in enumerate(self.pairs):
                    if upper not in out and lower not in out:
                        continue
                    own_u = float(out[upper]) * k_u if upper in out else jaw[2 * p]
                    own_l = float(out[lower]) * k_l if lower in out else jaw[2 * p + 1]
                    top, bottom = y_u + own_u + high[2 * p], y_l + own_l + high[2 * p + 1]
                    excess = bottom - top - press
                    if excess > 1e-9:
                        acted = True
                        out[upper] = (top + 0.5 * excess - y_u - high[2 * p]) / k_u
                        out[lower] = (bottom - 0.5 * excess - y_l - high[2 * p + 1]) / k_l
                        what = "kept a lip's height" if press < 0 else "stopped where they meet"
                        phrase = f"{FAPS[upper].name}/{FAPS[lower].name} {what}"
                        if phrase not in changed:
                            changed.append(phrase)
                if not acted:
                    break
        for n, most in self.midline.items():
            v = out.get(n)
            if v and v > most:
                out[n] = most
                changed.append(f"{FAPS[n].name} stopped short of the midline")
        for n, (low, high) in self.ranges.items():
            v = out.get(n)
            if not v:
                continue
            held = min(v, high) if high is not None else v
            held = max(held, low) if low is not None else held
            if held != v:
                out[n] = held
                span = " to ".join("any" if b is None else f"{b:g}" for b in (low, high))
                changed.append(f"{FAPS[n].name} held to its range ({span})")
        for n, limit in self.turns.items():
            v = out.get(n)
            if v and abs(v) > limit:
                out[n] = float(np.sign(v) * limit)
                changed.append(f"{FAPS[n].name} clamped to ±{TURN_LIMITS_DEG[n]:g}°")
        return out, changed
