"""Shape the generic head after this person's feature points.

The skin follows a Dirichlet free-form deformation (DFFD) [1]_: every vertex moves by the
Sibson-weighted mean of the control points' displacements, the control points being the
feature points plus 27 points around the head that follow the best similarity (or affine)
fit of the feature points, so that every vertex lies inside the controls' convex hull and
the far field moves smoothly. Sibson coordinates interpolate, so a vertex that *is* a
feature point lands exactly on its target; a point bound between vertices (a midpoint)
is put on its target by moving those few vertices by the small remaining residual. A thin-plate-spline RBF deformation is kept
beside it for comparison (``method="rbf"``).

Eyes, teeth, gums and tongue keep their shape: each moves by the similarity transform that
best fits the DFFD's motion of its own vertices.

References
----------
.. [1] L. Moccozet and N. Magnenat-Thalmann, "Dirichlet free-form deformations and their
   application to hand simulation", Computer Animation (1997).
.. [2] S. Umeyama, "Least-squares estimation of transformation parameters between two point
   patterns", IEEE TPAMI 13(4) (1991).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import check_fp_id
from mpeg4.errors import InputError
from mpeg4.head import Head

from .sibson import NaturalNeighbours

__all__ = ["RIGID_PARTS", "METHODS", "Similarity", "fit_similarity", "fit_affine", "bounding_controls",
           "dffd", "rbf_deform", "deform_head"]

#: Parts that move as rigid bodies (with uniform scale) instead of deforming.
RIGID_PARTS = ("eye_l", "eye_r", "teeth_upper", "teeth_lower", "gums_upper", "gums_lower", "tongue")

#: Deformation methods :func:`deform_head` knows.
METHODS = ("dffd", "rbf")


class Similarity:
    """``x → scale · R x + t``: rotation (3, 3), uniform scale, translation (3,) metres."""

    def __init__(self, rotation: np.ndarray, scale: float, translation: np.ndarray):
        self.rotation = np.asarray(rotation, dtype=np.float64)
        self.scale = float(scale)
        self.translation = np.asarray(translation, dtype=np.float64)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self.scale * np.asarray(points) @ self.rotation.T + self.translation


def fit_similarity(src, dst, weights=None) -> Similarity:
    """Least-squares similarity transform taking ``src`` to ``dst`` (Umeyama [2]_).

    Parameters
    ----------
    src, dst : (K, 3) float arrays
        Corresponding points, K >= 3 not collinear.
    weights : (K,) float array, optional
        Non-negative weights.

    Returns
    -------
    Similarity

    Examples
    --------
    >>> import numpy as np
    >>> p = np.random.default_rng(0).random((6, 3))
    >>> s = fit_similarity(p, 2 * p + 1)
    >>> round(s.scale, 9), np.allclose(s(p), 2 * p + 1)
    (2.0, True)
    """
    src, dst = np.asarray(src, dtype=np.float64), np.asarray(dst, dtype=np.float64)
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    ms, md = w @ src, w @ dst
    a, b = src - ms, dst - md
    cov = (b * w[:, None]).T @ a
    u, sig, vt = np.linalg.svd(cov)
    d = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[2] = -1.0  # a reflection is not a rotation
    r = u @ np.diag(d) @ vt
    var = w @ (a * a).sum(axis=1)
    scale = float((sig * d).sum() / var) if var > 0 else 1.0
    return Similarity(r, scale, md - scale * r @ ms)


def fit_affine(src, dst) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares affine map ``x → A x + t`` taking (K, 3) ``src`` to ``dst`` (K >= 4)."""
    src, dst = np.asarray(src, dtype=np.float64), np.asarray(dst, dtype=np.float64)
    h = np.c_[src, np.ones(len(src))]
    sol, *_ = np.linalg.lstsq(h, dst, rcond=None)
    return sol[:3].T, sol[3]


