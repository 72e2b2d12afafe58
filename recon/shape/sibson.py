"""Exact Sibson natural-neighbour coordinates in 3D.

The Sibson coordinate of a control point ``p_i`` at a query point ``x`` is the fraction of
the Voronoi cell that ``x`` would have, were it inserted among the control points, that it
steals from the cell of ``p_i`` [1]_. The coordinates are non-negative, sum to one,
reproduce linear functions exactly, interpolate at the control points and are continuous
(C1 away from the control points), which is what makes them the weights of the Dirichlet
free-form deformation [3]_.

They are computed here exactly with Watson's formulation [2]_: the tetrahedra of the
Delaunay tetrahedralisation whose circumspheres contain ``x`` (the *cavity* of ``x``) are
the only ones that change when ``x`` is inserted, and the volume ``x`` steals from
``p_i`` is the sum, over the cavity tetrahedra ``T`` incident to ``p_i``, of the signed
volume of the tetrahedron spanned by the circumcentre of ``T`` and the circumcentres of
the three tetrahedra that ``x`` forms with the faces of ``T`` incident to ``p_i``. Every
step is vectorised over (query, cavity tetrahedron) pairs.

References
----------
.. [1] R. Sibson, "A vector identity for the Dirichlet tessellation", Mathematical
   Proceedings of the Cambridge Philosophical Society 87 (1980) 151-155.
.. [2] D. F. Watson, "Contouring: A Guide to the Analysis and Display of Spatial Data",
   Pergamon (1992), chapter on natural-neighbour interpolation.
.. [3] L. Moccozet and N. Magnenat-Thalmann, "Dirichlet free-form deformations and their
   application to hand simulation", Computer Animation (1997).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp
from scipy.spatial import Delaunay, QhullError

from mpeg4.errors import InputError

__all__ = ["NaturalNeighbours", "sibson_coordinates"]

# Watson's circumcentres blow up when x lies on the plane of a cavity face (the two
# tetrahedra sharing that face then cancel). Such queries, and any query whose result fails
# the linear-precision self-check, are evaluated as the mean of two points nudged by these
# fractions of the control set's size in opposite directions (see ``_chunk``).
_PLANE_TOL = 1e-10
_NUDGES = (1e-6, 1e-4, 1e-3)
# Largest accepted |W @ controls - x| relative to the control set's size.
_CHECK_TOL = 1e-9


class NaturalNeighbours:
    """Delaunay tetrahedralisation of a control set, ready to give Sibson coordinates.

    Parameters
    ----------
    controls : (C, 3) float array
        Control points (metres, or any unit). No two may coincide and they must span 3D.
    names : sequence of str, optional
        Names of the control points for error messages (e.g. feature point ids).

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> w = NaturalNeighbours(cube).coordinates([[0.5, 0.5, 0.5]]).toarray()
    >>> np.allclose(w, 1 / 8)
    True
    """

    def __init__(self, controls, names=None):
        controls = np.asarray(controls, dtype=np.float64)
        if controls.ndim != 2 or controls.shape[1] != 3 or len(controls) < 4:
            raise InputError(f"control points have shape {controls.shape}, expected (C >= 4, 3)")
        if not np.isfinite(controls).all():
            raise InputError("control points contain NaN or infinity")
        self.names = [str(i) for i in range(len(controls))] if names is None else list(names)
        self.scale = float(np.ptp(controls, axis=0).max())
        # Duplicates: Qhull would silently drop one of them and its coordinate would be lost.
        from scipy.spatial import cKDTree

        self._tree = cKDTree(controls - controls.mean(axis=0))
        pairs = self._tree.query_pairs(1e-9 * max(self.scale, 1e-300))
        if pairs:
            a, b = sorted(next(iter(pairs)))
            raise InputError(f"control points {self.names[a]} and {self.names[b]} coincide",
                             fix="move one of them or leave it out of the control set")
        self.controls = controls
        self.origin = controls.mean(axis=0)
        local = controls - self.origin
        try:
            self.delaunay = Delaunay(local, qhull_options="Qbb Qc Qz Q12")
        except QhullError as e:
            raise InputError("the control points do not span three dimensions (they are coplanar or collinear)",
                             fix="add control points off that plane, e.g. the bounding points around the head") from e
        simplices = self.delaunay.simplices.astype(np.int64)
        if len(np.unique(simplices)) != len(controls):
            raise InputError("a control point is not a vertex of the tetrahedralisation", fix="remove duplicated points")
        # Positive orientation for every tetrahedron, so Watson's volumes have one sign.
        p = local[simplices]
        det = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
        flip = det < 0
        simplices[flip] = simplices[flip][:, [1, 0, 2, 3]]
        keep = np.abs(det) > 1e-18 * self.scale ** 3
        self.simplices = simplices[keep]
        p = local[self.simplices]
        self.centres, self.radii2 = _circumspheres(p)
        slack = 1e-6 * (self.radii2 + self.scale ** 2)
        self._sphere_rows = np.vstack([-2.0 * self.centres.T,
                                       (self.centres ** 2).sum(axis=1) - self.radii2 - slack])

    def coordinates(self, queries, chunk: int = 2048) -> sp.csr_matrix:
        """Sibson coordinates of query points.

        Parameters
        ----------
        queries : (V, 3) float array
            Points inside the convex hull of the controls, same unit as the controls.
        chunk : int
            Queries handled at a time (bounds the memory of the cavity search).

        Returns
        -------
        (V, C) scipy.sparse.csr_matrix
            Row v holds the coordinates of query v: non-negative, summing to 1; a query on
            a control point gets exactly 1 there.
        """
        queries = np.asarray(queries, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(queries).all():
            raise InputError("query points contain NaN or infinity")
        local = queries - self.origin
        outside = self.delaunay.find_simplex(local) < 0
        if outside.any():
            i = int(np.flatnonzero(outside)[0])
            raise InputError(f"{int(outside.sum())} of {len(queries)} points lie outside the convex hull of the "
                             f"control points (the first is point {i} at {np.round(queries[i], 6).tolist()})",
                             fix="surround the mesh with bounding control points")
        rows, cols, vals = [], [], []
        starts = range(0, len(local), chunk)
        # Chunks are independent and numpy releases the GIL in the heavy loops: use the cores.
        workers = min(len(starts), os.cpu_count() or 1)
        with ThreadPoolExecutor(max_workers=max(workers, 1)) as pool:
            results = pool.map(lambda s0: self._chunk(local[s0:s0 + chunk]), starts)
            for start, (r, c, v) in zip(starts, results):
                rows.append(r + start)
                cols.append(c)
                vals.append(v)
        m = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(len(queries), len(self.controls))).tocsr()
        m.sum_duplicates()
        return m

    def _chunk(self, x: np.ndarray):
        rows, cols, vals, bad = self._raw(x)
        controls = self.controls - self.origin
        # Self-check: linear precision must hold to round-off; where it does not (x on or
        # very near the planes of two Delaunay faces, where Watson's terms cancel), use the
        # mean of the coordinates at x +- d n. That mean reproduces x exactly (linear
        # precision) and differs from the coordinates at x by O(d^2) (they are C1 there).
        residual = _weighted_rows(rows, vals, controls[cols], len(x))
        bad |= np.linalg.norm(residual - x, axis=1) > _CHECK_TOL * self.scale
        redo = np.flatnonzero(bad)
        if len(redo) == 0:
            return rows, cols, vals
        keep = ~np.isin(rows, redo)
        rows, cols, vals = rows[keep], cols[keep], vals[keep]
        rng = np.random.default_rng(12345)
        todo = redo
        for step in _NUDGES:
            n = rng.standard_normal((len(todo), 3))
            n *= step * self.scale / np.linalg.norm(n, axis=1, keepdims=True)
            parts = [self._raw(x[todo] + n), self._raw(x[todo] - n)]
            ok = np.ones(len(todo), bool)
            for (r, c, v, b), sign in zip(parts, (1, -1)):
                res = _weighted_rows(r, v, controls[c], len(todo))
                ok &= ~b & (np.linalg.norm(res - (x[todo] + sign * n), axis=1) <= _CHECK_TOL * self.scale)
            for r, c, v, _ in parts:
                sel = ok[r]
                rows = np.concatenate([rows, todo[r[sel]]])
                cols = np.concatenate([cols, c[sel]])
                vals = np.concatenate([vals, 0.5 * v[sel]])
            todo = todo[~ok]
            if len(todo) == 0:
                return rows, cols, vals
        raise InputError(f"Sibson coordinates could not be computed stably at {np.round(x[todo[0]] + self.origin, 6).tolist()}",
                         fix="the control points are nearly degenerate there; move a control point slightly")

    def _raw(self, x: np.ndarray):
        """Watson's sums for queries ``x`` (local frame): COO triplets and a per-query flag
        for queries too close to a face plane to trust."""
        # Cavity search: a cheap matrix-product test with a generous margin, then the exact
        # distance on the candidates only.
        # |x - c|^2 < r^2 + slack  <=>  [x, 1] . [-2c, |c|^2 - r^2 - slack] < -|x|^2
        c = self.centres
        qi, ti = np.nonzero(np.c_[x, np.ones(len(x))] @ self._sphere_rows < -np.einsum("ij,ij->i", x, x)[:, None])
        exact = ((x[qi] - c[ti]) ** 2).sum(1)
        inside = exact < self.radii2[ti] * (1 + 1e-12) + (1e-12 * self.scale) ** 2
        qi, ti = qi[inside], ti[inside]
        # Queries on a control point: the coordinate is the unit vector.
        dist, nearest = self._tree.query(x)
        on_ctrl = dist <= 1e-10 * self.scale
        w, bad_pair = _watson(x, qi, self.simplices[ti], self.centres[ti], self.controls - self.origin, self.scale)
        bad = np.zeros(len(x), bool)
        bad[qi[bad_pair]] = True
        bad &= ~on_ctrl
        rows = np.repeat(qi, 4)
        cols = self.simplices[ti].reshape(-1)
        vals = w.reshape(-1)
        keep = ~on_ctrl[rows] & ~bad[rows]
        rows, cols, vals = rows[keep], cols[keep], vals[keep]
        total = np.bincount(rows, weights=vals, minlength=len(x))
        with np.errstate(divide="ignore", invalid="ignore"):
            vals = vals / total[rows]
        ctrl_rows = np.flatnonzero(on_ctrl)
        rows = np.concatenate([rows, ctrl_rows])
        cols = np.concatenate([cols, nearest[ctrl_rows]])
        vals = np.concatenate([vals, np.ones(len(ctrl_rows))])
        # Sum each control's contributions over the cavity; round-off around exact zeros
        # (cancelling contributions) is not a coordinate, a clearly negative sum is a failure.
        key, inverse = np.unique(rows * len(self.controls) + cols, return_inverse=True)
        vals = np.bincount(inverse, weights=vals, minlength=len(key))
        rows, cols = key // len(self.controls), key % len(self.controls)
        vals = np.where(np.abs(vals) < 1e-13, 0.0, vals)
        bad[rows[vals < 0]] = True
        return rows, cols, vals, bad


def _weighted_rows(rows, weights, vectors, n) -> np.ndarray:
    """(n, 3): for each row r, the sum of weights * vectors over the entries in row r."""
    return np.stack([np.bincount(rows, weights=weights * vectors[:, k], minlength=n) for k in range(3)], axis=1)


def _circumspheres(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circumcentres (T, 3) and squared radii (T,) of tetrahedra ``p`` (T, 4, 3)."""
    a = p[:, 1:] - p[:, :1]
    rhs = 0.5 * (a ** 2).sum(axis=2)
    c = np.linalg.solve(a, rhs[..., None])[..., 0]
    return c + p[:, 0], (c ** 2).sum(axis=1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of (3, K) component-major vectors."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


# Faces of a tetrahedron named by the vertex they omit, and for vertex i its three other
# vertices in an order that makes (i, j, k, l) an even permutation of (0, 1, 2, 3).
_FACES = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
_EVEN = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))


