"""Eyes, teeth, tongue and the other parts beside the skin.

A part is found from its feature points: the part a point is bound to, or, when the
point lies on the skin mesh, the connected piece of the skin that holds it and the pieces
overlapping that one (a head given as one mesh); failing both, a part of the
conventional name. Each part's motion in a
morph target is split into a rigid motion about the part's centre (the eyeball's
rotation centre; the centroid of teeth, tongue and gums), fitted by least squares
(Kabsch), and what is left. The target's part turns by the same rotation about its own
centre, moves by the translation in FAPU terms, and takes the rest (in FAPU terms)
through a correspondence of the two parts' vertices.

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
.. [2] W. Kabsch, "A solution for the best rotation to relate two sets of vectors",
   Acta Crystallographica A32 (1976) 922-923.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from mpeg4.head import Head

from .regions import face_scale, mouth_scale, region_scales

__all__ = ["PART_ROLES", "PartRef", "find_parts", "sphere_centre", "rigid_motion", "part_correspondence",
           "bound_alike", "feature_point_pins", "transfer_part_motion"]

#: Role → the feature points that find it (first present wins).
PART_ROLES = {
    "eye_l": ("3.5",),
    "eye_r": ("3.6",),
    "teeth_upper": ("9.10", "9.8"),
    "teeth_lower": ("9.11", "9.9"),
    "tongue": ("6.2", "6.1", "6.3", "6.4"),
}


@dataclass
class PartRef:
    """Where one part of a head is and how it moves.

    Attributes
    ----------
    role : str
        A :data:`PART_ROLES` key, or the part's name for parts found by name only.
    part : str
        Name of the head's part holding it.
    vertices : (k,) int64
        Its vertices in that part.
    centre : (3,) float64
        Rotation centre, metres.
    scale : (3,) float64
        Metres per normalised unit.
    installed : bool
        The centre was computed here (the head gave none).
    """

    role: str
    part: str
    vertices: np.ndarray
    centre: np.ndarray
    scale: np.ndarray
    installed: bool = False

    def points(self, head: Head) -> np.ndarray:
        return head.parts[self.part].vertices[self.vertices]


def sphere_centre(points: np.ndarray) -> np.ndarray:
    """(3,) centre of the least-squares sphere through (K, 3) ``points``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> u = rng.normal(size=(200, 3)); u /= np.linalg.norm(u, axis=1, keepdims=True)
    >>> np.round(sphere_centre(0.012 * u + [0.03, 0.04, 0.08]), 6).tolist()
    [0.03, 0.04, 0.08]
    """
    p = np.asarray(points, dtype=np.float64)
    # |x|^2 = 2 c.x + (r^2 - |c|^2): linear in c and the constant.
    a = np.c_[2 * p, np.ones(len(p))]
    sol = np.linalg.lstsq(a, (p * p).sum(axis=1), rcond=None)[0]
    return sol[:3]


def _skin_component(head: Head, vertex: int) -> np.ndarray | None:
    """Vertices of the skin's piece holding ``vertex`` with the pieces that overlap it (an
    eyeball's iris and sclera), unless it is the largest piece (the face)."""
    skin = head.skin
    t = skin.triangles
    rows = np.r_[t[:, 0], t[:, 1], t[:, 2]]
    cols = np.r_[t[:, 1], t[:, 2], t[:, 0]]
    g = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(skin.n_vertices,) * 2)
    count, label = connected_components(g, directed=False)
    largest = np.argmax(np.bincount(label))
    if label[vertex] == largest:
        return None
    v = skin.vertices
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    np.minimum.at(lo, label, v)
    np.maximum.at(hi, label, v)
    group = {int(label[vertex])}
    while True:
        glo, ghi = lo[list(group)].min(axis=0), hi[list(group)].max(axis=0)
        touching = np.flatnonzero((lo <= ghi).all(axis=1) & (hi >= glo).all(axis=1))
        grown = group | {int(c) for c in touching if c != largest}
        if grown == group:
            return np.flatnonzero(np.isin(label, list(group)))
        group = grown


def find_parts(head: Head) -> tuple[dict[str, PartRef], list[str]]:
    """The head's eyes, teeth and tongue (by :data:`PART_ROLES`) and its other non-skin
    parts (by name), with warnings for centres installed here.

    Returns
    -------
    parts : dict of str to PartRef
        Keyed by role (or part name).
    warnings : list of str
    """
    out: dict[str, PartRef] = {}
    notes = []
    taken: set[str] = set()
    for role, fps in PART_ROLES.items():
        ref = None
        for fp in fps:
            b = head.feature_points.get(fp)
            if b is None:
                continue
            if b.part != "skin":
                ref = (b.part, np.arange(head.parts[b.part].n_vertices))
            else:
                comp = _skin_component(head, b.vertices[int(np.argmax(b.weights))])
                if comp is not None:
                    ref = ("skin", comp)
            if ref is not None:
                break
        if ref is None and role in head.parts:
            ref = (role, np.arange(head.parts[role].n_vertices))
        if ref is None:
            continue
        name, idx = ref
        pts = head.parts[name].vertices[idx]
        given = head.parts[name].centre if name != "skin" and len(idx) == head.parts[name].n_vertices else None
        installed = False
        if role.startswith("eye"):
            if given is None:
                given, installed = sphere_centre(pts), True
                notes.append(f"the {role} part has no rotation centre: installed at the centre of its sphere "
                             f"({', '.join(f'{c * 1000:.1f}' for c in given)} mm)")
            centre, scale = given, face_scale(head)
        else:
            centre, scale = pts.mean(axis=0), mouth_scale(head)
        out[role] = PartRef(role, name, idx, np.asarray(centre, dtype=np.float64), scale, installed)
        if name != "skin":
            taken.add(name)
    for name, part in head.parts.items():
        if name == "skin" or name in taken:
            continue
        centre = part.vertices.mean(axis=0)
        out[name] = PartRef(name, name, np.arange(part.n_vertices), centre, region_scales(head, centre[None])[0])
    return out, notes


