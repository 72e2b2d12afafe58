"""The generic head's skin fitted to another head's surface: points no render shows.

An untextured head shows no eyebrows, hairline or ear detail to a photo detector, but its
shape still says where they are, relative to the points a detector does find (eyes, nose,
mouth). :func:`fit_generic` moves the generic head's skin onto a head mesh: first the
similarity [1]_ that takes the generic head's feature points to the found ones, then a
smooth thin-plate-spline displacement field [2]_ that puts them on the found points and the
skin on the surface, refined by rounds of non-rigid closest-point matching [3]_ from coarse
to fine (800 generic vertices spread over the skin, each pulled to the tangent plane at the
nearest surface vertex facing the same way; far matches and a stiff field first). The generic head's feature points, carried by the fit, are then where the
mesh's are.

References
----------
.. [1] S. Umeyama, "Least-squares estimation of transformation parameters between two
   point patterns", IEEE TPAMI 13(4) (1991).
.. [2] F. L. Bookstein, "Principal warps: thin-plate splines and the decomposition of
   deformations", IEEE TPAMI 11(6) (1989).
.. [3] B. Amberg, S. Romdhani, T. Vetter, "Optimal step nonrigid ICP algorithms for
   surface registration", CVPR (2007).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head

from .deform import fit_similarity

__all__ = ["GenericFit", "fit_generic"]

_SAMPLES = 800  # generic skin vertices matched to the surface each round
# Coarse to fine: far matches and a stiff field first (the skull may be centimetres off
# after the similarity), near matches and a supple field last.
_REACH = (0.04, 0.03, 0.02, 0.012, 0.008, 0.006, 0.005, 0.004)  # metres: farthest match accepted
_STIFF = (3e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 4e-5, 2e-5)  # TPS smoothing of the matches
_ROUNDS = len(_REACH)
_STEP = 0.002  # metres along the surface for the normals of the matched vertices


@dataclass
class GenericFit:
    """The generic head's skin fitted to a surface.

    Attributes
    ----------
    vertices : (V, 3) float64
        The generic skin's vertices on the surface, metres (the target's frame).
    points : dict of str to (3,) float64
        The generic head's skin feature points carried by the fit.
    anchors : list of str
        The found points the fit followed (outliers left out).
    gap : float
        Median distance of the matched generic vertices from the surface in the last
        round of matching, metres.
    move : callable
        ``move(points) -> points``: (K, 3) points of the generic head's frame carried by
        the fit (the similarity and the displacement field), such as points inside it.
    """

    vertices: np.ndarray
    points: dict
    anchors: list
    gap: float
    move: Callable[[np.ndarray], np.ndarray]


def _vertex_normals(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    n = np.zeros_like(v)
    fn = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    for k in range(3):
        np.add.at(n, t[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)


def _spread(points: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    """Indices of about ``n`` of the points spread evenly (one per voxel)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    cell = float(np.cbrt(np.prod(hi - lo + 1e-9) / n)) * 0.6
    keys = np.floor((points - lo) / cell).astype(np.int64)
    order = np.random.default_rng(seed).permutation(len(points))
    _, first = np.unique(keys[order], axis=0, return_index=True)
    return np.sort(order[first])