def bounding_controls(points, margin: float = 0.3) -> np.ndarray:
    """27 control points on a slightly irregular 3x3x3 lattice around ``points``.

    Parameters
    ----------
    points : (K, 3) float array
        Everything the deformation must cover (all the head's vertices), metres.
    margin : float
        Extra room on each side, as a fraction of the bounding box's size.

    Returns
    -------
    (27, 3) float64
        The lattice corners, edge midpoints, face centres and centre of the enlarged box;
        inner points are shifted by a fixed few per cent of the spacing so that no eight of
        them are cospherical (the Delaunay tetrahedralisation is then unique).
    """
    points = np.asarray(points, dtype=np.float64)
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = hi - lo
    lo, hi = lo - margin * size, hi + margin * size
    t = np.array([[i, j, k] for i in range(3) for j in range(3) for k in range(3)], float) / 2.0
    # A fixed, irrational-looking shift of the non-corner points (corners keep the box).
    shift = np.sin(np.arange(27 * 3).reshape(27, 3) * 2.399963) * 0.04
    corner = np.isin(t, (0.0, 1.0)).all(axis=1)
    t = t + np.where(corner[:, None], 0.0, shift)
    return lo + t * (hi - lo)


def dffd(vertices, controls, displaced, names=None) -> np.ndarray:
    """Dirichlet free-form deformation of vertices by moved control points.

    Parameters
    ----------
    vertices : (V, 3) float array
        Points to move, inside the convex hull of ``controls``, metres.
    controls : (C, 3) float array
        Control points at rest.
    displaced : (C, 3) float array
        Where the control points go.
    names : sequence of str, optional
        Control point names for error messages.

    Returns
    -------
    (V, 3) float64
        ``vertices + W @ (displaced - controls)`` with W the Sibson coordinates of the
        vertices among the controls; since W reproduces linear functions this equals
        ``W @ displaced``.
    """
    controls = np.asarray(controls, dtype=np.float64)
    w = NaturalNeighbours(controls, names).coordinates(vertices)
    return np.asarray(vertices, dtype=np.float64) + w @ (np.asarray(displaced, dtype=np.float64) - controls)


def rbf_deform(vertices, controls, displaced, kernel: str = "thin_plate_spline") -> np.ndarray:
    """The same deformation by radial basis functions (scipy's RBFInterpolator), for comparison."""
    from scipy.interpolate import RBFInterpolator  # here: the import costs half a second

    controls = np.asarray(controls, dtype=np.float64)
    rbf = RBFInterpolator(controls, np.asarray(displaced, dtype=np.float64) - controls, kernel=kernel)
    return np.asarray(vertices, dtype=np.float64) + rbf(np.asarray(vertices, dtype=np.float64))


