"""Meshes over :data:`MAX_MARK_TRIANGLES` are marked on a decimated copy, and the result is
carried back to the file's own vertices.

Marking renders, ray-casts and fits against the whole surface, and its memory grows with
the triangles: a 3.1-million-triangle head took 4.1 GB and two minutes. A head needs far
fewer to be found in 1024-pixel renders, so :func:`decimate` clusters the vertices of each
connected piece of each part on a grid (a cell found for the budget) and keeps, per
cluster, the original vertex nearest the cluster's centroid: the decimated mesh's vertices
are vertices of the file, and every file vertex knows the one it was merged into.
:func:`carry_back` then gives the marking to the file: each part's vertex list grows to
every vertex merged into it, and each feature point is bound to the nearest place on the
file's own triangles (a cluster cell away from the decimated surface at most).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from mpeg4.head import FeaturePointBinding, Head, Part
from mpeg4.io.fdp_json import PartSource

__all__ = ["MAX_MARK_TRIANGLES", "Decimation", "decimate", "carry_back"]

#: Most triangles a mesh is marked at; larger meshes are decimated first (a head needs some
#: tens of thousands; the generic head has 48,836).
MAX_MARK_TRIANGLES = 400_000


class Decimation:
    """How a decimated head's parts relate to the file's.

    Attributes
    ----------
    keep : dict of str to (M,) int64
        Per part: the file vertex each decimated vertex is.
    merged : dict of str to (N,) int64
        Per part: the decimated vertex each file vertex was merged into.
    pieces : dict of str to (N,) int64
        Per part: the connected piece of the file's mesh each file vertex is on.
    triangles : tuple of int
        (file, decimated) triangle counts.
    """

    def __init__(self, keep, merged, pieces, triangles):
        self.keep, self.merged, self.pieces, self.triangles = keep, merged, pieces, triangles


def _pieces(n: int, t: np.ndarray) -> np.ndarray:
    """(n,) the connected piece of each vertex."""
    adj = sparse.coo_matrix((np.ones(3 * len(t), bool), (t.ravel(), np.roll(t, 1, axis=1).ravel())), shape=(n, n))
    return connected_components(adj, directed=False)[1]


def _cluster(v: np.ndarray, piece: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clusters of one part: (N,) cluster label, (C,) representative vertex."""
    key = np.c_[piece, np.floor(v / cell).astype(np.int64)]
    _, label = np.unique(key, axis=0, return_inverse=True)
    label = label.ravel()
    count = np.bincount(label)
    centroid = np.stack([np.bincount(label, weights=v[:, k]) for k in range(3)], axis=1) / count[:, None]
    d = np.linalg.norm(v - centroid[label], axis=1)
    order = np.lexsort((d, label))
    first = order[np.r_[True, label[order][1:] != label[order][:-1]]]
    return label, first  # first[c]: the vertex of cluster c nearest its centroid


