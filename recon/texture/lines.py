"""The lines along which the photos' layers of the skin's texture meet.

The side photo's **feature line** (the feature points from the top of the skull down to the
ear's front, :data:`~recon.texture.warp.FEATURE_LINE`, then down the neck) is laid on the
head's skin for each side (:func:`feature_line`; over the skull on the skin itself,
:func:`on_skin`). With both photos at hand the front photo's region ends further forward
below the brow, where the two photos see the skin about equally squarely (:func:`view_line`,
its bands' splits chosen together, :func:`smoothest_splits`), never inside the face's
features (:func:`feature_envelope`). :mod:`recon.texture.regions` bounds the front photo's
region by these lines.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial import ConvexHull

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError

from .warp import FEATURE_LINE, convex_outline, sections

__all__ = ["SPLIT_STIFFNESS", "OVER_SKULL", "FEATURE_MARGIN_ES", "line_ids", "feature_line", "on_skin", "view_line",
           "smoothest_splits", "feature_envelope", "line_depth"]

_NECK_STEP = 0.01  # metres between the neck line's points


def line_ids(side: str) -> tuple[str, ...]:
    """The feature line of the face's ``"L"`` (as listed) or ``"R"`` side (mirrored ids)."""
    if side == "L":
        return FEATURE_LINE
    return tuple(FEATURE_POINTS[i].mirror or i for i in FEATURE_LINE)


def feature_line(points3d: Mapping[str, np.ndarray], skin_vertices: np.ndarray, skin_triangles: np.ndarray,
                 side: str) -> tuple[np.ndarray, np.ndarray]:
    """The feature line of one side of the face, top to bottom.

    Its feature points (:data:`FEATURE_LINE`, mirrored for ``"R"``), over the skull (from
    its top to the brow's end, :data:`OVER_SKULL` of them) with points on the skin between
    them every :data:`_NECK_STEP` (:func:`on_skin`), and, below the last of them (the ear's
    front), a line down the neck: at every :data:`_NECK_STEP` down to the bottom of the
    skin, the point of the skin's cross-section (its convex outline) that faces half way
    between the front and the side, where both photos see the neck at 45°. The front photo
    gets the neck's front, the side photos what lies behind.

    Returns
    -------
    points : (K, 3) float64
        Metres.
    is_fp : (K,) bool
        Which of them are feature points.
    """
    ids = line_ids(side)
    missing = [i for i in ids if i not in points3d]
    if missing:
        raise InputError(f"the head lacks the feature points {', '.join(missing)} of the texture's feature lines",
                         where="texture", fix="give the head all of " + ", ".join(ids))
    fps = np.array([np.asarray(points3d[i], float) for i in ids])
    sign = 1.0 if side == "L" else -1.0
    v = np.asarray(skin_vertices, float)
    heights = np.arange(fps[-1, 1] - _NECK_STEP, v[:, 1].min() + 0.004, -_NECK_STEP)
    neck = []
    for y, xz in zip(heights, sections(v, skin_triangles, heights)):
        if (xz[:, 0] * sign > 0).sum() < 3:
            break
        hull = convex_outline(xz)
        if hull is None:  # a degenerate section: the line ends here
            break
        # The outline's point that faces half way between the two cameras (its support
        # point along the 45° direction): both photos see the neck there at 45°, not the
        # front one at a grazing angle.
        k = int(np.argmax(hull @ np.array([sign, 1.0])))
        neck.append([hull[k, 0], y, hull[k, 1]])
    skull, skull_fp = on_skin(fps[:OVER_SKULL], v, skin_triangles, _NECK_STEP)
    points = np.vstack([skull, fps[OVER_SKULL:], np.array(neck).reshape(-1, 3)])
    return points, np.r_[skull_fp, np.ones(len(fps) - OVER_SKULL, bool), np.zeros(len(neck), bool)]


#: The feature line's points over the skull: its top, the hairline's end and the brow's end.
OVER_SKULL = 3


