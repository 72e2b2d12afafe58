"""Whether marked feature points look like a face: :func:`check_points`.

A marking can go wrong without failing: a detector that took the nostrils for the mouth,
a head turned over, a unit misread. These checks hold for any real human head in the
MPEG-4 neutral frame (+x the face's left, +y up, +z forward, metres), so a result that
fails one is unreliable and is said to be (:class:`Problem`), not returned silently.

The bounds are anatomy, made generous. Where a number was measured, it was measured on
the generic head and on 60 ICT FaceKit identities (``recon.evaluate.ict.identity_head``,
seeds 0-59), then widened well beyond that range (the measured range is in each comment);
distances are in units of the head's own spread (:func:`_spread`: the RMS distance of the
points from their centroid, 1.0-1.2 eye separations on those heads), so that no check
depends on the unit.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import Head

__all__ = ["Problem", "check_points", "CHECKS"]

#: The checks' names, in the order they run.
CHECKS = ("finite", "spread", "skull_above_eyes", "eyes_above_nose", "nose_above_mouth", "upper_lip_above_lower",
          "lips_above_chin", "left_right", "eye_separation_size", "ENS0/ES0", "MNS0/ES0", "MW0/ES0",
          "pupils_in_eye_openings", "pupils_on_eyeballs")

# Vertical order on the midline: (name, upper point, lower point, least gap in spreads).
# "eyes" is the pupils' mean height. Measured gaps (spreads): skull top above the eyes
# 1.35-1.65, eyes above the nose tip 0.41-0.57, nose tip above the upper lip 0.30-0.42,
# upper above lower lip 0.16-0.38, lower lip above the chin 0.35-0.60. The least gaps
# are a third of the smallest or less; the lips may overlap slightly (3 %, about 2 mm),
# as pressed or pursed lips can.
_ORDER = (("skull_above_eyes", "11.4", "eyes", 0.4),
          ("eyes_above_nose", "eyes", "9.3", 0.12),
          ("nose_above_mouth", "9.3", "8.1", 0.08),
          ("upper_lip_above_lower", "8.1", "8.2", -0.03),
          ("lips_above_chin", "8.2", "2.1", 0.1))

# A left point must be left of its right partner by more than this (spreads, about
# 0.7 mm): the closest pair, the lower edges of the nasal bone (9.13/9.14), is 0.14-0.20
# spreads apart on the heads measured; closer than this they are one point, not two.
_LEFT_RIGHT = 0.01

# Eye separation (ES0, m). Adult pupils are 54-74 mm apart, a small child's about 45 mm
# (measured 58-76 mm); 30-120 mm leaves room for any head and catches a unit misread by
# ten (cm for mm) or more.
_ES0_M = (0.030, 0.120)

# FAPU ratios to ES0: (name, upper point, lower point, axis). Measured ranges (generic and
# ICT heads): ENS0/ES0 0.62-0.90, MNS0/ES0 0.27-0.38, MW0/ES0 0.62-0.86; the allowed
# range is 40 % beyond each end (0.6 x the least, 1.4 x the most), which also holds the
# reference's anthropometric ball-park (ENS0 35-50, MNS0 12-22, MW0 45-55 mm for ES0 60-68).
_RATIOS = {"ENS0/ES0": ("3.5", "9.15", 1, (0.37, 1.26)),
           "MNS0/ES0": ("9.15", "2.2", 1, (0.16, 0.54)),
           "MW0/ES0": ("8.3", "8.4", 0, (0.37, 1.20))}

# Each pupil within its eye's opening: (pupil, corners). Across the opening (0 at the
# corner with the smaller x, 1 at the other) the pupils measured 0.35-0.64, up from the
# corners' line 0.04-0.18 eye widths; allowed a quarter of the width outside either
# corner and 0.6 widths above or below (a gaze straight ahead puts the pupil near the
# opening's middle; the margins take a detector's corner a few mm off).
_OPENINGS = (("3.5", ("3.11", "3.7")), ("3.6", ("3.8", "3.12")))
_ACROSS = (-0.25, 1.25)
_UP = (-0.6, 0.6)

# The pupil on its eyeball: within this share of the eyeball's radius of its front (the
# part's most forward vertex; the radius is from the part's centre to it). Measured at
# most 0.2 (the pupils are at the cornea's apex, less its flattening); half the radius
# (7-8 mm) is well off the cornea, inside the eye or in front of it.
_PUPIL_OFF_FRONT = 0.5

_POINT_NAMES = {"eyes": "the pupils (3.5/3.6 mean)", "11.4": "the skull's top 11.4", "9.3": "the nose tip 9.3",
                "8.1": "the upper lip 8.1", "8.2": "the lower lip 8.2", "2.1": "the chin 2.1"}


@dataclass(frozen=True)
class Problem:
    """One check a marking fails.

    Attributes
    ----------
    check : str
        The check's name (one of :data:`CHECKS`).
    points : tuple of str
        The feature points involved.
    value : float
        What was measured: metres for distances and heights, a plain number for ratios
        (``nan`` when it could not be measured).
    allowed : (float, float)
        The range a human head's value lies in (same unit; ``inf`` for no bound).
    message : str
        One line for a person: the check, the points and what is wrong.
    """

    check: str
    points: tuple[str, ...]
    value: float
    allowed: tuple[float, float]
    message: str


def check_points(points: Mapping[str, np.ndarray], head: Head | None = None) -> list[Problem]:
    """The consistency checks a marking's feature points fail (the module docstring).

    Parameters
    ----------
    points : mapping of str to (3,) array
        FP id → position, metres, in the MPEG-4 neutral frame. A check whose points are
        missing is skipped (the marking reports missing points itself).
    head : Head, optional
        The head in the same frame: when it has ``eye_l``/``eye_r`` parts, the pupils are
        checked against them; without eyeball parts that check is skipped.

    Returns
    -------
    list of Problem
        Empty when every check passes. Non-finite or coincident points give a Problem
        (``finite``, ``spread``), never an exception or a warning.

    Raises
    ------
    InputError
        A point that is not three numbers.
    """
    with np.errstate(all="ignore"):  # huge coordinates give inf, which fails a check; never a warning
        return _check(points, head)


def _check(points, head) -> list[Problem]:
    p = {}
    for i, v in points.items():
        a = np.asarray(v, dtype=np.float64)
        if a.shape != (3,):
            raise InputError(f"feature point {i} has shape {a.shape}, expected 3 coordinates", where="check_points",
                             fix="give each point as (x, y, z) in metres")
        p[i] = a
    problems = []
    bad = tuple(i for i, a in p.items() if not np.isfinite(a).all())
    if bad:
        problems.append(Problem("finite", bad, float("nan"), (-np.inf, np.inf),
                                f"finite: feature point(s) {', '.join(bad)} have no position "
                                "(NaN or infinite coordinates)"))
        p = {i: a for i, a in p.items() if i not in bad}
    s = _spread(p)
    if not s > 1e-6:  # under a micrometre: the points are one point (or there are none)
        problems.append(Problem("spread", tuple(p), s, (1e-6, np.inf),
                                f"spread: the {len(p)} points lie within {s * 1000:.3g} mm of each other: "
                                "they are not spread over a face"))
        return problems
    if "3.5" in p and "3.6" in p:
        p["eyes"] = 0.5 * (p["3.5"] + p["3.6"])
    problems += _order(p, s) + _left_right(p, s) + _proportions(p) + _openings(p)
    if head is not None:
        problems += _eyeballs(p, head)
    return problems


def _spread(p: Mapping[str, np.ndarray]) -> float:
    """RMS distance (m) of the points from their centroid; 0 for fewer than two."""
    if len(p) < 2:
        return 0.0
    a = np.array(list(p.values()))
    return float(np.sqrt(np.mean(np.sum((a - a.mean(axis=0)) ** 2, axis=1))))


def _name(i: str) -> str:
    return _POINT_NAMES.get(i, i)


def _involved(i: str) -> tuple[str, ...]:
    return ("3.5", "3.6") if i == "eyes" else (i,)


def _order(p, s: float) -> list[Problem]:
    out = []
    for name, upper, lower, least in _ORDER:
        if upper not in p or lower not in p:
            continue
        gap = float(p[upper][1] - p[lower][1])
        if gap < least * s:
            out.append(Problem(name, _involved(upper) + _involved(lower), gap, (least * s, np.inf),
                               f"{name}: {_name(upper)} is {gap * 1000:.1f} mm above {_name(lower)}; on a head it "
                               f"is at least {least * s * 1000:.1f} mm above"))
    return out


def _left_right(p, s: float) -> list[Problem]:
    """Every left point (catalogue side L) at larger x than its right mirror: one Problem."""
    pairs = [(i, f.mirror) for i, f in FEATURE_POINTS.items() if f.side == "L" and i in p and f.mirror in p]
    gaps = {pair: float(p[pair[0]][0] - p[pair[1]][0]) for pair in pairs}
    wrong = [pair for pair, g in gaps.items() if not g > _LEFT_RIGHT * s]
    if not wrong:
        return []
    worst = min(gaps[pair] for pair in wrong)
    shown = ", ".join(f"{a}/{b}" for a, b in wrong[:8]) + (f" and {len(wrong) - 8} more" if len(wrong) > 8 else "")
    return [Problem("left_right", tuple(i for pair in wrong for i in pair), worst, (_LEFT_RIGHT * s, np.inf),
                    f"left_right: {len(wrong)} of {len(pairs)} left points are not left of their right partners "
                    f"({shown}; at worst {worst * 1000:.1f} mm): left and right swapped, or the head mirrored")]


def _proportions(p) -> list[Problem]:
    if "3.5" not in p or "3.6" not in p:
        return []
    es = float(p["3.5"][0] - p["3.6"][0])
    out = []
    lo, hi = _ES0_M
    if not lo <= es <= hi:
        out.append(Problem("eye_separation_size", ("3.5", "3.6"), es, _ES0_M,
                           f"eye_separation_size: the pupils 3.5/3.6 are {es * 1000:.1f} mm apart across the face; "
                           f"a head's are {lo * 1000:.0f}-{hi * 1000:.0f} mm apart "
                           + ("(a unit misread?)" if es > 0 else "(left and right swapped?)")))
    for name, (a, b, axis, (rlo, rhi)) in _RATIOS.items():
        if a not in p or b not in p:
            continue
        d = float(p[a][axis] - p[b][axis])
        ratio = d / es if es > 1e-9 else float("nan")  # a zero or negative ES0 measures nothing
        if not rlo <= ratio <= rhi:
            what = (f"is {ratio:.2f}" if es > 1e-9 else "cannot be measured")
            out.append(Problem(name, ("3.5", "3.6", a, b), ratio, (rlo, rhi),
                               f"{name}: {name.split('/')[0]} ({a}-{b}, {d * 1000:.1f} mm) over ES0 (3.5-3.6, "
                               f"{es * 1000:.1f} mm) {what}; a face's is {rlo:.2f}-{rhi:.2f}"))
    return out


def _openings(p) -> list[Problem]:
    """Each pupil inside its eye's opening, between the corners and near their line."""
    out = []
    for pupil, corners in _OPENINGS:
        if pupil not in p or any(c not in p for c in corners):
            continue
        a, b = sorted((p[c] for c in corners), key=lambda v: v[0])
        width = float(b[0] - a[0])
        ids = (pupil,) + corners
        if not width > 1e-6:
            out.append(Problem("pupils_in_eye_openings", ids, width, (1e-6, np.inf),
                               f"pupils_in_eye_openings: the eye corners {'/'.join(corners)} are at the same x: "
                               "no eye opening"))
            continue
        across = float((p[pupil][0] - a[0]) / width)
        up = float((p[pupil][1] - 0.5 * (a[1] + b[1])) / width)
        if not _ACROSS[0] <= across <= _ACROSS[1]:
            out.append(Problem("pupils_in_eye_openings", ids, across, _ACROSS,
                               f"pupils_in_eye_openings: pupil {pupil} is {across:.2f} of the way across its eye "
                               f"opening ({'/'.join(corners)}); inside it is 0-1"))
        elif not _UP[0] <= up <= _UP[1]:
            out.append(Problem("pupils_in_eye_openings", ids, up, _UP,
                               f"pupils_in_eye_openings: pupil {pupil} is {up:+.2f} eye widths above the line "
                               f"of its corners ({'/'.join(corners)}); a pupil is near it"))
    return out


def _eyeballs(p, head: Head) -> list[Problem]:
    """Each pupil near the front of its eyeball part; skipped for a head without them."""
    out = []
    for role, pupil in (("eye_l", "3.5"), ("eye_r", "3.6")):
        part = head.parts.get(role)
        if part is None or pupil not in p or not part.n_vertices:
            continue
        v = part.vertices
        centre = part.centre if part.centre is not None else v.mean(axis=0)  # a sphere's vertices centre on it
        front = v[int(np.argmax(v[:, 2]))]
        radius = float(np.linalg.norm(front - centre))
        off = float(np.linalg.norm(p[pupil] - front))
        share = off / radius if radius > 1e-6 else float("nan")  # a flat eye has no radius
        if not share <= _PUPIL_OFF_FRONT:
            out.append(Problem("pupils_on_eyeballs", (pupil,), share, (0.0, _PUPIL_OFF_FRONT),
                               f"pupils_on_eyeballs: pupil {pupil} is {off * 1000:.1f} mm from the front of the "
                               f"eyeball {role} ({share:.2f} of its radius); a pupil is on the cornea"))
    return out
