"""Contours between feature points: the eyelid margins, the lips' inner contours and the
mouth's corners.

The motion changes fastest across the eyelid margins (a lid closes, the skin beside it
does not) and the lips' inner contours (the lips part), so a small misalignment there
costs the most. Each contour runs through feature points (an eye's inner corner, the
centre of its lid's margin, its outer corner; a lip's inner corners and the points along
it; a mouth corner's outer and inner points); between two of them it is the shortest
path along the skin's edges (:func:`contour_path`). Sampled by arc length on both heads, the contours give the
alignment more points that correspond (:func:`contour_pairs`), held by
:func:`fmc.clone.align.surface_warp` like the feature points.

On ICT FaceKit identities (the generic head to seeds 2000-2002, same topology, so the
true counterparts are known) the misalignment of true counterparts in the common space
fell from a median of 0.42 to 0.35 mm (90th percentile 1.01 to 0.93 mm) within 12 mm of
the eyes' points and from 0.44 to 0.38 mm (1.00 to 0.92 mm) about the lips (over the
whole narrow face 0.57 to 0.55 mm, the 90th percentile 1.79 to 1.80 mm); the round trip
from 2.46 % to 2.29 % (no shape worse; the blinks 6.4 and 6.0 % to 6.1 and 5.8 %, the
lips' rolls 4.0 and 3.8 % to 3.5 and 3.3 %, mouthClose 3.4 to 2.9 %), source → target
from 6.22 % to 6.07 %. Tried and left out: a path that keeps to the fold (each edge's
length discounted by the angle between its two triangles), less stable from one head
to another and worse (0.48 mm about the eyes); the lips' outer contours as well (round
trip 2.25 %, source → target 6.10 %); the lids' outer contours through 3.13 and 3.9
(2.80 % and 7.13 %); arc length in the alignment space instead of along the mesh
(2.28 % and 6.12 %, without the mouth's corners).

A contour that is not found on both heads (a feature point missing or off the skin, a
path much longer than its feature points are apart) is left out on both, so the
alignment stays the same from either side.
"""

from __future__ import annotations

import numpy as np

from mpeg4.head import Head
from mpeg4.surface import contour_path, edge_graph

__all__ = ["CONTOURS", "edge_graph", "contour_path", "contour_pairs"]

#: The contours, each the chain of feature points it passes through, in order.
CONTOURS = (
    ("3.11", "3.1", "3.7"),  # left upper lid margin
    ("3.11", "3.3", "3.7"),  # left lower lid margin
    ("3.12", "3.2", "3.8"),  # right upper lid margin
    ("3.12", "3.4", "3.8"),  # right lower lid margin
    ("2.4", "2.6", "2.2", "2.7", "2.5"),  # upper lip's inner contour
    ("2.4", "2.8", "2.3", "2.9", "2.5"),  # lower lip's inner contour
    ("8.3", "2.4"),  # left mouth corner, outer to inner
    ("8.4", "2.5"),  # right mouth corner, outer to inner
)

def _arc(points: np.ndarray) -> np.ndarray:
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    return s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(s))


def contour_pairs(source: Head, target: Head, source_space: np.ndarray, target_space: np.ndarray
                  ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The contours' vertices of both skins and their half-way places in the alignment
    space.

    Each vertex between two feature points of a contour sits at a fraction of the
    path's length (along the mesh, in metres); its counterpart is the point at the same
    fraction on the other head's path (linear along its edges, in the alignment space);
    its place, half-way between the two.

    Returns
    -------
    (source_vertices, source_places), (target_vertices, target_places)
        (K,) int64 and (K, 2) float64 (angle, height) for each head.
    """
    graphs = [edge_graph(h.skin.vertices, h.skin.triangles) for h in (source, target)]
    out = [([], []), ([], [])]
    for chain in CONTOURS:
        paths = [contour_path(h, chain, g) for h, g in zip((source, target), graphs)]
        if paths[0] is None or paths[1] is None:
            continue
        for pa, pb in zip(*paths):
            for k, (mine, other, hm, ho, sm, so) in enumerate(((pa, pb, source, target, source_space, target_space),
                                                               (pb, pa, target, source, target_space, source_space))):
                inner = mine[1:-1]
                if not len(inner):
                    continue
                u = _arc(hm.skin.vertices[mine])[1:-1]
                w = _arc(ho.skin.vertices[other])
                there = np.c_[np.interp(u, w, so[other, 0]), np.interp(u, w, so[other, 1])]
                out[k][0].append(inner)
                out[k][1].append(0.5 * (sm[inner, :2] + there))
    result = []
    for head, (v, p) in zip((source, target), out):
        v = np.concatenate(v) if v else np.zeros(0, np.int64)
        p = np.concatenate(p) if p else np.zeros((0, 2))
        # A vertex two contours share (where the lids' paths meet near a corner) would be
        # held at two places; feature points' vertices are held by the points.
        fps = {k for b in head.feature_points.values() if b.part == "skin" for k in b.vertices}
        once = np.bincount(v, minlength=head.skin.n_vertices)[v] == 1
        keep = once & ~np.isin(v, list(fps))
        result.append((v[keep], p[keep]))
    return result[0], result[1]
