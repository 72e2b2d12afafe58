"""How faithfully a head plays FAPs: measures over its Facial Animation Tables.

Each measure takes a head with tables and FAP values, plays them (``mpeg4.apply_fat``)
and compares the result with what ISO/IEC 14496-2 asks of it:

- parts move only as parts (:func:`part_leaks`, :func:`eyeball_centre_shift`): an
  eyeball only turns about its centre, the teeth and tongue only follow the jaw or their
  own FAPs;
- each FAP moves its feature point by value × FAPU along its axis, and FAPs given
  together by the sum of what each does (:func:`fp_conformance`).

``benchmarks/fap_conformance.py`` reports them over real FAP streams.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fmc.author import moving_parts
from fmc.clone.parts import rigid_motion
from mpeg4.catalogue import FAPS
from mpeg4.fat import apply_fat, fap_unit
from mpeg4.head import Head
from mpeg4.neck import neck_fade
from mpeg4.surface import inverted_triangles, triangle_normals

__all__ = ["HEAD_TURN_FAPS", "allowed_parts", "part_leaks", "eyeball_centre_shift", "fp_prediction",
           "fp_conformance", "lid_overlap", "region_over_fp", "SurfaceChecks"]

#: The head rotations (about 7.1): every part turns with them, the skin faded over the neck
#: (:func:`mpeg4.neck.neck_fade`: the shoulders stay).
HEAD_TURN_FAPS = (48, 49, 50)


def allowed_parts(head: Head, n: int) -> frozenset[str]:
    """The parts FAP ``n`` may move: all of them for a head turn, else
    :func:`fmc.author.moving_parts`."""
    if n in HEAD_TURN_FAPS:
        return frozenset(head.parts)
    return moving_parts(head, n)


def _neutral(head: Head) -> dict[str, np.ndarray]:
    return {name: part.vertices for name, part in head.parts.items()}


def part_leaks(head: Head, value: float = 300.0, faps=None) -> dict[int, dict[str, float]]:
    """Largest motion, metres, of each part a FAP must leave still, FAP by FAP.

    Each FAP with a table is played alone at ``-value`` and ``+value``.

    Returns
    -------
    dict
        FAP → {part: largest vertex motion} for the parts outside
        :func:`allowed_parts` that move at all (an empty dict for a clean FAP).
    """
    base = _neutral(head)
    fade = neck_fade(head).fade
    out = {}
    for n in (range(3, 69) if faps is None else faps):
        if (n, 0) not in head.fat:
            continue
        allowed = allowed_parts(head, n)
        worst: dict[str, float] = {}
        for v in (-value, value):
            moved = apply_fat(head.fat, base, {n: v}, head.fapu, neck_fade=fade)
            for name in base:
                if name in allowed:
                    continue
                m = float(np.linalg.norm(moved[name] - base[name], axis=1).max(initial=0.0))
                if m > 0:
                    worst[name] = max(worst.get(name, 0.0), m)
        out[n] = worst
    return out


def eyeball_centre_shift(head: Head, moved: Mapping[str, np.ndarray]) -> float:
    """How far, metres, an eyeball's centre has moved in the head's frame.

    An eyeball that only turns about its centre keeps it; the rigid motion of its vertices
    (least squares) is applied to the centre. Play the frame without the head turns
    (:data:`HEAD_TURN_FAPS`), which carry the eyes along with the head.
    """
    out = 0.0
    for name in ("eye_l", "eye_r"):
        part = head.parts.get(name)
        if part is None or part.centre is None or name not in moved:
            continue
        r, t = rigid_motion(part.vertices, np.asarray(moved[name]), part.centre)
        out = max(out, float(np.linalg.norm(t)))
    return out


def fp_prediction(head: Head, values: Mapping[int, float]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Feature point → ((3,) motion in metres, (3,) bool axes it fixes) that the standard
    predicts for a frame.

    Each translation FAP moves its feature point by value × FAPU along its axis; FAPs of
    one point add up. Only the points of translation FAPs are predicted (rotations,
    pupils and the tongue roll move whole parts), and only along the FAPs' axes.
    """
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for n, v in values.items():
        if not isinstance(n, (int, np.integer)) or n not in FAPS or not v:
            continue
        fap = FAPS[n]
        if fap.kind != "translation":
            continue
        fp = fap.feature_points[0]
        if fp not in head.feature_points:
            continue
        motion, axes = out.get(fp, (np.zeros(3), np.zeros(3, dtype=bool)))
        out[fp] = (motion + float(v) * fap_unit(n, head.fapu) * fap.axis_vector, axes | (fap.axis_vector != 0))
    return out