def on_skin(points: np.ndarray, skin_vertices: np.ndarray, skin_triangles: np.ndarray,
            step: float) -> tuple[np.ndarray, np.ndarray]:
    """A polyline of points on the skin with points added between them, every ``step``
    metres or less, on the skin's cross-section at their height (the nearest point of it to
    the chord): the line runs over the surface instead of under it.

    Over the skull the feature line's points lie 40-70 mm apart; the straight chords between
    them pass up to 15 mm under the skin. The front region ends at the line's depth and the side
    photo's warp is anchored on it: on a chord, the front photo's crown and the side photo's
    meet at two places of the texture that are not side by side, a seam no blend can reach
    (a dark cap on the crown bounded by the hair's outline, in a real pair).

    Returns
    -------
    points : (K, 3) float64
    is_given : (K,) bool
        Which of them are the given points.
    """
    p = np.asarray(points, float)
    out, given, added = [p[0]], [True], []
    for a, b in zip(p[:-1], p[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        for j in range(1, k):
            added.append(len(out))
            out.append(a + (b - a) * (j / k))
            given.append(False)
        out.append(b)
        given.append(True)
    out = np.array(out)
    if added:
        cuts = sections(np.asarray(skin_vertices, float), np.asarray(skin_triangles), out[added, 1])
        for i, xz in zip(added, cuts):
            if len(xz):
                near = xz[np.argmin(np.sum((xz - out[i, [0, 2]]) ** 2, axis=1))]
                out[i, [0, 2]] = near
    return out, np.array(given)


def view_line(points3d: Mapping[str, np.ndarray], skin_vertices: np.ndarray, skin_triangles: np.ndarray,
              side: str, toward_front: np.ndarray, toward_side: np.ndarray,
              step: float = _NECK_STEP, normals: np.ndarray | None = None,
              registration: tuple[float, float] = (1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """The line along which the front and the side photo see one side of the head alike,
    top to bottom: where the front region ends when both photos are at hand.

    The feature line (:func:`feature_line`) runs down the front of the ear: the cheek before
    it faces the side camera, and the front photo sees it edge-on, its skin squeezed into a
    few pixels (the texture's horizontal streaks there). This line keeps the feature line's
    points above the outer end of the brow (the top of the skull, the hairline's end, the
    brow's end: exact in both photos). Below the brow's end, every ``step`` metres down to
    the feature line's end, it splits the band of skin ahead of the feature line at that
    height, ordered outwards, where the least skin area goes to the photo that sees it
    worse: a vertex is better seen from the front when its colour lands closer to it from
    there. A photo whose pixels land within ``r`` of where they belong (its registration)
    puts a surface seen at angle θ within ``r / cos θ``, so the front wins when
    ``n . toward_front / r_front >= n . toward_side / r_side``: with equal registrations,
    when it faces the front camera at least as squarely as the side camera.
    One split per band, weighed by area, so that the side of the nose or a hollow at the
    temple moves it only by their own area instead of cutting the face there.

    The split never falls inside the face's features (:func:`feature_envelope`: the brows,
    eyes, nose and lips of that side, and a margin): a side photo's pixels land there worst
    (the eye sits deep in its socket, the lids and brows are seen edge-on), and on the side
    the side photo does not show, its mirror image would paint the *other* eye; an eye
    made of two photos, or of the wrong one, is what a viewer sees first.

    Parameters
    ----------
    points3d, skin_vertices, skin_triangles, side
        As :func:`feature_line`.
    toward_front, toward_side : (3,) float
        Unit directions from the head towards the front camera and towards the side camera
        on this side of the face (the side photo's, or its mirror image).
    step : float
        Metres between the line's points below the brow.
    normals : (N, 3) float, optional
        The skin's vertex normals (computed when None).
    registration : (float, float)
        How far the front and the side photo's pixels may land from the skin they belong
        to (:meth:`recon.texture.cameras.FittedCamera.registration_m`); only their ratio
        counts.

    Returns
    -------
    points : (K, 3) float64
        Metres: the feature line over the skull, then the splits below the brow's end.
    is_fp : (K,) bool
        Which of them are feature points (the top of the skull, the hairline's end and the
        brow's end).
    """
    from mpeg4.render import vertex_normals

    ear, ear_fp = feature_line(points3d, skin_vertices, skin_triangles, side)
    top = int(np.flatnonzero(ear_fp)[OVER_SKULL - 1]) + 1  # down to the brow's end
    sign = 1.0 if side == "L" else -1.0
    v = np.asarray(skin_vertices, float)
    n = vertex_normals(v, np.asarray(skin_triangles)) if normals is None else normals
    order = np.argsort(ear[:, 1])
    z_ear = np.interp(v[:, 1], ear[order, 1], ear[order, 2])
    r_front, r_side = registration
    better = (n @ np.asarray(toward_front, float)) * r_side - (n @ np.asarray(toward_side, float)) * r_front >= 0
    area = np.zeros(len(v))  # each vertex's share of the skin's area
    t = np.asarray(skin_triangles)
    np.add.at(area, t.ravel(), np.repeat(0.5 / 3 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]],
                                                                            v[t[:, 2]] - v[t[:, 0]]), axis=1), 3))
    ahead = np.flatnonzero((v[:, 0] * sign > 0) & (v[:, 2] >= z_ear))
    heights = np.arange(ear[top - 1, 1] - step, ear[-1, 1] - 0.5 * step, -step)
    inner = feature_envelope(points3d, side, heights)
    bands, costs = [], []
    for y, lim in zip(heights, inner):
        k = ahead[np.abs(v[ahead, 1] - y) <= 0.5 * step]
        if len(k) < 2:
            continue
        k = k[np.argsort(v[k, 0] * sign, kind="stable")]
        w, good = area[k], better[k]
        # Split the band where the least skin area is left with the photo that sees it worse:
        # vertices 0..j front, the rest side (a hollow at the temple or the side of the
        # nose only moves the split by its own area), never inside the features.
        cost = np.cumsum(w * ~good) + (np.sum(w * good) - np.cumsum(w * good))
        cost[:max(int(np.searchsorted(v[k, 0] * sign, lim)) - 1, 0)] = np.inf
        bands.append((y, k))
        costs.append(cost)
    splits = smoothest_splits(costs, [v[k][:, [0, 2]] for _, k in bands], SPLIT_STIFFNESS * step)
    line = [[v[k[j], 0], y, v[k[j], 2]] for (y, k), j in zip(bands, splits)]
    points = np.vstack([ear[:top], np.array(line).reshape(-1, 3)])
    return points, np.r_[ear_fp[:top], np.zeros(len(line), bool)]


