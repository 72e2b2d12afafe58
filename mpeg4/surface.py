"""Paths and smooth fields along a head's skin: the mesh as a graph (seam copies joined),
the shortest path through a chain of feature points, and the bi-Laplacian that smooth
fields over the surface minimise.

Shared by Facial Motion Cloning (:mod:`fmc.clone`: contours held in the alignment, the
surface warp), the muscle model (:mod:`fmc.muscles`: distances along the skin) and the
tables that leave other FAPs' points still (:mod:`fmc.separate`).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import dijkstra

from .head import Head
from .seams import seam_copies

__all__ = ["DETOUR", "edge_graph", "fp_vertex", "contour_path", "nearest_seed_labels", "bilaplacian", "smoothest_fill",
           "triangle_normals", "inverted_triangles"]

# A path longer than this many times the straight distance between its feature points
# has not found the contour.
DETOUR = 1.6


def edge_graph(vertices: np.ndarray, triangles: np.ndarray) -> sparse.csr_matrix:
    """(N, N) symmetric sparse matrix of a mesh's edge lengths, with the copies of one
    vertex joined.

    A textured head stores each vertex of a texture seam once per side of the seam, at the
    same place (:func:`mpeg4.seams.split_vertices`): the copies are joined by an edge of
    (almost) no length, so that paths and distances run across seams. A reconstructed
    head, the product's main target, has seams through its lips and lids; without the
    join a contour that crosses one was silently left out of the cloning.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = len(v)
    e = np.r_[t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]
    if n:
        first, inverse = seam_copies(v)
        copies = np.flatnonzero(first[inverse] != np.arange(n))
        e = np.r_[e, np.c_[copies, first[inverse[copies]]]]
    # The edges both ways, each once (the duplicates summed), then their lengths; a
    # zero-length edge (joined copies) would read as missing: a tiny length instead.
    both = sparse.csr_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                             shape=(n, n)).tocoo()
    length = np.maximum(np.linalg.norm(v[both.row] - v[both.col], axis=1), 1e-12)
    return sparse.csr_matrix((length, (both.row, both.col)), shape=(n, n))


def fp_vertex(head: Head, fp: str) -> int | None:
    """The skin vertex of feature point ``fp`` (its heaviest, for a point inside a triangle);
    None when the point is missing or not on the skin."""
    b = head.feature_points.get(fp)
    if b is None or b.part != "skin" or not len(b.vertices):
        return None
    return int(b.vertices[int(np.argmax(b.weights))])


def contour_path(head: Head, chain: tuple[str, ...], graph: sparse.csr_matrix | None = None
                 ) -> list[np.ndarray] | None:
    """The contour through the feature points ``chain`` on the head's skin: one (K_i,)
    vertex path per pair of consecutive points, from the first point's vertex (its
    heaviest, for a point inside a triangle) to the second's; None when a point is
    missing or not on the skin, or a path strays (longer than :data:`DETOUR` times the
    straight distance). ``graph``: the skin's :func:`edge_graph`, if already made."""
    skin = head.skin
    verts = [fp_vertex(head, fp) for fp in chain]
    if any(k is None for k in verts) or len(set(verts)) < len(verts):
        return None
    graph = edge_graph(skin.vertices, skin.triangles) if graph is None else graph
    reach = DETOUR * max(np.linalg.norm(skin.vertices[a] - skin.vertices[b]) for a, b in zip(verts[:-1], verts[1:]))
    dist, pred = dijkstra(graph, indices=verts[:-1], return_predecessors=True, limit=reach)
    out = []
    for row, (a, b) in enumerate(zip(verts[:-1], verts[1:])):
        if not np.isfinite(dist[row, b]):
            return None
        path = [b]
        while path[-1] != a:
            path.append(pred[row, path[-1]])
        path = np.array(path[::-1], dtype=np.int64)
        length = np.linalg.norm(np.diff(skin.vertices[path], axis=0), axis=1).sum()
        if length > DETOUR * np.linalg.norm(skin.vertices[a] - skin.vertices[b]):
            return None
        out.append(path)
    return out


