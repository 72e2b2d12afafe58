"""Head turns that fade over the neck: the head turns, the shoulders stay.

The head rotations (FAPs 48-50: pitch, yaw, roll about 7.1, the top of the spine) are in
the standard one rigid motion of the whole face. A head whose mesh reaches the shoulders
would then swing its shoulders and the neck's cut along. Here each vertex turns by a share
of the rotation, its **fade** ``s`` in [0, 1]: 1 on the head, 0 on the skin's lowest
boundary loop (the cut under the neck), smoothly in between (:func:`neck_fade`: from the cut up to the
chin's height).

**The deformation.** The turn is split into ``K`` equal partial turns ``R^(j/K)`` about
7.1 (:data:`NECK_SEGMENTS`; ``K + 1`` joints: the shoulders, ``K - 1`` neck joints, the
head) and a vertex blends the two joints its fade falls between, linearly
(:func:`joint_weights`, :func:`blend_turn`)::

    v' = (1 - f) (R_j (v - o) + o) + f (R_(j+1) (v - o) + o),   j + f = s K

This is linear blend skinning, what glTF viewers do with ``JOINTS_0``/``WEIGHTS_0``, so an
animated GLB (joints at 7.1, joint j turning by ``R^(j/K)``) plays exactly what the decoder
computes. A slerp of the rotation by ``s`` (each vertex turned by ``s`` times the angle)
would keep every ring of the neck round, but no glTF viewer can play it: linear blending of
two rotations pulls a point towards the axis by ``1 − cos(Δ/2)`` of its distance at worst,
Δ the angle between the two joints. With one segment (a shoulder joint and a head joint)
that is 13 % at 60° of yaw and 23 % at 80°, and the neck's sides fold over (38 triangles of
the generic head turned over at 80°); with the four segments used here it is 0.8 % and
1.5 %, nothing folds, and the blend is an exact slerp at s = 0, ¼, ½, ¾ and 1.

Eyeballs, teeth, gums, tongue and eyelashes (:data:`RIGID_PREFIXES`) follow the head
fully (s = 1): they sit inside it.
"""

from __future__ import annotations

import numpy as np

from .head import Head, Part

__all__ = ["NECK_SEGMENTS", "RIGID_PREFIXES", "NeckFade", "neck_cut", "neck_fade", "smoothstep", "joint_pair",
           "joint_weights", "partial_turns", "blend_turn", "quat_from_matrix", "matrix_from_quat", "quat_power"]

#: Partial turns the neck is split into (joints: shoulders, K - 1 in the neck, the head).
NECK_SEGMENTS = 4
#: Parts (by name prefix) that turn with the head fully: they sit inside it.
RIGID_PREFIXES = ("eye_", "teeth_", "gums_", "tongue", "eyelashes_")


class NeckFade:
    """Per-vertex share of the head turn, and where the fade runs.

    Attributes
    ----------
    fade : dict of str to (N,) float64
        Part → fade s in [0, 1] per vertex (1: turns with the head).
    pivot : (3,) float64
        The turn's centre, 7.1, metres.
    base : (3,) float64
        Centre of the neck's cut (mean of its vertices), metres; the pivot when the skin
        has no cut (a rigid head).
    """

    def __init__(self, fade: dict, pivot: np.ndarray, base: np.ndarray):
        self.fade = fade
        self.pivot = np.asarray(pivot, dtype=np.float64).reshape(3)
        self.base = np.asarray(base, dtype=np.float64).reshape(3)


