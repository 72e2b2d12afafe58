"""Inner and outer lip FAPs that share the lips instead of each moving them whole.

The inner-lip FAPs 4-13 move the points of the inner lip contour (2.2-2.9), the
outer-lip FAPs 51-60 those of the outer contour (8.1-8.8); a stream usually sets both, so
the lip between the contours must move once, not twice. A table authored for one FAP
alone moves the whole lip (the sculpted shapes and the muscles move the lip as one), so
each pair's tables are cut by a smooth partition across the lip (:func:`innerness`): the
inner FAP keeps the part from the inner contour inwards, the outer FAP the part from the
outer contour outwards, and the lip between is shared. Given together with equal effect
they give back one whole lip motion; a stream that sets only one FAP of a pair gets the
other filled by the player (:meth:`mpeg4.io.fap.FapStream.held`, :func:`mpeg4.io.fap.fill_lip_contours`).
"""

from __future__ import annotations

import numpy as np
from skimage.measure import points_in_poly

from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable
from mpeg4.head import Head

__all__ = ["MOUTH_LINE_FPS", "mouth_line", "lip_side", "smooth_partition", "INNER_LOOP", "OUTER_LOOP", "LIP_NODES",
           "innerness", "split_lip_pairs", "partition_lips", "share_lips"]

#: The inner lip contour around the mouth (right corner, upper lip, left corner, lower lip).
INNER_LOOP = ("2.5", "2.7", "2.2", "2.6", "2.4", "2.8", "2.3", "2.9")
#: The outer lip contour in the same order.
OUTER_LOOP = ("8.4", "8.6", "8.1", "8.5", "8.3", "8.7", "8.2", "8.8")


#: Inner-lip feature points that define the mouth line (see :func:`mouth_line`).
MOUTH_LINE_FPS = ("2.5", "2.7", "2.9", "2.2", "2.3", "2.6", "2.8", "2.4")


def mouth_line(points) -> np.ndarray:
    """(5, 2) polyline of the mouth, sorted along its first coordinate.

    It runs through the lip corners 2.5 and 2.4 and midway between the inner contours of
    the two lips (2.7/2.9, 2.2/2.3, 2.6/2.8), so the inner-lip points of each lip fall
    clearly on their own side.

    Parameters
    ----------
    points : mapping of str to (2,) array
        The :data:`MOUTH_LINE_FPS` in any 2D space (front-view x, y; the cloning space).
    """
    p = {i: np.asarray(points[i], dtype=np.float64) for i in MOUTH_LINE_FPS}
    line = np.array([p["2.5"], 0.5 * (p["2.7"] + p["2.9"]), 0.5 * (p["2.2"] + p["2.3"]), 0.5 * (p["2.6"] + p["2.8"]),
                     p["2.4"]])
    return line[np.argsort(line[:, 0])]


def lip_side(head: Head, part: str) -> np.ndarray | None:
    """(N,) +1 for vertices of ``part`` above the mouth line, −1 below, 0 beyond the corners."""
    if part != "skin" or not all(i in head.feature_points for i in MOUTH_LINE_FPS):
        return None
    line = mouth_line({i: head.fp_position(i)[:2] for i in MOUTH_LINE_FPS})
    v = head.parts[part].vertices
    line_y = np.interp(v[:, 0], line[:, 0], line[:, 1])
    inside = (v[:, 0] > line[0, 0]) & (v[:, 0] < line[-1, 0])
    return np.where(inside, np.sign(v[:, 1] - line_y), 0.0)


def smooth_partition(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N, K) smooth partition of unity over increasing ``nodes``: column j is 1 at node j,
    0 at its neighbours, the quintic smoothstep between, and the outer columns 1 beyond the
    outer nodes.

    ``nodes`` (K,) places each node at one x; (K, 2) gives each an interval [lo, hi] on
    which its column is 1 (a point bound to an edge or a triangle: all its vertices take
    its whole piece), the intervals in order and apart.
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    lo, hi = (nodes, nodes) if nodes.ndim == 1 else (nodes[:, 0], nodes[:, 1])
    x = np.asarray(x, dtype=np.float64)
    k = len(lo)
    out = np.zeros((len(x), k))
    for j in range(k):
        out[(x >= lo[j]) & (x <= hi[j]), j] = 1.0
    for j in range(k - 1):
        a, b = hi[j], lo[j + 1]
        inside = (x > a) & (x < b)
        t = (x[inside] - a) / (b - a)
        step = t ** 3 * (10 - 15 * t + 6 * t ** 2)
        out[inside, j] = 1 - step
        out[inside, j + 1] = step
    out[x < lo[0], 0] = 1.0
    out[x > hi[-1], -1] = 1.0
    return out


def _distance_to_loop(points: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """(N,) distance of 2D points to a closed polyline (M, 2)."""
    a, b = loop, np.roll(loop, -1, axis=0)
    ab = b - a
    t = np.einsum("nmk,mk->nm", points[:, None, :] - a[None], ab) / np.maximum((ab * ab).sum(axis=1), 1e-30)
    closest = a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2).min(axis=1)