def nearest_seed_labels(graph: sparse.csr_matrix, seeds, labels, reach: float) -> np.ndarray:
    """(N,) the label of the seed nearest each vertex along the mesh, 0 beyond ``reach``.

    Parameters
    ----------
    graph : (N, N) scipy.sparse.csr_matrix
        Edge lengths (:func:`edge_graph`).
    seeds : (k,) int
        Vertex ids; a vertex given twice keeps the label given last.
    labels : (k,) float
        One per seed.
    reach : float
        Metres along the mesh.
    """
    out = np.zeros(graph.shape[0])
    if not len(seeds):
        return out
    dist, _, source = dijkstra(graph, directed=False, indices=list(seeds), min_only=True,
                               return_predecessors=True, limit=reach)
    label_of = dict(zip((int(k) for k in seeds), labels))
    near = np.isfinite(dist)
    out[near] = [label_of[int(k)] for k in source[near]]
    return out


def bilaplacian(vertices: np.ndarray, triangles: np.ndarray) -> sparse.csr_matrix:
    """(N, N) the bi-Laplacian ``L D⁻¹ L`` of a triangle mesh.

    ``L`` is the cotangent Laplacian (an obtuse angle's negative cotangent clipped to
    zero, so that it stays an M-matrix) and ``D`` its diagonal, the sum of each vertex's
    weights: the square of the random-walk Laplacian ``D⁻¹ L``, which weighs every vertex
    alike. (With lumped areas for ``D`` instead, the finite-element bi-Laplacian, the
    cloning of ICT FaceKit identities was worse against their ground truth: 7.5 % against
    6.6 %.)
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = len(v)
    rows, cols, vals = [], [], []
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        i, j, k = t[:, a], t[:, b], t[:, c]
        u, w = v[i] - v[k], v[j] - v[k]
        cot = (u * w).sum(axis=1) / np.maximum(np.linalg.norm(np.cross(u, w), axis=1), 1e-18)
        half = 0.5 * np.clip(cot, 0.0, 1e3)
        rows += [i, j]
        cols += [j, i]
        vals += [half, half]
    w = sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    d = np.asarray(w.sum(axis=1)).ravel()
    lap = sparse.diags(d) - w
    return (lap @ sparse.diags(1.0 / np.maximum(d, 1e-12)) @ lap).tocsr()


def smoothest_fill(q: sparse.spmatrix, values: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``values`` with its ``free`` rows the smoothest the operator ``q`` allows given the
    others: the solution of ``q[free] @ x = 0`` with the other rows fixed (with ``q`` the
    :func:`bilaplacian`, the bi-harmonic fill).

    Parameters
    ----------
    q : (N, N) sparse
    values : (N,) or (N, K) float
    free : (N,) bool

    Returns
    -------
    (N,) or (N, K) float64
        A new array.

    Raises
    ------
    RuntimeError
        When some free rows have nothing fixed around them (``q[free][:, free]`` singular).
    """
    from scipy.sparse.linalg import splu

    out = np.array(values, dtype=np.float64)
    free = np.asarray(free, dtype=bool)
    if free.any():
        q = sparse.csr_matrix(q)[free]
        out[free] = splu(q[:, free].tocsc()).solve(-np.asarray(q[:, ~free] @ out[~free]))
    return out


def triangle_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T, 3) each triangle's normal, its length twice the triangle's area."""
    t = np.asarray(triangles)
    return np.cross(vertices[t[:, 1]] - vertices[t[:, 0]], vertices[t[:, 2]] - vertices[t[:, 0]])


def inverted_triangles(vertices: np.ndarray, triangles: np.ndarray, offsets: np.ndarray,
                       scales=(1.0,), rest_normals: np.ndarray | None = None) -> np.ndarray:
    """(T,) bool: triangles whose normal, moved by ``s · offsets`` (V, 3) for any ``s`` in
    ``scales``, points against its rest normal (slivers of no area are never counted).
    ``rest_normals``: :func:`triangle_normals` of ``vertices``, when the caller keeps them."""
    out = np.zeros(len(triangles), bool)
    # Only a triangle with a moving corner can turn over.
    live = np.flatnonzero((offsets != 0).any(axis=1)[triangles].any(axis=1))
    t = triangles[live]
    rest = triangle_normals(vertices, t) if rest_normals is None else rest_normals[live]
    turned = np.zeros(len(t), bool)
    for s in scales:
        turned |= (rest * triangle_normals(vertices + s * offsets, t)).sum(axis=1) < 0
    out[live] = turned & (np.linalg.norm(rest, axis=1) > 1e-12)
    return out