def rigid_motion(points: np.ndarray, moved: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation R (3, 3) and translation t (3,) with
    ``moved ≈ R (points − centre) + centre + t`` (Kabsch [2]_).

    Examples
    --------
    >>> from mpeg4.fat import rotation_matrix
    >>> p = np.random.default_rng(1).normal(size=(50, 3))
    >>> r0 = rotation_matrix([0, 1, 0], 0.2)
    >>> r, t = rigid_motion(p, (p - 1.0) @ r0.T + 1.0 + [0.0, 0.1, 0.0], np.ones(3))
    >>> bool(np.allclose(r, r0)), bool(np.allclose(t, [0.0, 0.1, 0.0]))
    (True, True)
    """
    mp, mm = points.mean(axis=0), moved.mean(axis=0)
    h = (points - mp).T @ (moved - mm)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, mm - centre - r @ (mp - centre)


def part_correspondence(source: Head, s: PartRef, target: Head, t: PartRef, k: int = 4) -> sparse.csr_matrix:
    """(k_t, k_s) weights taking values on the source part's vertices to the target's:
    inverse-distance over the ``k`` nearest, each part's vertices taken about their
    centroid and divided by their spread along each axis (so two eyeballs, or two
    tongues, of different sizes and places meet point for point); feature points on both
    parts are pinned (:func:`feature_point_pins`)."""

    def normalised(p):
        return (p - p.mean(axis=0)) / np.maximum(p.std(axis=0), 1e-12)

    ps, pt = normalised(s.points(source)), normalised(t.points(target))
    k = min(k, len(ps))
    dist, near = cKDTree(ps).query(pt, k=k)
    dist, near = dist.reshape(len(pt), k), near.reshape(len(pt), k)
    w = 1.0 / np.maximum(dist, 1e-12) ** 2
    exact = dist[:, 0] < 1e-9
    w[exact] = 0.0
    w[exact, 0] = 1.0
    w /= w.sum(axis=1, keepdims=True)
    rows = np.repeat(np.arange(len(pt)), k)
    out = sparse.lil_matrix(sparse.csr_matrix((w.ravel(), (rows, near.ravel())), shape=(len(pt), len(ps))))
    s_at = {int(v): k for k, v in enumerate(s.vertices)}
    t_at = {int(v): k for k, v in enumerate(t.vertices)}
    for v, cols in feature_point_pins(source, target, s.part, t.part).items():
        if v in t_at and all(c in s_at for c in cols):
            out.rows[t_at[v]] = sorted(s_at[c] for c in cols)
            out.data[t_at[v]] = [cols[c] for c in sorted(cols, key=s_at.get)]
    return out.tocsr()


def bound_alike(a, b) -> bool:
    """Two :class:`mpeg4.head.FeaturePointBinding` with as many vertices and the same weights
    (heads made from one generic head)."""
    return len(a.vertices) == len(b.vertices) and np.allclose(a.weights, b.weights, atol=1e-9)


def feature_point_pins(source: Head, target: Head, source_part: str, target_part: str) -> dict[int, dict[int, float]]:
    """Target vertex → {source vertex: weight} making the feature points on both parts
    correspond exactly.

    A target point bound to one vertex takes the source point's combination of vertices.
    A point bound alike on both heads (as many vertices, the same weights: heads made from
    one generic head) is pinned vertex by vertex, which keeps each vertex's own motion; in
    any order the point itself moves as the source's. Other bindings are left alone (one
    value spread over several vertices would flatten the motion there; on the skin,
    :func:`fmc.clone.skin.shift_bound_points` then shifts their vertices alike).
    """
    pins: dict[int, dict[int, float]] = {}
    for fp, b in target.feature_points.items():
        a = source.feature_points.get(fp)
        if a is None or a.part != source_part or b.part != target_part:
            continue
        if len(b.vertices) == 1:
            cols: dict[int, float] = {}
            for u, w in zip(a.vertices, a.weights):
                cols[int(u)] = cols.get(int(u), 0.0) + w
            pins[int(b.vertices[0])] = cols
        elif bound_alike(a, b):
            for u, v in zip(a.vertices, b.vertices):
                pins[int(v)] = {int(u): 1.0}
    return pins


def transfer_part_motion(source_points: np.ndarray, displacement: np.ndarray, s: PartRef, target_points: np.ndarray,
                         t: PartRef, weights: sparse.csr_matrix) -> np.ndarray:
    """(k_t, 3) displacement of the target part for the source part's (k_s, 3) one.

    The rigid motion about the centres carries over (rotation as is, translation scaled
    by the two parts' scales); the non-rigid rest is carried by ``weights`` in normalised
    terms.
    """
    moved = source_points + displacement
    r, tr = rigid_motion(source_points, moved, s.centre)
    rest = moved - ((source_points - s.centre) @ r.T + s.centre + tr)
    rigid = (target_points - t.centre) @ r.T + t.centre + tr * (t.scale / s.scale) - target_points
    return rigid + (weights @ (rest / s.scale)) * t.scale