def fp_conformance(head: Head, values: Mapping[int, float], rel_tol: float = 0.10,
                   abs_tol: float = 0.5e-3, moved: Mapping[str, np.ndarray] | None = None) -> tuple[int, int]:
    """How many predicted feature points of a frame move as :func:`fp_prediction` says.

    A point conforms when, along every axis its FAPs fix, its motion is within
    ``max(rel_tol × |predicted|, abs_tol)`` of the prediction (across those axes it is
    free: a raised lip corner also moves in depth with the skin).

    ``moved`` gives the frame as played without the head turns (else it is played here
    with :func:`mpeg4.fat.apply_fat`).

    Returns
    -------
    (conforming, predicted) : tuple of int
    """
    pred = fp_prediction(head, values)
    if not pred:
        return 0, 0
    if moved is None:
        moved = apply_fat(head.fat, _neutral(head), {k: v for k, v in values.items() if k not in HEAD_TURN_FAPS},
                          head.fapu)
    ok = 0
    for fp, (p, axes) in pred.items():
        d = head.fp_position(fp, moved) - head.fp_position(fp)
        tol = max(rel_tol * float(np.linalg.norm(p)), abs_tol)
        ok += bool(np.all(np.abs(d - p)[axes] <= tol))
    return ok, len(pred)


def lid_overlap(head: Head, moved: Mapping[str, np.ndarray]) -> float:
    """How far, metres, a lower lid margin has passed above its upper one (0 when the lids
    stay apart or just meet): the upper margins 3.1/3.2 against the lower 3.3/3.4."""
    out = 0.0
    for upper, lower in (("3.1", "3.3"), ("3.2", "3.4")):
        if upper in head.feature_points and lower in head.feature_points:
            gap = head.fp_position(upper, moved)[1] - head.fp_position(lower, moved)[1]
            out = max(out, -float(gap))
    return out


def region_over_fp(head: Head, n: int, value: float, part: str = "skin") -> float:
    """Largest motion of ``part`` over the motion of FAP ``n``'s own point, the FAP alone
    at ``value`` (a region that outruns its point by far bulges or tears); NaN when the
    point does not move."""
    fp = FAPS[n].feature_points[0]
    base = _neutral(head)
    # Only a head turn fades over the neck: the fade is not worth finding for any other FAP.
    fade = neck_fade(head).fade if n in HEAD_TURN_FAPS else None
    moved = apply_fat(head.fat, base, {n: value}, head.fapu, neck_fade=fade)
    own = float(np.linalg.norm(head.fp_position(fp, moved) - head.fp_position(fp)))
    if own < 1e-9 or part not in moved:
        return float("nan")
    return float(np.linalg.norm(moved[part] - base[part], axis=1).max()) / own


class SurfaceChecks:
    """A part's neutral surface, to check a deformed copy: triangles turned over, edges
    stretched.

    Parameters
    ----------
    head : Head
    part : str
    """

    def __init__(self, head: Head, part: str = "skin"):
        p = head.parts[part]
        self.triangles = np.asarray(p.triangles)
        self._rest = np.asarray(p.vertices, dtype=np.float64)
        self._normals = triangle_normals(self._rest, self.triangles)
        e = np.concatenate([self.triangles[:, [0, 1]], self.triangles[:, [1, 2]], self.triangles[:, [2, 0]]])
        self.edges = np.unique(np.sort(e, axis=1), axis=0)
        self._lengths = np.linalg.norm(p.vertices[self.edges[:, 0]] - p.vertices[self.edges[:, 1]], axis=1)
        self._long = self._lengths > 1e-9

    def inverted(self, vertices: np.ndarray) -> int:
        """Number of triangles whose normal points against its neutral one
        (:func:`mpeg4.surface.inverted_triangles`; slivers of no area left out)."""
        return int(inverted_triangles(self._rest, self.triangles, vertices - self._rest,
                                      rest_normals=self._normals).sum())

    def stretch(self, vertices: np.ndarray) -> float:
        """Largest edge length over its neutral length."""
        e = self.edges[self._long]
        length = np.linalg.norm(vertices[e[:, 0]] - vertices[e[:, 1]], axis=1)
        return float((length / self._lengths[self._long]).max(initial=1.0))