#: How dearly the view line pays for a sideways step between neighbouring bands, per metre
#: stepped, as a share of the band's height (the most skin area a step of that length can
#: move to the better photo). Below 1 a split can move; at 0.5 a lone band hardly jumps
#: from its neighbours (it pays for two steps about the most it can gain on one), and a
#: stretch of ``k`` bands moves when more than about ``1 / k`` of the skin it passes over
#: is better seen from the other photo: the split follows the face's shape, not the noise of single
#: normals (one band's jump to the ear and back shears the side photo's warp into a
#: zig-zag, a seam across the cheek).
SPLIT_STIFFNESS = 0.5


def smoothest_splits(costs, points, penalty: float) -> list[int]:
    """The split of each band that minimises the bands' costs plus ``penalty`` times the
    length of the steps between consecutive bands' splits (dynamic programming, exact).

    Parameters
    ----------
    costs : sequence of (n_i,) float
        Each band's cost of splitting at each of its candidates (``inf``: never there).
    points : sequence of (n_i, D) float
        Where each candidate lies (metres).
    penalty : float
        Cost per metre stepped between bands.

    Returns
    -------
    list of int
        The chosen candidate of each band.
    """
    if not costs:
        return []
    total, back = np.asarray(costs[0], float), []
    for c, p0, p1 in zip(costs[1:], points[:-1], points[1:]):
        step = np.linalg.norm(np.asarray(p0, float)[:, None] - np.asarray(p1, float)[None], axis=2)
        reach = total[:, None] + penalty * step  # (n_prev, n_next)
        best = np.argmin(reach, axis=0)
        total = reach[best, np.arange(reach.shape[1])] + np.asarray(c, float)
        back.append(best)
    out = [int(np.argmin(total))]
    for best in reversed(back):
        out.append(int(best[out[-1]]))
    return out[::-1]