def _collapse(t: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Triangles over cluster labels, degenerate and repeated ones dropped."""
    tri = label[t]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])]
    _, first = np.unique(np.sort(tri, axis=1), axis=0, return_index=True)
    return tri[np.sort(first)]


def decimate(head: Head, max_triangles: int = MAX_MARK_TRIANGLES) -> tuple[Head, Decimation]:
    """The head with at most ``max_triangles`` triangles over all parts (see the module
    docstring); pieces never merge with each other, so the parts' pieces stay as they were.

    Returns
    -------
    Head
        The decimated head (the file's parts and names, no feature points).
    Decimation
    """
    total = sum(len(p.triangles) for p in head.parts.values())
    area = sum(0.5 * np.linalg.norm(np.cross(p.vertices[p.triangles[:, 1]] - p.vertices[p.triangles[:, 0]],
                                             p.vertices[p.triangles[:, 2]] - p.vertices[p.triangles[:, 0]]),
                                    axis=1).sum() for p in head.parts.values())
    # About two triangles per cell of a surface: start there, shrink the count until it fits.
    cell = float(np.sqrt(2 * area / max_triangles)) if area > 0 else 1.0
    pieces = {name: _pieces(p.n_vertices, p.triangles) for name, p in head.parts.items()}
    while True:
        parts, keep, merged = {}, {}, {}
        for name, p in head.parts.items():
            label, rep = _cluster(p.vertices, pieces[name], cell)
            tri = _collapse(p.triangles, label)
            parts[name] = Part(name, p.vertices[rep], tri, None if p.uv is None else p.uv[rep], p.texture, p.colour,
                               p.centre)
            keep[name], merged[name] = rep, label
        n = sum(len(p.triangles) for p in parts.values())
        if n <= max_triangles:
            break
        cell *= 1.05 * np.sqrt(n / max_triangles)
    return Head(parts, metadata=dict(head.metadata)), Decimation(keep, merged, pieces, (total, n))


def _part_sources(parts: dict[str, PartSource], dec: Decimation) -> dict[str, PartSource]:
    """The decimated file's parts as the file's vertices: each of the file's pieces goes
    whole to the part most of its vertices were merged into (decimation may have cut a thin
    piece in two, and the halves may have gone to different parts)."""
    out = dict(parts)
    for source in {s.source for s in parts.values() if s.vertices is not None}:
        names = [n for n, s in parts.items() if s.source == source and s.vertices is not None]
        role = np.full(len(dec.keep[source]), len(names))  # per decimated vertex; len(names): no part
        for k, n in enumerate(names):
            role[parts[n].vertices] = k
        piece, of_vertex = dec.pieces[source], role[dec.merged[source]]
        votes = sparse.coo_matrix((np.ones(len(piece)), (piece, of_vertex)),
                                  shape=(piece.max() + 1, len(names) + 1)).toarray()
        winner = np.argmax(votes, axis=1)[piece]
        for k, n in enumerate(names):
            out[n] = PartSource(source, np.flatnonzero(winner == k), parts[n].centre)
    return out


def _closest_on(part: Part, points: np.ndarray, k: int = 24) -> list[tuple[tuple[int, ...], tuple[float, ...]]]:
    """For (P, 3) points: the nearest place on the part's triangles among those round its
    ``k`` nearest vertices, as (vertices, weights)."""
    import trimesh

    t = part.triangles
    corner = t.ravel()
    order = np.argsort(corner, kind="stable")
    start = np.searchsorted(corner[order], np.arange(part.n_vertices + 1))
    _, near = cKDTree(part.vertices).query(points, k=min(k, part.n_vertices))
    near = np.atleast_2d(near)
    out = []
    for p, verts in zip(points, near):
        tris = np.unique(np.concatenate([order[start[v]:start[v + 1]] // 3 for v in verts]))
        if not len(tris):
            out.append(None)
            continue
        corners = part.vertices[t[tris]]
        at = trimesh.triangles.closest_point(corners, np.repeat(p[None], len(tris), axis=0))
        j = int(np.argmin(np.linalg.norm(at - p, axis=1)))
        w = trimesh.triangles.points_to_barycentric(corners[j:j + 1], at[j:j + 1])[0]
        w = np.clip(w, 0, None)
        keep = w > 1e-9
        out.append((tuple(int(x) for x in t[tris[j]][keep]), tuple(float(x) for x in w[keep] / w[keep].sum())))
    return out


def carry_back(placed: Head, bindings: dict, parts: dict[str, PartSource], raw: Head, frame: np.ndarray,
               dec: Decimation, where: str) -> tuple[Head, dict, dict[str, PartSource]]:
    """The marking of the decimated mesh on the file's own mesh.

    Parameters
    ----------
    placed : Head
        The decimated mesh placed in the neutral frame, with its feature points.
    bindings : dict of str to FeaturePointBinding
        Its feature points.
    parts : dict of str to PartSource
        Its parts, in the decimated file's vertices.
    raw : Head
        The file's mesh as read.
    frame : (4, 4) float
        From the file's coordinates to the neutral frame.
    dec : Decimation
    where : str

    Returns
    -------
    head : Head
        The file's mesh placed, its feature points bound to its own triangles.
    bindings : dict of str to FeaturePointBinding
    parts : dict of str to PartSource
        In the file's vertices.
    """
    from mpeg4.io.fdp_json import place_mesh

    full_parts = _part_sources(parts, dec)
    head = place_mesh(raw, frame, full_parts, where)

    def to_full(name: str, j: int) -> int | None:
        """A placed decimated part's vertex as the placed file part's vertex."""
        s_dec, s_full = parts.get(name), full_parts.get(name)
        if s_dec is None:
            return None
        fid = int(dec.keep[s_dec.source][j if s_dec.vertices is None else s_dec.vertices[j]])
        return fid if s_full.vertices is None else int(np.searchsorted(s_full.vertices, fid))

    out = {}
    surface: dict[str, list[str]] = {}
    for i, b in bindings.items():
        mapped = [to_full(b.part, j) for j in b.vertices]
        if len(b.vertices) == 4 and None not in mapped:
            # A point inside a part (four vertices around it): the same vertices of the file,
            # which are where the decimated ones were, give the same point.
            out[i] = FeaturePointBinding(b.part, tuple(mapped), b.weights)
        else:
            surface.setdefault(b.part, []).append(i)
    for name, ids in surface.items():
        if name not in head.parts or not len(head.parts[name].triangles):
            continue
        points = np.array([placed.fp_position(i) for i in ids])
        for i, f in zip(ids, _closest_on(head.parts[name], points)):
            if f is not None:
                out[i] = FeaturePointBinding(name, *f)
    head.feature_points = out
    return head, out, full_parts