def smoothstep(t: np.ndarray) -> np.ndarray:
    """``3 t² − 2 t³`` of ``t`` clipped to [0, 1]: flat at both ends, so the fade starts and
    stops without a crease."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def neck_cut(part: Part) -> np.ndarray | None:
    """Vertices of the part's lowest boundary loop (the cut under the neck), or None when
    the mesh is closed.

    Returns
    -------
    (k,) int64 or None
        Indices into ``part.vertices`` of the boundary loop with the lowest mean height (y).
    """
    t = part.triangles
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    edges, counts = np.unique(e, axis=0, return_counts=True)
    border = edges[counts == 1]
    if not len(border):
        return None
    # Loops as connected components of the border edges.
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    verts, pairs = np.unique(border, return_inverse=True)
    pairs = pairs.reshape(-1, 2)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(verts), len(verts)))
    _, labels = connected_components(graph, directed=False)
    loops = [verts[labels == k] for k in np.unique(labels)]
    return min(loops, key=lambda idx: part.vertices[idx, 1].mean()).astype(np.int64)


def neck_fade(head: Head) -> NeckFade:
    """Where and how much each vertex of ``head`` turns with the head (FAPs 48-50).

    The neck's axis runs from the centre of the skin's cut (:func:`neck_cut`) to 7.1.
    Around it, a vertex at azimuth φ and height h along the axis gets

    ``s = smoothstep((h − h_cut(φ)) / (h_chin − h_cut(φ)))``

    where ``h_cut(φ)`` is the height of the cut at that azimuth (linear between its
    vertices, so the fade starts exactly on the cut, however slanted: a cut low on the
    chest and high on the back) and ``h_chin`` the height of the chin, 2.1. The fade thus
    starts at the cut (s = 0: the shoulders and the cut stay) and ends level with the
    chin (s = 1: the face, the skull and the jaw turn fully); heights in metres, s
    unitless. Where the cut rises above the chin, the fade spans a quarter of the longest
    span from the cut instead. Parts named by :data:`RIGID_PREFIXES` get s = 1.

    A head without 7.1 or 2.1, without a ``skin`` part, with a closed skin, or cut above
    its chin all round (a face without a neck) turns rigidly: s = 1 everywhere.

    Parameters
    ----------
    head : Head
        Its neutral vertices and feature points are used.

    Returns
    -------
    NeckFade
    """
    ones = {name: np.ones(p.n_vertices) for name, p in head.parts.items()}
    if "7.1" not in head.feature_points:
        return NeckFade(ones, np.zeros(3), np.zeros(3))
    pivot = head.fp_position("7.1")
    skin = head.parts.get("skin")
    cut = None if skin is None or "2.1" not in head.feature_points else neck_cut(skin)
    if cut is None:
        return NeckFade(ones, pivot, pivot)
    base = skin.vertices[cut].mean(axis=0)
    axis = pivot - base
    length = float(np.linalg.norm(axis))
    up = axis / length if length > 1e-9 else np.array([0.0, 1.0, 0.0])
    side = np.array([1.0, 0.0, 0.0]) - up[0] * up  # the face's left, across the axis
    if np.linalg.norm(side) < 1e-9:
        side = np.array([0.0, 0.0, 1.0]) - up[2] * up
    side /= np.linalg.norm(side)
    front = np.cross(side, up)

    def height_azimuth(v):
        d = v - base
        return d @ up, np.arctan2(d @ side, d @ front)

    h_cut, phi_cut = height_azimuth(skin.vertices[cut])
    order = np.argsort(phi_cut)
    h_chin = float((head.fp_position("2.1") - base) @ up)
    spans = h_chin - h_cut
    if spans.max() <= 0:
        return NeckFade(ones, pivot, base)
    fade = {}
    for name, p in head.parts.items():
        if name.startswith(RIGID_PREFIXES):
            fade[name] = np.ones(p.n_vertices)
            continue
        h, phi = height_azimuth(p.vertices)
        floor = np.interp(phi, phi_cut[order], h_cut[order], period=2 * np.pi)
        span = np.maximum(h_chin - floor, 0.25 * spans.max())
        fade[name] = smoothstep((h - floor) / span)
    fade["skin"][cut] = 0.0  # exactly: the cut never moves
    return NeckFade(fade, pivot, base)


def joint_pair(fade: np.ndarray, segments: int = NECK_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """The two neighbouring joints each vertex blends: (N,) int64 the lower one j (the
    upper is j + 1), and (N,) float64 the upper one's weight, for (N,) fades in [0, 1]."""
    s = np.clip(np.asarray(fade, dtype=np.float64), 0.0, 1.0) * segments
    j = np.minimum(np.floor(s).astype(np.int64), segments - 1)
    return j, s - j


