"""2D triangle-mesh interpolation of the source's motion at the target's points.

Each target point, placed in the source's alignment space, takes the motion of a source
triangle by its barycentric weights [1]_:

- where several projected triangles hold it (the surfaces inside the mouth, the lids
  over the eye sockets, the ears over the head) the one nearest in depth wins;
- a triangle the point lies outside has its excess of negative barycentric weight
  clamped away and the rest renormalised, and competes by the distance from the point
  to that place on it. Measured in metres (the angle times the radius, the height times
  the face's height, the depth) this makes one rule of Pandžić's three: inside a
  triangle the distance is the depth difference; outside every triangle the nearest
  wins; and a point just off its own surface (a lid's edge over the socket behind it)
  takes that surface's motion rather than the layer it happens to lie over;
- each corner's value may be carried half-way to the point along the corner's gradient
  (:func:`gradient_operator`): exact for quadratic motion, where the barycentric blend
  alone flattens the motion's curvature (and cloning there and back flattens it twice);
- anti-aliasing, on request: a point may average the motion over samples in a disc about
  it (Epanechnikov weights, radius ``support`` in the alignment space, one per point).
  Cloning asks for none by default: a sparse target's own linear interpolation between
  its vertices is the low-pass, and the averaging only blurs (see
  :func:`fmc.clone.correspond`).

Points are located through a uniform grid over the triangles' bounding boxes
(:class:`TriangleIndex`); a point its own cell does not settle tries the triangles round
its nearest source vertices. Every step is vectorised over all points. The result is a
sparse (target points × source vertices) matrix, computed once and applied to every
motion.

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

__all__ = ["TriangleIndex", "disc_samples", "gradient_operator", "interpolation_matrix"]

# A point counts as inside a triangle when no barycentric weight is below -_EPS.
_EPS = 1e-9


class TriangleIndex:
    """Uniform-grid spatial index of 2D triangles.

    Parameters
    ----------
    vertices : (V, 2) float
    triangles : (T, 3) int
        Degenerate (zero-area) triangles are never returned.
    cell : float, optional
        Grid cell size; by default half the median extent of a triangle.
    """

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, cell: float | None = None):
        self.vertices = np.asarray(vertices, dtype=np.float64)[:, :2]
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        a, b, c = (self.vertices[self.triangles[:, j]] for j in range(3))
        e1, e2 = b - a, c - a
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        self.valid = np.abs(det) > 1e-14
        # (T, 2, 2) inverse of [e1 e2]: barycentric (w1, w2) = inv @ (p - a).
        safe = np.where(self.valid, det, 1.0)
        self._inv = np.stack([np.c_[e2[:, 1], -e2[:, 0]], np.c_[-e1[:, 1], e1[:, 0]]], axis=1) / safe[:, None, None]
        self._origin = a
        lo, hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
        ids = np.flatnonzero(self.valid)
        if cell is None:
            ext = (hi - lo)[ids].max(axis=1) if len(ids) else np.ones(1)
            cell = 0.5 * float(np.median(ext)) if len(ext) else 1.0
        self.cell = max(cell, 1e-12)
        self.lo = lo[ids].min(axis=0) if len(ids) else np.zeros(2)
        i0 = np.floor((lo[ids] - self.lo) / self.cell).astype(np.int64)
        i1 = np.floor((hi[ids] - self.lo) / self.cell).astype(np.int64)
        self.shape = (i1.max(axis=0) + 1) if len(ids) else np.ones(2, dtype=np.int64)
        w = i1[:, 0] - i0[:, 0] + 1
        counts = w * (i1[:, 1] - i0[:, 1] + 1)
        owner = np.repeat(np.arange(len(ids)), counts)
        k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        cx = i0[owner, 0] + k % w[owner]
        cy = i0[owner, 1] + k // w[owner]
        cells = cy * self.shape[0] + cx
        order = np.argsort(cells, kind="stable")
        self._tris = ids[owner[order]]
        self._start = np.searchsorted(cells[order], np.arange(self.shape[0] * self.shape[1] + 1))

    def candidates(self, points: np.ndarray, reach: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(point, triangle) index pairs: every triangle whose box meets the point's cell
        or, with ``reach`` k, the cells up to k away (a triangle may come twice)."""
        g = np.floor((np.asarray(points)[:, :2] - self.lo) / self.cell).astype(np.int64)
        pts, tris = [], []
        for dx in range(-reach, reach + 1):
            for dy in range(-reach, reach + 1):
                c = g + (dx, dy)
                ok = (c >= 0).all(axis=1) & (c < self.shape).all(axis=1)
                cell = np.where(ok, c[:, 1] * self.shape[0] + c[:, 0], 0)
                counts = np.where(ok, self._start[cell + 1] - self._start[cell], 0)
                point = np.repeat(np.arange(len(points)), counts)
                k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
                pts.append(point)
                tris.append(self._tris[self._start[cell[point]] + k])
        return np.concatenate(pts), np.concatenate(tris)

    def border_distance(self, points: np.ndarray, reach: int, x_scale: np.ndarray, y_scale: float) -> np.ndarray:
        """(N,) distance from each point to the border of the block of cells up to
        ``reach`` from its own, with the axes scaled by ``x_scale`` (N,) and ``y_scale``."""
        p = (np.asarray(points)[:, :2] - self.lo) / self.cell
        g = np.floor(p)
        near = np.minimum(p - (g - reach), (g + reach + 1) - p) * self.cell
        return np.minimum(near[:, 0] * x_scale, near[:, 1] * y_scale)

    def barycentric(self, points: np.ndarray, tris: np.ndarray) -> np.ndarray:
        """(N, 3) barycentric weights of ``points`` (N, 2) in triangles ``tris`` (N,)."""
        w12 = np.einsum("nij,nj->ni", self._inv[tris], np.asarray(points)[:, :2] - self._origin[tris])
        return np.c_[1.0 - w12.sum(axis=1), w12]

    def locate(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For a triangulation without overlaps: (N,) the triangle holding each point (−1
        for none) and (N, 3) its barycentric weights."""
        point, tris = self.candidates(points)
        bary = self.barycentric(points[point], tris)
        hit = bary.min(axis=1) >= -_EPS
        tri_of = np.full(len(points), -1, dtype=np.int64)
        weights = np.zeros((len(points), 3))
        tri_of[point[hit]] = tris[hit]
        weights[point[hit]] = bary[hit]
        return tri_of, weights


def disc_samples(support: float, n: int = 16) -> np.ndarray:
    """(n, 2) offsets filling a disc of radius ``support`` evenly: a sunflower pattern of
    n/2 points and their mirror images through the centre, so that equal weights average
    the disc's area and leave a linear field unchanged.

    Examples
    --------
    >>> d = disc_samples(0.02)
    >>> d.shape, bool(np.linalg.norm(d, axis=1).max() <= 0.02), bool(np.allclose(d.mean(axis=0), 0))
    ((16, 2), True, True)
    """
    half = max(n // 2, 1)
    k = np.arange(half) + 0.5
    r = support * np.sqrt(k / half)
    a = k * np.pi * (3 - np.sqrt(5))
    p = np.c_[r * np.cos(a), r * np.sin(a)]
    return np.r_[p, -p]


def gradient_operator(space: np.ndarray, triangles: np.ndarray, height: float, apart: np.ndarray | None = None,
                      regularisation: float = 1.0) -> tuple[sparse.csr_matrix, sparse.csr_matrix]:
    """Sparse (V, V) operators giving a vertex field's gradient in the alignment space
    (per unit of angle and of height) at each vertex, by least squares over its mesh
    neighbours.

    Parameters
    ----------
    space : (V, 3) float
        Vertices in the alignment space (angle, height, radius).
    triangles : (T, 3) int
        The mesh; its edges are the neighbourhoods.
    height : float
        Metres per unit of height (with the radius, it makes the regularisation isotropic
        in metres).
    apart : (V,) float, optional
        Classes (the lips: +1, −1, 0) whose members of opposite sign are not each other's
        neighbours, so the gradient of one lip never reads the other's values.
    regularisation : float
        Ridge term, as a fraction of the mean squared edge length round the vertex: where
        the neighbours crowd along a line (a silhouette of the projection) the gradient
        across it goes to zero instead of growing without bound. It shrinks every
        gradient a little too (by about a quarter on a regular mesh at 1); on ICT FaceKit
        identities cloning was the most accurate about there (0.3 and 3 were worse).

    Returns
    -------
    gx, gy : scipy.sparse.csr_matrix
        ``gx @ u`` and ``gy @ u`` are the two components of the gradient of ``u`` (V,);
        their rows sum to zero (a constant has none); without regularisation a linear
        field's are exact.
    """
    space = np.asarray(space, dtype=np.float64)
    n = len(space)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    e = np.unique(np.sort(np.r_[t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1), axis=0)
    e = np.r_[e, e[:, ::-1]]
    if apart is not None:
        e = e[apart[e[:, 0]] * apart[e[:, 1]] >= 0]
    k, j = e[:, 0], e[:, 1]
    # In metres about vertex k: the angle times its radius, the height times the unit.
    s = np.c_[space[:, 2], np.full(n, height)]
    d = (space[j, :2] - space[k, :2]) * s[k]
    m = np.zeros((n, 2, 2))
    np.add.at(m, k, d[:, :, None] * d[:, None, :])
    count = np.bincount(k, minlength=n)
    mean_sq = np.bincount(k, weights=(d * d).sum(axis=1), minlength=n) / np.maximum(count, 1)
    m += (regularisation * mean_sq + 1e-30)[:, None, None] * np.eye(2)
    coef = np.einsum("nij,nj->ni", np.linalg.inv(m)[k], d) * s[k]  # per unit of angle and height
    out = []
    for c in range(2):
        g = sparse.csr_matrix((np.r_[coef[:, c], -coef[:, c]], (np.r_[k, k], np.r_[j, k])), shape=(n, n))
        out.append(g)
    return out[0], out[1]


def _first_per_group(group: np.ndarray, score: np.ndarray) -> np.ndarray:
    """Indices of the lowest score within each group (groups need not be sorted)."""
    order = np.argsort(score, kind="stable")
    _, first = np.unique(group[order], return_index=True)
    return order[first]


def _closest(q: np.ndarray, qd: np.ndarray, index: TriangleIndex, radius: np.ndarray, height: float,
             point: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For (point, triangle) pairs: the clamped, renormalised barycentric weights and the
    distance (metres) from the query to that place on the triangle.

    The distance has three parts: across the angle (scaled by the query's radius), along
    the height (scaled by ``height``, metres per unit) and in depth. Inside a triangle it
    is the depth difference alone, Pandžić's rule for overlapping triangles; outside, the
    excess of negative weight is clamped away and the distance to the clamped place added.
    """
    b = index.barycentric(q[point], tris)
    w = np.clip(b, 0.0, None)
    w /= w.sum(axis=1, keepdims=True)
    corners = index.triangles[tris]
    at = np.einsum("nj,njc->nc", w, index.vertices[corners])
    gap = q[point] - at
    dr = np.einsum("nj,nj->n", w, radius[corners]) - qd[point]
    cost = np.hypot(np.hypot(gap[:, 0] * qd[point], gap[:, 1] * height), dr)
    return w, cost


def interpolation_matrix(points: np.ndarray, depth: np.ndarray, src_space: np.ndarray, src_triangles: np.ndarray,
                         n_source: int, height: float, forbidden: np.ndarray | None = None, support: float = 0.0,
                         n_samples: int = 16, k_outside: int = 8, chunk: int = 40000,
                         gradients: tuple[sparse.csr_matrix, sparse.csr_matrix] | None = None) -> sparse.csr_matrix:
    """Sparse (N, n_source) weights: row i interpolates source vertex values at point i.

    Each point takes the source triangle nearest to it in a metric version of the
    alignment space (see :func:`_closest`): among the triangles that hold it, the nearest
    in depth; a triangle it lies outside competes by its distance, with the excess of
    negative barycentric weight clamped and the rest renormalised. So a point whose
    own surface has no triangle under it (it lies just off the source's lid, over the
    socket behind) takes the nearest place on that surface, not the layer behind.

    Parameters
    ----------
    points : (N, 2) float
        Target points in the source's alignment space.
    depth : (N,) float
        Their radius in the source's terms (metres).
    src_space : (V, 3) float
        Source vertices in the alignment space (angle, height, radius).
    src_triangles : (T, 3) int
        The source triangles the points may take motion from.
    n_source : int
        Number of source vertices (columns).
    height : float
        Metres per unit of the space's height on the source.
    forbidden : (V,) bool, optional
        Source vertices whose motion must not reach these points (the other lip): their
        triangles with a forbidden corner are never chosen, so a point over such a
        triangle takes the nearest place on its own side. (A mixed triangle with its
        forbidden corners' weights dropped gave the rest all the motion: on the upper lip's
        inner surface by the mouth's corner, the corner's own, half the jaw's, where the
        upper lip beside it stays: a sheet hung across the open mouth.)
    support : float or (N,) float
        Radius of the anti-aliasing disc about each point in the alignment space; 0 for
        none. The disc's samples are averaged with Epanechnikov weights (1 − r²/support²).
    n_samples : int
        Samples in the disc.
    k_outside : int
        Source vertices (nearest in the metric) whose triangles a point tries when its own
        cell does not settle it.
    chunk : int
        Points per block (bounds the memory of the candidate pairs).
    gradients : (gx, gy) of scipy.sparse.csr_matrix, optional
        The source field's gradient operators (:func:`gradient_operator`): with them each
        corner's value is carried half-way to the point along the corner's gradient,
        which is exact for a quadratic field (the plain barycentric blend is off by half
        the curvature times the spread of the corners), so that cloning there and back
        loses less of the motion's curvature. The rows still sum to one.
    """
    points = np.asarray(points, dtype=np.float64)[:, :2]
    depth = np.asarray(depth, dtype=np.float64)
    n = len(points)
    support = np.broadcast_to(np.asarray(support, dtype=np.float64), (n,))
    on, off = np.flatnonzero(support > 0), np.flatnonzero(~(support > 0))
    unit = disc_samples(1.0, n_samples)
    # Epanechnikov weights: the samples nearer the point count more.
    kernel = 1.0 - (unit ** 2).sum(axis=1)
    kernel /= kernel.sum()
    owner = np.r_[off, np.repeat(on, len(unit))]
    q_all = np.r_[points[off], (points[on, None, :] + support[on, None, None] * unit[None]).reshape(-1, 2)]
    sample_w = np.r_[np.ones(len(off)), np.tile(kernel, len(on))]
    src_triangles = np.asarray(src_triangles, dtype=np.int64).reshape(-1, 3)
    if forbidden is not None:
        src_triangles = src_triangles[~forbidden[src_triangles].any(axis=1)]
    index = TriangleIndex(src_space[:, :2], src_triangles)
    radius = src_space[:, 2]
    valid = np.flatnonzero(index.valid)
    # Beyond the own cell: the triangles round the source vertices nearest in the same
    # metric (angle times radius, height times the height unit, radius).
    used = np.unique(index.triangles[valid])
    tree = cKDTree(np.c_[src_space[used, 0] * radius[used], src_space[used, 1] * height, radius[used]]) \
        if len(valid) else None
    corner = index.triangles[valid].ravel()
    by_vertex = np.argsort(corner, kind="stable")
    first = np.searchsorted(corner[by_vertex], np.arange(len(src_space) + 1))
    tri_of = np.full(len(q_all), -1, dtype=np.int64)
    bary = np.zeros((len(q_all), 3))
    for start in range(0, len(q_all), chunk):
        q = q_all[start:start + chunk]
        qd = depth[owner[start:start + chunk]]
        best_t = np.full(len(q), -1, dtype=np.int64)
        best_w = np.zeros((len(q), 3))
        best_c = np.full(len(q), np.inf)
        todo = np.arange(len(q))
        # The own cell first: a triangle not tried there lies wholly outside the cell, so
        # a point whose best is nearer than the cell's border is done. The others try the
        # triangles round their nearest source vertices.
        for stage in ("cell", "vertices"):
            if not len(todo) or tree is None:
                break
            if stage == "vertices":
                k = min(k_outside, len(used))
                _, near = tree.query(np.c_[q[todo, 0] * qd[todo], q[todo, 1] * height, qd[todo]], k=k)
                verts = used[near.reshape(len(todo), k)]
                counts = first[verts + 1] - first[verts]
                point = np.repeat(np.repeat(todo, k), counts.ravel())
                offs = np.arange(counts.sum()) - np.repeat(np.cumsum(counts.ravel()) - counts.ravel(), counts.ravel())
                tris = valid[by_vertex[np.repeat(first[verts].ravel(), counts.ravel()) + offs] // 3]
            else:
                point, tris = index.candidates(q[todo], 0)
                point = todo[point]
            w, cost = _closest(q, qd, index, radius, height, point, tris)
            pick = _first_per_group(point, cost)
            better = cost[pick] < best_c[point[pick]]
            p = point[pick][better]
            best_t[p], best_w[p], best_c[p] = tris[pick][better], w[pick][better], cost[pick][better]
            if stage == "cell":
                todo = todo[best_c[todo] > index.border_distance(q[todo], 0, qd[todo], height)]
        tri_of[start:start + chunk] = best_t
        bary[start:start + chunk] = best_w
    hit = tri_of >= 0
    corners = index.triangles[tri_of[hit]]
    w = bary[hit]
    if forbidden is not None:
        allowed = ~forbidden[corners]
        w = np.where(allowed, w, 0.0)
        total = w.sum(axis=1, keepdims=True)
        # A point at the forbidden side of a mixed triangle: its allowed corners share it.
        even = allowed / np.maximum(allowed.sum(axis=1, keepdims=True), 1)
        w = np.where(total > 0, w / np.where(total > 0, total, 1.0), even)
    rows = np.repeat(owner[hit], 3)
    total = np.bincount(owner[hit], weights=sample_w[hit], minlength=n)
    share = sample_w[hit] / total[owner[hit]]  # the disc's samples average
    vals = (w * share[:, None]).ravel()
    out = sparse.csr_matrix((vals, (rows, corners.ravel())), shape=(n, n_source))
    if gradients is not None:
        # Each corner's value carried half-way to the point along its gradient: exact for
        # a quadratic field, where the plain barycentric blend is off by half the
        # curvature times the spread of the corners.
        off = 0.5 * (q_all[hit][:, None, :] - src_space[corners, :2]).reshape(-1, 2)
        for c, g in enumerate(gradients):
            out = out + sparse.csr_matrix((vals * off[:, c], (rows, corners.ravel())), shape=(n, n_source)) @ g
    return out.tocsr()
