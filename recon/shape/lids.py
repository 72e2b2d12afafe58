"""The neutral lids: how open the eyes are in the photos, and the head's lids posed to match.

A person photographed with lowered lids (a heavy upper lid, a gaze a little down, a
squint) has lid margins (3.1/3.3 on the left eye, 3.2/3.4 on the right) nearer together
than the generic head's. The deformation pins those two feature points where the photos
put them, but it moves them as points: pulled a few millimetres down, a lid margin's
centre goes into the eyeball, which then shows through the lid as a wide-open eye, or
makes a notch in the margin.

So the lids are posed first, as a face closes them: :func:`pose_lids` adds the ICT
FaceKit's sculpted lid shapes (the generic head's morph targets: ``eyeBlink`` lowers the
upper lid, ``eyeWide`` raises it, ``eyeSquint`` raises the lower lid and, reversed, lowers
it) to the head the deformation starts from, with the weights that give each eye's lid
margins the heights the photos show (:func:`lid_heights`). The sculpted shapes slide the
lids over the eyeball (at full blink no outer lid vertex of the generic head goes more
than 0.13 mm into it), and an identity plus expression shapes is the ICT FaceKit's own
model of a face. The generic head's Facial Animation Tables for the lid FAPs 19-22 were
the other candidate and were not taken: no combination of shapes met those FAPs' axes,
so they are local displacement fields that push the lid straight down, up to 0.9 mm into
the eyeball at a quarter of their travel, and FAP 21's drags the upper lid 4 mm back.

Heights are measured against the line through the eye's corners (3.7-3.11, 3.12-3.8),
at right angles to it, in eye widths (the corners' distance): a head roll and the
photo's scale drop out, and the corners, fixed to the skull, do not move with the gaze.

References
----------
.. [1] ICT FaceKit, USC Institute for Creative Technologies: identity and ARKit-named
   expression blendshapes (``data/generic_head/README.md``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.head import Head

__all__ = ["EYES", "LID_MARGINS", "LID_SHAPES", "MIN_OPENING", "lid_heights", "pose_lids", "lid_opening_mm",
           "neutral_lids", "settle_lids"]

#: Per eye: upper lid margin, lower lid margin, outer corner, inner corner.
EYES = {"left": ("3.1", "3.3", "3.7", "3.11"), "right": ("3.2", "3.4", "3.12", "3.8")}

#: The lid margins' feature points.
LID_MARGINS = ("3.1", "3.2", "3.3", "3.4")

#: Per eye, the sculpted shapes that pose its lids: upper lid down, upper lid up, lower lid up.
LID_SHAPES = {"left": ("eyeBlink_L", "eyeWide_L", "eyeSquint_L"),
              "right": ("eyeBlink_R", "eyeWide_R", "eyeSquint_R")}

#: Smallest lid opening built, in eye widths (about 3 mm): a photo with the eyes nearly
#: shut is not a neutral face, and the FAP unit IRISD (the lids' distance) would shrink
#: to nothing with it.
MIN_OPENING = 0.1

# Weight of the shapes' sizes against the heights' misfit (eye widths squared per unit
# weight squared): the smallest posing that meets the heights.
_RIDGE = 1e-4


def lid_heights(points: Mapping[str, np.ndarray], image: bool = False) -> dict[str, np.ndarray]:
    """How open each eye is: its lid margins' heights above and below the eye's corner line.

    Parameters
    ----------
    points : mapping of str to (2,) or (3,) array
        FP id → position: pixels of a front photo (``image=True``: y down) or metres in
        the neutral frame (y up; x and y are used, as a front view shows them).
    image : bool
        Whether ``points`` are pixels with y down.

    Returns
    -------
    dict of str to (2,) float64
        ``"left"``/``"right"`` → (upper, lower): the upper margin's distance above the line
        through the corners and the lower margin's below it, in eye widths (the corners'
        distance); their sum is the opening. Eyes missing a point are left out.

    Examples
    --------
    >>> h = lid_heights({"3.1": [0.03, 0.012], "3.3": [0.03, 0.002], "3.7": [0.045, 0.005],
    ...                  "3.11": [0.015, 0.005]})["left"]
    >>> np.round(h, 4).tolist()
    [0.2333, 0.1]
    """
    out = {}
    for eye, (up, low, outer, inner) in EYES.items():
        if not all(i in points for i in (up, low, outer, inner)):
            continue
        p = {i: np.asarray(points[i], dtype=np.float64)[:2] * ([1.0, -1.0] if image else 1.0)
             for i in (up, low, outer, inner)}
        along = p[outer] - p[inner]
        width = float(np.linalg.norm(along))
        if width <= 0:
            continue
        along /= width
        normal = np.array([-along[1], along[0]])
        if normal[1] < 0:  # the face's up, whichever way the corners run
            normal = -normal
        out[eye] = np.array([(p[up] - p[inner]) @ normal, -((p[low] - p[inner]) @ normal)]) / width
    return out


def lid_opening_mm(head: Head, vertices: Mapping[str, np.ndarray] | None = None) -> dict[str, float]:
    """Per eye, the lid margins' distance in height (3.1.y - 3.3.y, 3.2.y - 3.4.y), mm: the
    head's IRISD0 when it is neutral."""
    return {eye: 1e3 * float(head.fp_position(up, vertices)[1] - head.fp_position(low, vertices)[1])
            for eye, (up, low, _, _) in EYES.items() if up in head.feature_points and low in head.feature_points}