def deform_head(head: Head, targets: Mapping[str, np.ndarray], method: str = "dffd",
                far_field: str = "similarity", rigid_parts=RIGID_PARTS,
                extra: tuple[np.ndarray, np.ndarray] | None = None) -> Head:
    """The generic head moved so that its feature points land on ``targets``.

    Parameters
    ----------
    head : Head
        The generic head (it must carry the feature points named in ``targets``).
    targets : mapping of str to (3,) array
        FP id → where it goes, metres, in the head's frame.
    method : {"dffd", "rbf"}
        Exact Sibson DFFD (default) or a thin-plate-spline RBF.
    far_field : {"similarity", "affine"}
        How the 27 bounding control points follow the feature points.
    rigid_parts : sequence of str
        Parts moved by a fitted similarity transform instead of deformed.
    extra : ((M, 3), (M, 3)) float arrays, optional
        More controls that are not feature points: places on the head (metres) and where
        they go (the profile's, :func:`recon.shape.outline.follow_profile`); the far field
        follows the feature points alone.

    Returns
    -------
    Head
        A new head; feature point bindings, morph targets and FATs are carried over
        (the displacements of morph targets are those of the generic head).
    """
    if method not in METHODS:
        raise InputError(f"unknown deformation method {method!r}", fix=f"use one of {', '.join(METHODS)}")
    if far_field not in ("similarity", "affine"):
        raise InputError(f"unknown far-field model {far_field!r}", fix="use 'similarity' or 'affine'")
    ids = []
    for i in targets:
        check_fp_id(i, where="target feature points")
        if i not in head.feature_points:
            raise InputError(f"the head has no feature point {i} to move", fix="leave it out of the targets")
        ids.append(i)
    if len(ids) < 4:
        raise InputError(f"only {len(ids)} target feature points; the deformation needs at least 4")
    rest = np.array([head.fp_position(i) for i in ids])
    # Points bound to the same place on the head (11.5 on 11.4 when the head has no hair)
    # cannot steer it two ways: the first one in catalogue order steers.
    from scipy.spatial import cKDTree

    dup = {j for _, j in cKDTree(rest).query_pairs(1e-6)}  # pairs (i, j) have i < j
    skipped = [ids[k] for k in sorted(dup)]
    keep = [k for k in range(len(ids)) if k not in dup]
    ids, rest = [ids[k] for k in keep], rest[keep]
    goal = np.array([np.asarray(targets[i], dtype=np.float64).reshape(3) for i in ids])
    if not np.isfinite(goal).all():
        bad = [i for i, g in zip(ids, goal) if not np.isfinite(g).all()]
        raise InputError(f"target positions of {', '.join(bad)} are not finite numbers")

    everything = np.concatenate([p.vertices for p in head.parts.values()])
    box = bounding_controls(np.vstack([everything, rest]))
    if far_field == "similarity":
        far = fit_similarity(rest, goal)(box)
    else:
        a, t = fit_affine(rest, goal)
        far = box @ a.T + t
    more_rest, more_goal = (np.zeros((0, 3)), np.zeros((0, 3))) if extra is None else (
        np.asarray(extra[0], np.float64).reshape(-1, 3), np.asarray(extra[1], np.float64).reshape(-1, 3))
    if more_rest.shape != more_goal.shape or not np.isfinite(more_goal).all():
        raise InputError("the extra controls need as many finite goals as places")
    controls = np.vstack([rest, more_rest, box])
    displaced = np.vstack([goal, more_goal, far])
    names = ids + [f"extra control {k}" for k in range(len(more_rest))] + [f"bounding point {k}" for k in range(len(box))]

    if method == "dffd":
        nn = NaturalNeighbours(controls, names)

        def move(v):
            return v + nn.coordinates(v) @ (displaced - controls)
    else:
        from scipy.interpolate import RBFInterpolator

        rbf = RBFInterpolator(controls, displaced - controls, kernel="thin_plate_spline")

        def move(v):
            return v + rbf(v)

    out = head.copy()
    for name, part in out.parts.items():
        moved = move(part.vertices)
        if name in rigid_parts:
            sim = fit_similarity(part.vertices, moved)
            part.vertices = sim(part.vertices)
            if part.centre is not None:
                part.centre = sim(part.centre[None])[0]
        else:
            part.vertices = moved
    # A point bound between vertices (a midpoint, a barycentric point) is not itself a
    # vertex, so the interpolation does not pin it; move its few vertices by the residual.
    # Vertices that are feature points themselves stay pinned.
    pinned = {(out.feature_points[i].part, out.feature_points[i].vertices[0]) for i in ids
              if len(out.feature_points[i].vertices) == 1}
    for i, g in zip(ids, goal):
        b = out.feature_points[i]
        if len(b.vertices) > 1 and b.part not in rigid_parts:
            free = [(v, w) for v, w in zip(b.vertices, b.weights) if (b.part, v) not in pinned]
            share = sum(w for _, w in free)
            if free and share > 0:
                out.parts[b.part].vertices[[v for v, _ in free]] += (g - out.fp_position(i)) / share
    out.metadata = dict(out.metadata, deformation=dict(method=method, far_field=far_field,
                                                       control_points=len(ids), extra_controls=len(more_rest),
                                                       bounding_points=len(box),
                                                       coincident_points_skipped=skipped))
    return out