def fit_generic(vertices, triangles, found: Mapping[str, np.ndarray], weights: Mapping[str, float] | None = None,
                generic: Head | None = None, outlier: float = 0.012, give: float = 1e-6) -> GenericFit:
    """The generic head's skin moved onto a surface, following the points found on it.

    Parameters
    ----------
    vertices : (N, 3) float array
        The target surface's vertices (its skin), metres, in the neutral frame.
    triangles : (T, 3) int array
    found : mapping of str to (3,) array
        FP id → found position on the surface (points a detector sees well), metres.
    weights : mapping of str to float, optional
        Their confidences (1 when None).
    generic : Head, optional
        The shipped generic head by default.
    outlier : float
        Metres: a found point this far from where the similarity and then the fit put the
        generic head's is left out of the fit.
    give : float
        Smoothing of the displacement field at a found point of confidence 1 (scipy's
        ``RBFInterpolator`` smoothing, divided by each point's confidence): near 0 the fit
        goes through the found points; larger values let the generic head's shape and the
        surface overrule a noisy detector.

    Returns
    -------
    GenericFit

    Raises
    ------
    InputError
        Fewer than 6 found points the generic head's skin carries.
    """
    from scipy.interpolate import RBFInterpolator
    from scipy.spatial import cKDTree

    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    skin = generic.parts["skin"]
    rest = skin.vertices.astype(np.float64)
    b = generic.feature_points
    ids = [i for i in found if i in b and b[i].part == "skin" and (weights is None or weights.get(i, 1.0) > 0)]
    if len(ids) < 6:
        raise InputError(f"only {len(ids)} found feature points to fit the generic head to",
                         fix="check the mesh is a head facing the viewer")

    def at(verts, i):
        return np.asarray(b[i].weights) @ verts[list(b[i].vertices)]

    src = np.array([at(rest, i) for i in ids])
    dst = np.array([found[i] for i in ids], dtype=np.float64)
    w = np.array([1.0 if weights is None else max(float(weights[i]), 1e-3) for i in ids])
    keep = np.ones(len(ids), bool)
    # The similarity, twice: the second without the points the first leaves far off.
    for _ in range(2):
        sim = fit_similarity(src[keep], dst[keep], w[keep])
        off = np.linalg.norm(sim(src) - dst, axis=1)
        keep = off < max(outlier, 3 * np.median(off))
    base = sim(rest)
    tv = np.asarray(vertices, dtype=np.float64)
    tt = np.asarray(triangles, dtype=np.int64)
    tn = _vertex_normals(tv, tt)
    tree = cKDTree(tv)
    sample = _spread(rest, _SAMPLES)
    # Each round moves only the matched vertices and two points beside each along the
    # surface (their normals by finite differences): the whole skin moves once, at the end.
    n0 = _vertex_normals(rest, skin.triangles)[sample]
    t1 = np.cross(n0, np.where(np.abs(n0[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n0, t1)
    probe = np.concatenate([rest[sample], rest[sample] + _STEP * t1, rest[sample] + _STEP * t2, src])
    moved = sim(probe)
    m = len(sample)
    anchor_d = dst - sim(src)
    gap = np.inf
    field = None
    for k in range(_ROUNDS):
        q, a, c = moved[:m], moved[m:2 * m], moved[2 * m:3 * m]
        cur_n = np.cross(a - q, c - q)
        cur_n /= np.maximum(np.linalg.norm(cur_n, axis=1, keepdims=True), 1e-20)
        dist, j = tree.query(q)
        n = tn[j]
        # The tangent plane at the nearest vertex: the match may slide along the surface.
        target = q + np.sum((tv[j] - q) * n, axis=1, keepdims=True) * n
        ok = (dist < _REACH[k]) & (np.sum(cur_n * n, axis=1) > 0.6)
        if ok.sum() < 20:
            break
        gap = float(np.median(np.linalg.norm(target[ok] - q[ok], axis=1)))
        ctrl = np.r_[src[keep], rest[sample[ok]]]
        disp = np.r_[anchor_d[keep], target[ok] - sim(rest[sample[ok]])]
        smooth = np.r_[max(give, 1e-6) / w[keep], np.full(ok.sum(), _STIFF[k])]
        field = RBFInterpolator(ctrl, disp, kernel="thin_plate_spline", smoothing=smooth)
        moved = sim(probe) + field(probe)
        off = np.linalg.norm(moved[3 * m:] - dst, axis=1)
        keep = off < max(outlier, 3 * np.median(off))
    current = base if field is None else base + field(rest)
    points = {i: at(current, i) for i in b if b[i].part == "skin"}

    def move(p):
        p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
        return sim(p) + (0.0 if field is None else field(p))

    return GenericFit(current, points, [i for i, k in zip(ids, keep) if k], gap, move)