def _shape_deltas(head: Head, names) -> dict[str, np.ndarray] | None:
    """Part → (S, N, 3) dense displacements of the named morph targets; None when the head
    lacks one."""
    if not all(n in head.morph_targets for n in names):
        return None
    parts = sorted({p for n in names for p in head.morph_targets[n]})
    out = {}
    for part in parts:
        d = np.zeros((len(names), head.parts[part].n_vertices, 3))
        for k, n in enumerate(names):
            t = head.morph_targets[n].get(part)
            if t is not None:
                d[k, t.indices] = t.vectors
        out[part] = d
    return out


def _solve(heights, want: np.ndarray, n: int, lo=0.0, hi=1.0, ridge: float = _RIDGE) -> tuple[np.ndarray, float]:
    """Weights within [lo, hi] minimising ``|heights(w) - want|² + ridge |w|²`` (Gauss-Newton
    rounds of bounded linear least squares), and that cost."""
    from scipy.optimize import lsq_linear

    w = np.zeros(n)
    for _ in range(5):
        h = heights(w)
        jac = np.stack([heights(w + 0.1 * np.eye(n)[k]) - h for k in range(n)], axis=1) / 0.1
        a = np.vstack([jac, np.sqrt(ridge) * np.eye(n)])
        b = np.r_[want - h + jac @ w, np.zeros(n)]
        step = lsq_linear(a, b, bounds=(lo, hi)).x
        done = np.abs(step - w).max() < 1e-6
        w = step
        if done:
            break
    return w, float(np.sum((heights(w) - want) ** 2) + ridge * w @ w)


def pose_lids(head: Head, target: Mapping[str, np.ndarray]) -> tuple[Head, dict]:
    """The head with its lids posed so that each eye's margins have the ``target`` heights.

    Per eye the upper lid takes its blink or its widening (one of the two, whichever fits
    better) and the lower lid its squint, each with a weight in [0, 1] (the sculpted
    range; the squint also in [-1, 0], reversed, to lower the lower lid, which the blink
    raises a little), minimising ``|heights(w) - target|² + 1e-4 |w|²`` (a few Gauss-Newton
    rounds of bounded linear least squares: the heights are nearly linear in the weights).

    Parameters
    ----------
    head : Head
        With the feature points of :data:`EYES` and the morph targets of :data:`LID_SHAPES`
        (the generic head and the heads made from it carry them).
    target : mapping of str to (2,) array
        ``"left"``/``"right"`` → (upper, lower) heights in eye widths
        (:func:`lid_heights`); an eye not given keeps its lids.

    Returns
    -------
    head : Head
        A new head (the given one when nothing was posed).
    record : dict
        Per eye: ``target`` and ``posed`` heights, ``weights`` by shape name (those not used
        at 0), ``met`` (the target met within 0.01 eye widths, about 0.3 mm; else the shapes'
        range fell short); empty for a head without the shapes.
    """
    record: dict = {}
    vertices = {name: p.vertices for name, p in head.parts.items()}
    for eye, want in target.items():
        names = LID_SHAPES[eye]
        deltas = _shape_deltas(head, names)
        if deltas is None or not all(i in head.feature_points for i in EYES[eye]):
            continue
        want = np.asarray(want, dtype=np.float64).reshape(2)
        base = vertices

        def moved(w):
            return {p: v + np.tensordot(w, deltas[p], 1) if p in deltas else v for p, v in base.items()}

        def heights(w):
            at = moved(w)
            return lid_heights({i: head.fp_position(i, at) for i in EYES[eye]})[eye]

        best = None
        for upper in (0, 1):  # the blink, or the widening, with the squint
            w, cost = _solve(lambda x: heights(np.r_[x[0] * (upper == 0), x[0] * (upper == 1), x[1]]), want, 2,
                             lo=np.array([0.0, -1.0]))
            full = np.r_[w[0] * (upper == 0), w[0] * (upper == 1), w[1]]
            if best is None or cost < best[1]:
                best = (full, cost)
        w = best[0]
        vertices = moved(w)
        h = heights(w)
        record[eye] = {"target": [round(float(x), 4) for x in want], "posed": [round(float(x), 4) for x in h],
                       "weights": {n: round(float(x), 4) for n, x in zip(names, w)},
                       "met": bool(np.abs(h - want).max() <= 0.01)}
    if not record:
        return head, record
    return head.with_vertices({p: v for p, v in vertices.items() if v is not head.parts[p].vertices}), record