def joint_weights(fade: np.ndarray, segments: int = NECK_SEGMENTS) -> np.ndarray:
    """Skinning weights of the joint chain for per-vertex fades.

    Parameters
    ----------
    fade : (N,) float
        Share of the turn, in [0, 1].
    segments : int
        K: joints 0 (shoulders, still) to K (the head, the whole turn).

    Returns
    -------
    (N, K + 1) float64
        Rows sum to 1; at most two neighbouring joints weigh in per vertex.
    """
    j, f = joint_pair(fade, segments)
    w = np.zeros((len(j), segments + 1))
    rows = np.arange(len(j))
    w[rows, j] = 1.0 - f
    w[rows, j + 1] = f
    return w


def quat_from_matrix(a: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (x, y, z, w), w ≥ 0, of a (3, 3) rotation matrix."""
    a = np.asarray(a, dtype=np.float64)
    tr = np.trace(a)
    # Shepperd's method: divide by the largest of the four candidates (no cancellation).
    k = int(np.argmax([a[0, 0], a[1, 1], a[2, 2], tr]))
    if k == 3:
        q = np.array([a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1], 1.0 + tr])
    else:
        i, j, m = k, (k + 1) % 3, (k + 2) % 3
        q = np.zeros(4)
        q[i] = 1.0 + 2.0 * a[i, i] - tr
        q[j] = a[j, i] + a[i, j]
        q[m] = a[m, i] + a[i, m]
        q[3] = a[m, j] - a[j, m]
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def matrix_from_quat(q: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of a quaternion (x, y, z, w) (normalised first)."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def quat_power(q: np.ndarray, f: float) -> np.ndarray:
    """(4,) quaternion of the same axis and ``f`` times the angle (the shorter way round)."""
    q = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    if q[3] < 0:
        q = -q
    half = np.arctan2(np.linalg.norm(q[:3]), q[3])
    s = np.sin(half)
    if s < 1e-15:
        return np.array([0.0, 0.0, 0.0, 1.0])
    return np.r_[q[:3] / s * np.sin(f * half), np.cos(f * half)]


def partial_turns(a: np.ndarray, b: np.ndarray, pivot: np.ndarray, segments: int = NECK_SEGMENTS
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The joints' motions for a whole-head motion ``x → a x + b``.

    Joint j turns by ``R^(j/K)`` about ``pivot`` (and moves by j/K of any translation
    ``a`` leaves beyond turning about the pivot, which a head turn has none of).

    Returns
    -------
    (K + 1, 3, 3) and (K + 1, 3) float64
        ``x → A_j x + b_j`` per joint; joint 0 still, joint K the motion given.
    """
    pivot = np.asarray(pivot, dtype=np.float64)
    q = quat_from_matrix(a)
    rest = b - (pivot - a @ pivot)
    mats = np.empty((segments + 1, 3, 3))
    offs = np.empty((segments + 1, 3))
    for j in range(segments + 1):
        m = matrix_from_quat(quat_power(q, j / segments)) if j < segments else np.asarray(a, dtype=np.float64)
        mats[j] = m
        offs[j] = pivot - m @ pivot + rest * (j / segments)
    return mats, offs


def blend_turn(vertices: np.ndarray, weights: np.ndarray, a: np.ndarray, b: np.ndarray, pivot: np.ndarray
               ) -> np.ndarray:
    """Vertices turned by a whole-head motion, faded by their joint weights.

    Parameters
    ----------
    vertices : (N, 3) float
        Metres (after the morphs and the parts' own motions: glTF's order).
    weights : (N, K + 1) float
        From :func:`joint_weights`.
    a, b : (3, 3) and (3,) float
        The head's motion ``x → a x + b`` (the head turns composed).
    pivot : (3,) float
        7.1, metres.

    Returns
    -------
    (N, 3) float64
        ``Σ_j w_j (A_j v + b_j)`` (:func:`partial_turns`): linear blend skinning.
    """
    mats, offs = partial_turns(a, b, pivot, weights.shape[1] - 1)
    out = np.zeros((len(vertices), 3))
    for j in range(weights.shape[1]):
        w = weights[:, j]
        if w.any():
            out += w[:, None] * (vertices @ mats[j].T + offs[j])
    return out