def innerness(head: Head, part: str = "skin") -> np.ndarray | None:
    """(N,) weight in [0, 1] across the lips for the vertices of ``part``.

    1 on and inside the inner lip contour, 0 on and outside the outer contour, and in
    between the smoothstep of ``d_outer / (d_inner + d_outer)``, the distances to the two
    contours in the front view (x, y). None when the head lacks a contour point or the
    part does not carry them.
    """
    ids = INNER_LOOP + OUTER_LOOP
    if not all(i in head.feature_points and head.feature_points[i].part == part for i in ids):
        return None
    v = head.parts[part].vertices[:, :2]
    inner = np.array([head.fp_position(i)[:2] for i in INNER_LOOP])
    outer = np.array([head.fp_position(i)[:2] for i in OUTER_LOOP])
    d_in, d_out = _distance_to_loop(v, inner), _distance_to_loop(v, outer)
    t = d_out / np.maximum(d_in + d_out, 1e-30)
    w = t * t * (3 - 2 * t)
    w[~points_in_poly(v, outer)] = 0.0
    w[points_in_poly(v, inner)] = 1.0
    # The points themselves: each FAP moves its own contour's points alone.
    for ids_, value in ((INNER_LOOP, 1.0), (OUTER_LOOP, 0.0)):
        for i in ids_:
            w[list(head.feature_points[i].vertices)] = value
    return w


def _scaled(table: FaceDefTable, part: str, weight: np.ndarray) -> FaceDefTable:
    meshes = []
    for m in table.meshes:
        if m.part == part:
            d = m.displacements * weight[m.indices][:, None, None]
            keep = np.abs(d).reshape(len(m.indices), -1).max(axis=1) > 0
            m = FaceDefMesh(m.part, m.borders, m.indices[keep], d[keep])
        meshes.append(m)
    return FaceDefTable(table.fap, table.high_level, meshes, list(table.transforms))


def split_lip_pairs(head: Head, fat: FAT, part: str = "skin") -> FAT:
    """``fat`` with each inner/outer lip pair's tables cut by :func:`innerness`.

    The inner FAP n (4-13) keeps its motion weighted by the innerness, the outer FAP
    n + 47 its own weighted by one minus it. Pairs of which either table is missing, and
    heads without both lip contours, are left as they are.
    """
    w = innerness(head, part)
    if w is None:
        return fat
    out = FAT(fat)
    for n in range(4, 14):
        m = n + 47
        if (n, 0) in fat and (m, 0) in fat:
            out.add(_scaled(fat[(n, 0)], part, w))
            out.add(_scaled(fat[(m, 0)], part, 1.0 - w))
    return out




#: Per lip contour, its points across the mouth, right corner to left corner, on the upper
#: and on the lower lip (the corners shared), and the FAPs that move them: per place, the
#: upper lip's and the lower lip's vertical FAP, or at a corner its vertical and horizontal.
LIP_NODES = {
    "inner": (("2.5", "2.7", "2.2", "2.6", "2.4"), ("2.5", "2.9", "2.3", "2.8", "2.4"),
              ((13, 7), (9, 11), (4, 5), (8, 10), (12, 6))),
    "outer": (("8.4", "8.6", "8.1", "8.5", "8.3"), ("8.4", "8.8", "8.2", "8.7", "8.3"),
              ((60, 54), (56, 58), (51, 52), (55, 57), (59, 53))),
}


def partition_lips(head: Head, fat: FAT, part: str = "skin") -> FAT:
    """``fat`` with each lip FAP's table cut by a smooth partition across the mouth.

    Along each contour the lip FAPs' points lie a centimetre apart, less than the reach of
    the motion each table carries (a sculpted shape or a smooth bump moves the whole lip),
    so each FAP moved its neighbours' points too: played together, as every stream plays
    them, no point went where its own FAP says. Cut by a partition of unity across the
    mouth (:func:`smooth_partition` over the x of the lip's points: corner,
    midpoint, centre, midpoint, corner), a FAP keeps its table at its own point and fades to
    nothing at the neighbouring points: each point then moves by its own FAP, and equal
    values on every point still add up to one whole-lip motion. The upper lip's FAPs are
    cut along the upper lip's points, the lower lip's along the lower's, a corner's along
    the lip each vertex belongs to (:func:`lip_side`). Heads without all the
    lip points are left as they are.
    """
    out = FAT(fat)
    side = lip_side(head, part)
    if part not in head.parts or side is None:
        return out
    x = head.parts[part].vertices[:, 0]
    for upper, lower, faps in LIP_NODES.values():
        if not all(i in head.feature_points and head.feature_points[i].part == part for i in upper + lower):
            continue
        # Each point's piece is whole over all the vertices it is bound to.
        nodes = [np.array([[x[list(head.feature_points[i].vertices)].min(), x[list(head.feature_points[i].vertices)].max()]
                           for i in ids]) for ids in (upper, lower)]
        if any(np.any(n[1:, 0] <= n[:-1, 1]) for n in nodes):
            continue
        cut_up, cut_low = (smooth_partition(n, x) for n in nodes)
        for j, group in enumerate(faps):
            corner = j in (0, len(faps) - 1)
            for k, n in enumerate(group):
                if (n, 0) not in out:
                    continue
                if corner:
                    cut = np.where(side < 0, cut_low[:, j], cut_up[:, j])
                else:
                    cut = (cut_up if k == 0 else cut_low)[:, j]
                out.add(_scaled(out[(n, 0)], part, cut))
    return out


def share_lips(head: Head, fat: FAT, part: str = "skin") -> FAT:
    """The lip FAPs' tables cut to share the lips: across the lip between the contours
    (:func:`split_lip_pairs`) and across the mouth between the places
    (:func:`partition_lips`)."""
    return partition_lips(head, split_lip_pairs(head, fat, part), part)
