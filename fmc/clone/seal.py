"""Lips the mesh seals: the mouth ripped open along its line, so that the lips can part.

Many head meshes join the lips: one edge loop, or a strip of triangles, runs from the upper
lip to the lower (the MediaPipe face mask closes a 5 mm gap so). Cloned motion then cannot
part them: the jaw drags the joined surface into a sheet across the open mouth, and the
lower inner lip's feature points, found on a render where the lips look closed, sit on the
upper lip's line. A mouth is sealed when the skin's edges lead from the upper inner lip's
midpoint (2.2) to the lower's (2.3) about as directly as a straight line does — a mouth
that opens has only the way round its corners or through the mouth's inside.
:func:`rip_mouth` then duplicates the vertices along the upper inner contour (2.4 → 2.2 →
2.5, the lip line the points were found on) between the corners: the triangles below the
line take the copies, lowered by :data:`PARTING` (so that nothing takes them for a
texture seam's copies, which move as one), and the lower inner lip's points go onto them.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.csgraph import dijkstra

from mpeg4.head import FeaturePointBinding, Head
from mpeg4.surface import contour_path, edge_graph, fp_vertex

__all__ = ["PARTING", "sealed_mouth", "rip_mouth"]

#: Metres the lower lip's copies of the lip line sit below the upper lip's: lips apart.
PARTING = 1e-5
#: The inner lip's points on the upper lip and their partners on the lower.
_PARTNERS = (("2.2", "2.3"), ("2.6", "2.8"), ("2.7", "2.9"))


def sealed_mouth(head: Head) -> np.ndarray | None:
    """The lip line of a sealed mouth: (K,) skin vertices from the inner lip corner 2.4
    through 2.2 to 2.5; None when the mouth opens (or its points are missing)."""
    if "skin" not in head.parts:
        return None
    skin = head.skin
    a, b = fp_vertex(head, "2.2"), fp_vertex(head, "2.3")
    if a is None or b is None:
        return None
    graph = edge_graph(skin.vertices, skin.triangles)
    if a != b:
        straight = float(np.linalg.norm(skin.vertices[a] - skin.vertices[b]))
        edge = float(np.median(graph.data))
        along = dijkstra(graph, indices=a, limit=2 * straight + edge)[b]
        if not np.isfinite(along):
            return None
    paths = contour_path(head, ("2.4", "2.2", "2.5"), graph)
    if paths is None:
        return None
    return np.concatenate([paths[0], paths[1][1:]])


def _split_fan(fan: np.ndarray, centre: int, cuts: tuple[int, int]) -> list[np.ndarray] | None:
    """The two halves (indices into ``fan``) of the triangles round ``centre`` once its
    edges to ``cuts`` are cut; None unless there are two."""
    label = -np.ones(len(fan), dtype=np.int64)
    # Triangles sharing an edge from the centre to a vertex that is not cut are joined.
    spokes = [set(int(x) for x in tri if x != centre) for tri in fan]
    halves = []
    for start in range(len(fan)):
        if label[start] >= 0:
            continue
        label[start] = len(halves)
        todo, members = [start], [start]
        while todo:
            a = todo.pop()
            for b in range(len(fan)):
                if label[b] < 0 and (spokes[a] & spokes[b]) - set(cuts):
                    label[b] = label[start]
                    todo.append(b)
                    members.append(b)
        halves.append(np.array(members))
    return halves if len(halves) == 2 else None


def rip_mouth(head: Head) -> tuple[Head, int]:
    """A copy of ``head`` with a sealed mouth ripped along its lip line (:func:`sealed_mouth`).

    Returns
    -------
    head : Head
        The lip line's inner vertices duplicated (:func:`mpeg4.seams.split_vertices`: its
        tables and morph targets move the copies with their originals until cloned); the
        triangles below the line on the copies; 2.3, 2.8 and 2.9 on the copies of the line
        vertices nearest 2.2, 2.6 and 2.7.
    ripped : int
        Vertices duplicated; 0 (and the head itself) when the mouth is not sealed.
    """
    from mpeg4.seams import split_vertices

    line = sealed_mouth(head)
    if line is None or len(line) < 3:
        return head, 0
    skin = head.skin
    v, t = skin.vertices, skin.triangles
    inner = line[1:-1]
    n = len(v)
    # Around each vertex of the line, the line's two edges split its fan of triangles in
    # two; the half lying lower takes the copy, vertex n + k for inner[k] (the head in its
    # neutral frame, y up).
    tris = t.copy()
    for k, i in enumerate(inner):
        prev, nxt = int(line[k]), int(line[k + 2])
        fan = np.flatnonzero((t == i).any(axis=1))
        halves = _split_fan(t[fan], int(i), (prev, nxt))
        if halves is None:
            return head, 0
        low = min(halves, key=lambda h: v[t[fan[h]]].mean(axis=(0, 1))[1])
        rows = fan[low]
        tris[rows] = np.where(t[rows] == i, n + k, tris[rows])
    out = split_vertices(head, "skin", np.r_[np.arange(n), inner], tris)
    verts = out.parts["skin"].vertices
    verts[n:, 1] -= PARTING
    for upper, partner in _PARTNERS:
        if upper not in head.feature_points:
            continue
        k = int(np.argmin(np.linalg.norm(v[inner] - head.fp_position(upper), axis=1)))
        out.feature_points[upper] = FeaturePointBinding.at_vertex("skin", int(inner[k]))
        out.feature_points[partner] = FeaturePointBinding.at_vertex("skin", n + k)
    # The copies part: they are no texture seam's (the seams before stay listed).
    dups = dict(out.metadata.get("duplicated_vertices", {}))
    before = head.metadata.get("duplicated_vertices", {}).get("skin")
    if before is not None and len(before):
        dups["skin"] = before
    else:
        dups.pop("skin", None)
    out.metadata = dict(out.metadata, duplicated_vertices=dups, ripped_lip_line=len(inner))
    return out, len(inner)
