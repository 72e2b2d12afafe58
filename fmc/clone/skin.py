"""The skin's weights: each target skin vertex as a blend of the source skin's vertices.

Step 4 of the method (:mod:`fmc.clone`): the interpolation (:mod:`fmc.clone.interpolate`)
applied lip by lip, so that each lip takes nothing from the other (:func:`skin_weights`),
and the target's feature points pinned to the source's (:func:`pin_feature_points`).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from mpeg4.catalogue import FAPS
from mpeg4.head import Head

from .interpolate import gradient_operator, interpolation_matrix
from .parts import bound_alike, feature_point_pins

__all__ = ["OWN_POINTS", "skin_weights", "pin_feature_points", "shift_bound_points"]

#: The feature points some low-level FAP moves as its own (its first point in the catalogue).
OWN_POINTS = frozenset(f.feature_points[0] for n, f in FAPS.items() if n >= 3 and f.feature_points)

# Source triangles spanning more angle than this cross the back of the head (where the
# angle wraps) or surround the axis at the crown: in the plane they would cover the face.
_MAX_TRIANGLE_ANGLE = np.pi


def pin_feature_points(weights: sparse.csr_matrix, source: Head, target: Head) -> sparse.csr_matrix:
    """``weights`` with the target skin's feature points taking the source's exactly (the
    points are known to correspond; those between the triangulation's vertices, such as
    the inner lips and the chin boss, would otherwise miss by a little). See
    :func:`fmc.clone.parts.feature_point_pins`.

    A point bound to several vertices of the target and otherwise than on the source (a
    coarse mesh, the point inside a triangle) keeps its vertices' own motion, each shifted
    by one common offset (:func:`shift_bound_points`): on the MediaPipe mask (468 vertices)
    the vertices around a brow or cheek point, some millimetres from it, took three
    quarters of the source point's motion, and the point moved as little.
    """
    out = sparse.lil_matrix(weights)
    pins = feature_point_pins(source, target, "skin", "skin")
    for v, cols in pins.items():
        out.rows[v] = sorted(cols)
        out.data[v] = [cols[c] for c in sorted(cols)]
    return shift_bound_points(out.tocsr(), source, target, held=list(pins))


def shift_bound_points(weights: sparse.csr_matrix, source: Head, target: Head, held=()) -> sparse.csr_matrix:
    """``weights`` (N_t, N_s) with each target skin point bound to several vertices, and
    not alike on the source (:func:`fmc.clone.parts.feature_point_pins` leaves those),
    moving as the source's point.

    Only the points a FAP moves as its own (:data:`OWN_POINTS`): the others, such as the
    jaw's angles 2.13/2.14, are held still by most tables while the skin around them moves
    (:mod:`fmc.separate`), and shifted to hold still on the mask's coarse rim they dented
    its jaw line whenever the mouth moved.

    Each such point ``f`` adds one offset ``λ_f`` (a row over the source's vertices) to its
    vertices but the ``held`` ones (pinned to another point), so that their weighted sum is
    the source point's: the vertices keep their differences (the local shape of the
    motion), and the weights of each row still sum to one. Points sharing vertices are
    solved together, in the least-squares sense (on a coarse mesh two points may share a
    triangle: what they cannot both have is left, not blown up).
    """
    points = []
    for fp, b in target.feature_points.items():
        a = source.feature_points.get(fp)
        if fp not in OWN_POINTS or a is None or a.part != "skin" or b.part != "skin" or len(b.vertices) == 1:
            continue
        if not bound_alike(a, b):
            points.append((a, b))
    if not points:
        return weights
    n_t, n_s = weights.shape
    # (F, N_t) the targets' bindings and (F, N_s) the sources'.
    bind_t = _binding_rows([b for _, b in points], n_t)
    bind_s = _binding_rows([a for a, _ in points], n_s)
    # (F, N_t) which vertices each offset moves: all of its point's, alike, but the held.
    member = (bind_t > 0).astype(np.float64).tolil()
    member[:, np.asarray(list(held), dtype=np.int64)] = 0.0
    member = member.tocsr()
    miss = (bind_s - bind_t @ weights).toarray()  # (F, N_s)
    mix = (bind_t @ member.T).toarray()  # (F, F): how much of each offset reaches each point
    offsets = np.linalg.lstsq(mix, miss, rcond=1e-3)[0]
    return (weights + sparse.csr_matrix(member.T @ sparse.csr_matrix(offsets))).tocsr()


def _binding_rows(bindings, n: int) -> sparse.csr_matrix:
    """(len(bindings), n): each binding's weights on its vertices."""
    return sparse.csr_matrix((np.concatenate([b.weights for b in bindings]),
                              (np.repeat(np.arange(len(bindings)), [len(b.vertices) for b in bindings]),
                               np.concatenate([b.vertices for b in bindings]))), shape=(len(bindings), n))


def skin_weights(source: Head, source_space: np.ndarray, aligned: np.ndarray, depth: np.ndarray,
                 source_lip: np.ndarray, target_lip: np.ndarray, source_parts: np.ndarray, target_parts: np.ndarray,
                 support: float | np.ndarray) -> sparse.csr_matrix:
    """(N_t, N_s) weights taking the source skin's values to the target skin's vertices.

    ``source_space`` (N_s, 3) and ``aligned`` (N_t, 2), ``depth`` (N_t,) place the two
    skins in one alignment space (:func:`align_heads`); ``support`` is the anti-aliasing
    radius, one for all or (N_t,). Each lip's target vertices take nothing from the other
    lip's source vertices; skin vertices that belong to parts (``*_parts`` masks) neither
    give nor take. The interpolation carries each corner's value half-way along its
    gradient (:func:`fmc.clone.interpolate.gradient_operator`; the lips' gradients each
    from their own lip).
    """
    tris = source.skin.triangles
    ang = source_space[tris, 0]
    keep = (ang.max(axis=1) - ang.min(axis=1) < _MAX_TRIANGLE_ANGLE) & ~source_parts[tris].any(axis=1)
    height = 0.5 * (source.fp_position("4.1")[1] + source.fp_position("4.2")[1]) - source.fp_position("2.1")[1]
    n_t = len(aligned)
    support = np.broadcast_to(np.asarray(support, dtype=np.float64), (n_t,))
    grads = gradient_operator(source_space, tris[keep], height, apart=source_lip)
    out = sparse.csr_matrix((n_t, len(source_space)))
    for side, other in ((0.0, None), (1.0, -1.0), (-1.0, 1.0)):
        mine = np.flatnonzero((target_lip == side) & ~target_parts)
        if not len(mine):
            continue
        w = interpolation_matrix(aligned[mine], depth[mine], source_space, tris[keep], len(source_space), height,
                                 forbidden=None if other is None else source_lip == other, support=support[mine],
                                 gradients=grads)
        rows = sparse.csr_matrix((np.ones(len(mine)), (mine, np.arange(len(mine)))), shape=(n_t, len(mine)))
        out = out + rows @ w
    return out.tocsr()