def neutral_lids(start: Head, goal: Mapping[str, np.ndarray], front: Mapping[str, np.ndarray],
                 min_opening: float = MIN_OPENING) -> tuple[Head, dict, dict]:
    """The head a deformation onto ``goal`` starts from, with its lids posed as the front
    photo shows them, and the goal it then pins.

    The heights come from the front photo's points rather than from the 3D points, whose
    inner eye corners (seen in the front photo alone) take their depth, and through the
    perspective some of their height, from a model (the generic head carried by the side
    photo's depths: a few millimetres of depth, a few tenths of a millimetre of height
    through a 100 mm lens, where the lids open 3 mm), while the photo's own proportions
    are exact. The lid margins leave the goal: pinned as points they would
    still be pulled, alone, wherever their photo positions' small disagreements with the
    posed lid put them (into the eyeball, or into a notch in the margin); the deformation
    carries the posed lids with the eye's corners, the lid fold and the eyeball around them.

    Parameters
    ----------
    start : Head
        The head the deformation starts from (the identity model's, or the generic head).
    goal : mapping of str to (3,) array
        The 3D feature points the deformation will pin, metres.
    front : mapping of str to (2,) array
        The front photo's points, pixels (:func:`lid_heights` with ``image=True``).
    min_opening : float
        An eye whose photo shows its lids nearer together than this (eye widths) is posed
        with them that far apart, each moved by half the shortfall.

    Returns
    -------
    start : Head
        Posed by :func:`pose_lids`.
    goal : dict
        The goal without the lid margins of the eyes posed.
    record : dict
        Per eye: ``measured`` (the photo's ``upper`` and ``lower`` heights, in eye widths),
        ``shapes`` (the weights applied), ``met`` (see :func:`pose_lids`), and
        ``widened_to`` (the opening posed) when the photo's was under ``min_opening``.
    """
    measured = lid_heights(front, image=True)
    target = {eye: h + max(min_opening - float(h.sum()), 0.0) / 2 for eye, h in measured.items()}
    posed, pose = pose_lids(start, target)
    goal = dict(goal)
    record = {}
    for eye, r in pose.items():
        h = measured[eye]
        record[eye] = {"measured": {"upper": round(float(h[0]), 4), "lower": round(float(h[1]), 4)},
                       "shapes": r["weights"], "met": r["met"]}
        if h.sum() < min_opening:
            record[eye]["widened_to"] = min_opening
        for i in EYES[eye][:2]:
            goal.pop(i, None)
    return posed, goal, record


def settle_lids(head: Head, goal: Mapping[str, np.ndarray], record: Mapping[str, dict]) -> Head:
    """The deformed head's lid margins brought to the goal's heights by the same shapes.

    :func:`neutral_lids` posed the start by the front photo's proportions and took the
    margins out of the goal; the deformation then carried the lids with the eye around
    them, which moves them a little (on synthetic photos up to 0.6 mm: the inner corners'
    3D heights are the least sure). This small second pose puts each margin's height
    back on the goal's (the goal's 3D heights of the margins themselves are sure: both
    photos agree on them within 0.2 mm there) without pulling the margin alone.

    Parameters
    ----------
    head : Head
        The deformed head.
    goal : mapping of str to (3,) array
        The 3D points the deformation was to pin, with the lid margins.
    record : mapping of str to dict
        :func:`neutral_lids`'s record: the weights already applied; they are updated in
        place (``shapes``, and ``settled_mm``, how far the margins' heights moved).

    Returns
    -------
    Head
    """
    vertices = {name: p.vertices for name, p in head.parts.items()}
    for eye, r in record.items():
        names = LID_SHAPES[eye]
        up, low = EYES[eye][:2]
        deltas = _shape_deltas(head, names)
        if deltas is None or up not in goal or low not in goal:
            continue
        base_w = np.array([r["shapes"][n] for n in names])
        base = vertices
        want = np.array([goal[up][1], goal[low][1]], dtype=np.float64)

        def moved(w):
            return {p: v + np.tensordot(w, deltas[p], 1) if p in deltas else v for p, v in base.items()}

        def margins(w):
            at = moved(w)
            return np.array([head.fp_position(up, at)[1], head.fp_position(low, at)[1]])

        # Metres here: a ridge of 1e-10 m² per unit weight² (0.01 mm per 0.1 weight).
        w, _ = _solve(margins, want, len(names), lo=-base_w, hi=1.0 - base_w, ridge=1e-10)
        before = margins(np.zeros(len(names)))
        vertices = moved(w)
        r["shapes"] = {n: round(float(x), 4) for n, x in zip(names, base_w + w)}
        r["settled_mm"] = [round(1e3 * float(x), 3) for x in margins(w) - before]
    return head.with_vertices({p: v for p, v in vertices.items() if v is not head.parts[p].vertices})