#: The face's features whose texture comes from one photo whole: brows, eyes, lips, nose.
_FEATURE_GROUPS = (3, 4, 8, 9)
#: How far beyond its feature points a feature's skin reaches, in eye separations (ES0):
#: the upper lid's fold and the crow's feet run about 5 mm past the eye's outer corner,
#: and the multiresolution blend spreads a seam over about as much again.
FEATURE_MARGIN_ES = 0.15


def feature_envelope(points3d: Mapping[str, np.ndarray], side: str, heights: np.ndarray,
                     margin: float | None = None) -> np.ndarray:
    """How far out from the midline the face's features reach on one side, per height.

    The convex hull, in (height, distance from the midline), of the brow, eye, lip and nose
    feature points on ``side`` and the midline (MPEG-4 groups 3, 4, 8 and 9), widened by
    ``margin``.

    Parameters
    ----------
    points3d : mapping of str to (3,) float
        The head's feature points, metres (x to the head's left, y up).
    side : {"L", "R"}
        ``"L"``: x > 0.
    heights : (K,) float
        Metres.
    margin : float, optional
        Metres; :data:`FEATURE_MARGIN_ES` eye separations (3.5 to 3.6) by default.

    Returns
    -------
    (K,) float64
        Distance from the midline, metres; -inf at heights above or below every feature
        (nothing to keep there).
    """
    sign = 1.0 if side == "L" else -1.0
    own = [np.asarray(p, float) for i, p in points3d.items()
           if i in FEATURE_POINTS and FEATURE_POINTS[i].group in _FEATURE_GROUPS
           and FEATURE_POINTS[i].side in (side, "C")]
    heights = np.asarray(heights, float)
    out = np.full(len(heights), -np.inf)
    if len(own) < 3:
        return out
    if margin is None:
        es = (np.linalg.norm(np.asarray(points3d["3.5"]) - np.asarray(points3d["3.6"]))
              if "3.5" in points3d and "3.6" in points3d else 0.063)
        margin = FEATURE_MARGIN_ES * es
    p = np.array([[q[1], max(q[0] * sign, 0.0)] for q in own])
    p = np.vstack([p, [[p[:, 0].max(), 0.0], [p[:, 0].min(), 0.0]]])  # closed at the midline
    hull = p[ConvexHull(p).vertices]
    a, b = hull, np.roll(hull, -1, axis=0)
    for k, y in enumerate(heights):
        lo, hi = np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 0], b[:, 0])
        e = (lo <= y) & (y <= hi) & (hi > lo)
        if e.any():
            t = (y - a[e, 0]) / (b[e, 0] - a[e, 0])
            out[k] = np.max(a[e, 1] + t * (b[e, 1] - a[e, 1])) + margin
    return out


def line_depth(left: np.ndarray, right: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """(N,) z (metres) of the feature lines at the given heights (y, metres): linear along
    each line by height, the mean of the left and right lines, held beyond the ends."""
    out = []
    for p in (np.asarray(left), np.asarray(right)):
        order = np.argsort(p[:, 1])
        out.append(np.interp(heights, p[order, 1], p[order, 2]))
    return 0.5 * (out[0] + out[1])