def _watson(x, qi, tets, centres, controls, scale):
    """Stolen volumes (K, 4) for each (query, cavity tetrahedron) pair and its 4 vertices.

    ``g[m]`` is the circumcentre of the tetrahedron that x forms with the face opposite
    vertex m; the volume x steals from vertex i through this tetrahedron is the signed
    volume of (c, g[j], g[k], g[l]) with c the tetrahedron's circumcentre. All vectors are
    taken relative to x (component-major, shape (3, K)) for accuracy and speed.
    """
    xq = x[qi]
    r = [(controls[tets[:, j]] - xq).T for j in range(4)]  # vertex j relative to x
    n = [np.einsum("ij,ij->j", v, v) for v in r]
    pair = {}
    for i in range(4):
        for j in range(i + 1, 4):
            pair[i, j] = _cross(r[i], r[j])

    def cross_of(i, j):
        return pair[i, j] if i < j else -pair[j, i]

    g, bad = [], np.zeros(len(qi), bool)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for a, b, c in _FACES:
            bc, ca, ab = cross_of(b, c), cross_of(c, a), cross_of(a, b)
            den = 2.0 * np.einsum("ij,ij->j", r[a], bc)
            # |den| / (2 |a||b||c|) measures how flat (x, face) is, whatever the scale.
            bad |= np.abs(den) <= _PLANE_TOL * 2.0 * np.sqrt(n[a] * n[b] * n[c])
            g.append((n[a] * bc + n[b] * ca + n[c] * ab) / den)
        cc = (centres - xq).T
        w = np.empty((len(qi), 4))
        for i, (j, k, l) in enumerate(_EVEN):
            u, v, t = g[j] - cc, g[k] - cc, g[l] - cc
            w[:, i] = np.einsum("ij,ij->j", u, _cross(v, t)) / 6.0
    bad |= ~np.isfinite(w).all(axis=1)
    w[bad] = 0.0
    return w, bad


def sibson_coordinates(queries, controls, names=None) -> sp.csr_matrix:
    """Exact Sibson natural-neighbour coordinates of 3D points.

    Parameters
    ----------
    queries : (V, 3) float array
        Points inside the convex hull of ``controls``.
    controls : (C, 3) float array
        Control points; none may coincide, and they must span 3D.
    names : sequence of str, optional
        Control point names for error messages.

    Returns
    -------
    (V, C) scipy.sparse.csr_matrix
        Non-negative rows summing to 1; ``W @ controls == queries`` (linear precision).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> c = rng.random((30, 3))
    >>> q = 0.25 + 0.5 * rng.random((5, 3))
    >>> w = sibson_coordinates(q, c)
    >>> bool(np.allclose(w @ c, q)) and bool(np.allclose(w.sum(axis=1), 1))
    True
    """
    return NaturalNeighbours(controls, names).coordinates(queries)
