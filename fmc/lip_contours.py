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

__all__ = ["INNER_LOOP", "OUTER_LOOP", "innerness", "split_lip_pairs"]

#: The inner lip contour around the mouth (right corner, upper lip, left corner, lower lip).
INNER_LOOP = ("2.5", "2.7", "2.2", "2.6", "2.4", "2.8", "2.3", "2.9")
#: The outer lip contour in the same order.
OUTER_LOOP = ("8.4", "8.6", "8.1", "8.5", "8.3", "8.7", "8.2", "8.8")


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


