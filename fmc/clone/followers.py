"""Parts that lie on the skin and follow it: separate eyelids, brow and lash cards, beards.

A head from elsewhere often models what sits on the face as meshes of their own: eyelids
over the eyeballs, eyebrow and eyelash cards, a beard, a hair cap. The source has nothing
of that name, so cloning would leave them still while the skin under them moves: a lid
that never closes, a brow that stays when the brow rises. A target part the source has no
counterpart for, that is no rigid part (eyes, teeth, tongue), and whose vertices lie, by
their median, within :data:`FOLLOW_ES0` of the eye separation from the skin, is bound to the
skin instead: each vertex to the skin's closest point (a triangle and its barycentric
weights), and in every cloned morph target and table it moves as the skin does there
(:func:`follower_weights`). What lies further off (glasses, a body, a throat inside the
neck) keeps still.

The lower teeth and the tongue of a target, when the source has nothing for them (a head
whose one mesh holds everything), turn with the jaw instead: rigidly, as the jaw's feature
points move (:func:`jaw_riders`), so that an open mouth does not leave them up among the
upper teeth.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from scipy import sparse

from mpeg4.head import Head

__all__ = ["FOLLOW_ES0", "JAW_FPS", "JAW_ROLES", "follower_weights", "surface_followers", "jaw_anchors", "jaw_riders"]

#: A part follows the skin when its vertices lie, by their median, within this share of
#: ES0 of it (about 5 mm on an adult): lids and brows lie on it, lash cards a few
#: millimetres off; glasses lie 10-20 mm in front of the face.
FOLLOW_ES0 = 0.08


def follower_weights(skin_vertices: np.ndarray, skin_triangles: np.ndarray, points: np.ndarray
                     ) -> tuple[sparse.csr_matrix, np.ndarray]:
    """Each point bound to the closest point of the skin.

    Parameters
    ----------
    skin_vertices : (N, 3) float
        Metres.
    skin_triangles : (M, 3) int
    points : (K, 3) float
        Metres.

    Returns
    -------
    weights : scipy.sparse.csr_matrix, (K, N)
        Barycentric weights (three per row, summing to 1): ``weights @ d`` is the skin's
        displacement ``d`` (N, 3) at each point's closest skin point.
    distance : (K,) float64
        From each point to the skin, metres.
    """
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(skin_vertices, dtype=np.float64), np.asarray(skin_triangles), process=False,
                           validate=False)
    closest, distance, tri = trimesh.proximity.closest_point(mesh, np.asarray(points, dtype=np.float64))
    corners = mesh.triangles[tri]
    bary = trimesh.triangles.points_to_barycentric(corners, closest)
    bary = np.clip(np.nan_to_num(bary, nan=1.0 / 3.0), 0.0, None)  # a sliver triangle: its centre
    bary /= np.maximum(bary.sum(axis=1, keepdims=True), 1e-12)
    rows = np.repeat(np.arange(len(points)), 3)
    cols = np.asarray(skin_triangles)[tri].ravel()
    weights = sparse.csr_matrix((bary.ravel(), (rows, cols)), shape=(len(points), len(skin_vertices)))
    return weights, np.asarray(distance, dtype=np.float64)


def surface_followers(head: Head, candidates: Iterable[str]) -> tuple[dict[str, sparse.csr_matrix], list[str]]:
    """The ``candidates`` (part names of ``head``) that lie on its skin, each with its
    :func:`follower_weights`, and a note for each.

    Returns
    -------
    followers : dict of str to scipy.sparse.csr_matrix
        Part → (its vertices, skin vertices) weights.
    notes : list of str
    """
    skin = head.skin
    reach = FOLLOW_ES0 * head.fapu.ES0
    out, notes = {}, []
    for name in candidates:
        part = head.parts.get(name)
        if part is None or name == "skin" or not part.n_vertices:
            continue
        weights, distance = follower_weights(skin.vertices, skin.triangles, part.vertices)
        median = float(np.median(distance))
        if median <= reach:
            out[name] = weights
            notes.append(f"the target's part '{name}' lies on the skin ({median * 1000:.1f} mm from it): "
                         "it moves as the skin under it")
    return out, notes


#: The chin's feature points: its bottom (2.1), its boss (2.10) and corners (2.11, 2.12),
#: where the skin is held to the jaw's bone. The skin over the jaw's angles (2.13, 2.14)
#: slides over it: on the generic head's own jaw opening the lower teeth, turned by the
#: chin's points, land 4.5 mm from where its tables put them (of 11.6 mm; 3.3 with the chin
#: boss on the lower lip's underside, a point of the lip's rather than of the chin's, whose
#: longer lever suited this one motion; without 2.10 7.7 mm), by those and the angles' 4.4
#: mm (4.6 with the angles on the cheek at the lobes' height, before they were put at the
#: gonion).
JAW_FPS = ("2.1", "2.10", "2.11", "2.12")
#: Target roles that ride on the jaw: with no counterpart on the source (a head whose one
#: mesh holds everything, its teeth not found), they turn with the jaw instead of staying.
JAW_ROLES = ("teeth_lower", "tongue")


def jaw_anchors(head: Head) -> sparse.csr_matrix | None:
    """(K, N) weights of the jaw's feature points (:data:`JAW_FPS`) on the skin's vertices;
    None with fewer than three of them on the skin."""
    rows, cols, vals = [], [], []
    k = 0
    for fp in JAW_FPS:
        b = head.feature_points.get(fp)
        if b is None or b.part != "skin":
            continue
        rows += [k] * len(b.vertices)
        cols += list(b.vertices)
        vals += list(b.weights)
        k += 1
    if k < 3:
        return None
    return sparse.csr_matrix((vals, (rows, cols)), shape=(k, head.skin.n_vertices))


def jaw_riders(head: Head, anchors: sparse.csr_matrix, skin_motion: np.ndarray, parts: Iterable[str]
               ) -> dict[str, np.ndarray]:
    """Part → (n, 3) displacement (metres) of each of ``parts`` moved rigidly as the jaw's
    feature points move with ``skin_motion`` ((N, 3), metres): the least-squares rotation
    and translation (Kabsch) of those points."""
    from .parts import rigid_motion

    points = anchors @ head.skin.vertices
    moved = points + anchors @ np.asarray(skin_motion, dtype=np.float64)
    centre = points.mean(axis=0)
    r, t = rigid_motion(points, moved, centre)
    out = {}
    for name in parts:
        x = head.parts[name].vertices
        out[name] = (x - centre) @ r.T + centre + t - x
    return out
