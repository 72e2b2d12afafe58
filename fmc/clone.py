"""Facial Motion Cloning: copy a source head's morph targets onto any head with feature points.

The method, after Pandžić, one small function per step:

1. :func:`normalisation` — every vertex takes the FAPU scale of the region of its nearest
   feature points (mouth and jaw: x by MW0, y and z by 3·MNS0; the rest of the face: x by
   ES0, y and z by 2·ENS0; blended smoothly across the border), so motion is compared in
   FAPU terms.
2. :func:`alignment_space` — a cylindrical projection about a vertical axis: angle and
   height, the angle 0 at the nose tip, the axis placed at the depth where the mouth spans
   a fixed angle on both heads.
3. :func:`align_to_source` — the target's projected vertices moved so its feature points
   land on the source's: a piecewise-affine warp over a triangulation of the feature
   points (points outside it shift with their nearest feature point).
4. :func:`interpolate_motion` — each aligned target vertex takes the source's normalised
   motion by barycentric interpolation in the projected source triangle that holds it;
   where several projected triangles hold it (the back of the head folds over the front)
   the one nearest in depth wins; a vertex outside every triangle uses the triangle with
   the smallest excess of negative barycentric weight, clamped and renormalised. Upper-lip
   target vertices use only upper-lip source triangles, and lower-lip ones lower-lip
   triangles, so the lips part.
5. Denormalisation by the target's scales gives the target's morph target. Parts other than
   the skin (eyes, teeth, tongue) move rigidly: each takes the source part's mean motion in
   normalised terms.

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, cKDTree

from mpeg4.catalogue import FEATURE_POINTS

from .author import MOUTH_LINE_FPS, mouth_line
from mpeg4.errors import InputError
from mpeg4.head import Head, SparseDisplacement

__all__ = ["REQUIRED_FPS", "normalisation", "alignment_space", "align_to_source", "interpolate_motion",
           "clone_targets", "clone"]

#: Feature points the method cannot do without (scales, projection axis, alignment).
REQUIRED_FPS = ("3.5", "3.6", "9.15", "2.2", "8.3", "8.4", "9.3", "2.1", "4.1", "4.2")

_MOUTH_GROUPS = {2, 8, 6}
_MOUTH_SPAN = 0.5  # radians: the mouth's angular width in the alignment space


def _require(head: Head, name: str) -> None:
    missing = [i for i in REQUIRED_FPS if i not in head.feature_points]
    if missing:
        raise InputError(f"the {name} head lacks the feature points {', '.join(missing)}",
                         fix="place them (recon annotate, or in its fdp.json) before cloning")


def _fps(head: Head, part: str = "skin") -> tuple[list[str], np.ndarray]:
    ids = [i for i, b in head.feature_points.items() if b.part == part]
    return ids, np.array([head.fp_position(i) for i in ids])


def normalisation(head: Head, vertices: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) per-vertex scales (metres per normalised unit) of the skin, by the region of
    each vertex's nearest skin feature point."""
    v = head.skin.vertices if vertices is None else vertices
    f = head.fapu
    ids, pts = _fps(head)
    mouth = np.array([FEATURE_POINTS[i].group in _MOUTH_GROUPS or i in ("9.15", "5.1", "5.2") for i in ids])
    upper = np.array([f.ES0, 2 * f.ENS0, 2 * f.ENS0])
    lower = np.array([f.MW0, 3 * f.MNS0, 3 * f.MNS0])
    # A soft border between the regions (a hard one flips a vertex's scale wherever the
    # nearest point changes region, differently on two heads).
    d_mouth = cKDTree(pts[mouth]).query(v)[0]
    d_upper = cKDTree(pts[~mouth]).query(v)[0]
    t = np.clip(0.5 + (d_upper - d_mouth) / (0.2 * f.ES0), 0.0, 1.0)
    w = t * t * (3 - 2 * t)
    return w[:, None] * lower + (1 - w[:, None]) * upper


def alignment_space(head: Head, points: np.ndarray) -> np.ndarray:
    """(K, 3): angle (rad, 0 at the nose tip), height and radius of ``points`` about the
    head's vertical axis, the axis placed so the mouth corners are ``_MOUTH_SPAN`` apart."""
    nose = head.fp_position("9.3")
    ml, mr = head.fp_position("8.3"), head.fp_position("8.4")
    cx = 0.5 * (ml[0] + mr[0])

    def span(cz):
        return abs(np.arctan2(ml[0] - cx, ml[2] - cz) - np.arctan2(mr[0] - cx, mr[2] - cz))

    # The span grows as the axis nears the mouth: bisect on the axis depth.
    lo, hi = min(ml[2], mr[2]) - 1.0, min(ml[2], mr[2]) - 1e-4
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if span(mid) < _MOUTH_SPAN else (lo, mid)
    cz = 0.5 * (lo + hi)
    zero = np.arctan2(nose[0] - cx, nose[2] - cz)
    p = np.asarray(points, dtype=np.float64)
    theta = np.arctan2(p[:, 0] - cx, p[:, 2] - cz) - zero
    theta = (theta + np.pi) % (2 * np.pi) - np.pi
    radius = np.hypot(p[:, 0] - cx, p[:, 2] - cz)
    # Heights in units of the face's height (brows to chin), so both heads span alike.
    y0 = head.fp_position("2.1")[1]
    h = 0.5 * (head.fp_position("4.1")[1] + head.fp_position("4.2")[1]) - y0
    return np.c_[theta, (p[:, 1] - y0) / h, radius]


def align_to_source(target_2d: np.ndarray, target_fps_2d: np.ndarray, source_fps_2d: np.ndarray) -> np.ndarray:
    """Move (N, 2) target points by the piecewise-affine map taking the target's feature
    points (K, 2) onto the source's (inside their triangulation; outside it, by the offset
    of the nearest feature point)."""
    tri = Delaunay(target_fps_2d)
    simplex = tri.find_simplex(target_2d)
    inside = simplex >= 0
    out = np.empty_like(target_2d)
    t = tri.transform[simplex[inside]]
    b = np.einsum("nij,nj->ni", t[:, :2], target_2d[inside] - t[:, 2])
    bary = np.c_[b, 1 - b.sum(axis=1)]
    out[inside] = np.einsum("ni,nij->nj", bary, source_fps_2d[tri.simplices[simplex[inside]]])
    if (~inside).any():
        # Beyond the feature points an affine map runs away (the neck, far below the chin):
        # points there shift by their nearest feature point's offset.
        _, nearest = cKDTree(target_fps_2d).query(target_2d[~inside])
        out[~inside] = target_2d[~inside] + (source_fps_2d - target_fps_2d)[nearest]
    return out


def _lip_class(head: Head, space: np.ndarray) -> np.ndarray:
    """+1 upper lip, −1 lower lip, 0 elsewhere, for points given in ``head``'s space."""
    need = MOUTH_LINE_FPS + ("8.4", "8.3", "8.1", "8.2")
    if not all(i in head.feature_points for i in need):
        return np.zeros(len(space))
    fp = dict(zip(need, alignment_space(head, np.array([head.fp_position(i) for i in need]))[:, :2]))
    line = mouth_line(fp)
    line_y = np.interp(space[:, 0], line[:, 0], line[:, 1])
    inside = (space[:, 0] > fp["8.4"][0]) & (space[:, 0] < fp["8.3"][0])
    top, bottom = fp["8.1"][1], fp["8.2"][1]
    margin = 0.5 * (top - bottom)
    near = inside & (space[:, 1] < top + margin) & (space[:, 1] > bottom - margin)
    return np.where(near, np.where(space[:, 1] >= line_y, 1.0, -1.0), 0.0)


def interpolate_motion(points: np.ndarray, depth: np.ndarray, src_space: np.ndarray, src_tris: np.ndarray,
                       src_motion: np.ndarray, forbidden: np.ndarray | None = None, k: int = 24,
                       depth_tol: float = 0.25) -> np.ndarray:
    """Barycentric interpolation of per-vertex source motion at 2D points.

    Parameters
    ----------
    points : (N, 2)
        Target points in the (aligned) source space.
    depth : (N,)
        Their radius about the axis, for choosing among overlapping triangles.
    src_space : (V, 3)
        Source vertices in the alignment space (angle, height, radius).
    src_tris : (T, 3)
        Source triangles.
    src_motion : (V, C)
        What to interpolate.
    forbidden : (V,) bool, optional
        Source vertices whose motion must not reach these points (the other lip); their
        barycentric weights are dropped and the rest renormalised.
    k : int
        Candidate triangles per point (by centroid distance).
    depth_tol : float
        Largest depth difference, as a fraction of the source's median radius, between a
        point and the triangle it takes motion from; beyond it the point does not move.
    """
    a, b, c = (src_space[src_tris[:, j], :2] for j in range(3))
    # Candidates by centroid distance in angle, height and depth (scaled to the face), so
    # that where the projection folds (mouth, throat) the right layer is among them.
    r_scale = np.median(src_space[:, 2])
    centroids = np.c_[(a + b + c) / 3, src_space[src_tris, 2].mean(axis=1) / r_scale]
    k = min(k, len(src_tris))
    _, cand = cKDTree(centroids).query(np.c_[points, depth / r_scale], k=k)
    cand = cand.reshape(len(points), k)
    A, B, C = a[cand], b[cand], c[cand]  # (N, k, 2)
    v0, v1, v2 = B - A, C - A, points[:, None, :] - A
    d00 = (v0 * v0).sum(-1)
    d01 = (v0 * v1).sum(-1)
    d11 = (v1 * v1).sum(-1)
    d20 = (v2 * v0).sum(-1)
    d21 = (v2 * v1).sum(-1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) < 1e-300, 1e-300, den)
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    bary = np.stack([1 - w1 - w2, w1, w2], axis=-1)  # (N, k, 3)
    excess = np.clip(-bary, 0, None).sum(-1)
    tri_depth = np.einsum("nkj,nkj->nk", bary, src_space[src_tris[cand], 2])
    # Inside triangles first, nearest in depth among them; else the smallest excess.
    score = np.where(excess <= 1e-12, np.abs(tri_depth - depth[:, None]), 1e6 + excess)
    best = np.argmin(score, axis=1)
    rows = np.arange(len(points))
    # No source surface at this point's depth (inner mouth against the face, the back of
    # the head): it gets no motion rather than another layer's.
    unmatched = np.abs(tri_depth[rows, best] - depth) > depth_tol * r_scale
    w = np.clip(bary[rows, best], 0, None)
    verts = src_tris[cand[rows, best]]  # (N, 3)
    if forbidden is not None:  # e.g. the other lip: its vertices lend no motion
        w = np.where(forbidden[verts], 0.0, w)
        empty = w.sum(axis=1) <= 0
        w[empty] = np.where(forbidden[verts[empty]], 0.0, 1.0)
    total = w.sum(axis=1, keepdims=True)
    w = np.divide(w, total, out=np.zeros_like(w), where=total > 0)
    w[unmatched] = 0.0
    return np.einsum("nj,njc->nc", w, src_motion[verts])


def clone_targets(source: Head, target: Head, names=None) -> dict[str, dict[str, SparseDisplacement]]:
    """The source's morph targets cloned onto the target.

    Parameters
    ----------
    source, target : Head
        Both with the :data:`REQUIRED_FPS` on their skins; the source with morph targets.
    names : iterable of str, optional
        Targets to clone (all by default).

    Returns
    -------
    dict
        Target name → part → displacement, for the target head.
    """
    _require(source, "source")
    _require(target, "target")
    names = list(source.morph_targets if names is None else names)
    if not names:
        raise InputError("the source head has no morph targets to clone", fix="give a source with motion")
    # 1-2: spaces and scales.
    s_v, t_v = source.skin.vertices, target.skin.vertices
    s_space, t_space = alignment_space(source, s_v), alignment_space(target, t_v)
    s_scale, t_scale = normalisation(source), normalisation(target)
    # 3: align the target's projection onto the source's through the shared FPs.
    shared = [i for i in source.feature_points if source.feature_points[i].part == "skin"
              and i in target.feature_points and target.feature_points[i].part == "skin"]
    s_fp = alignment_space(source, np.array([source.fp_position(i) for i in shared]))[:, :2]
    t_fp = alignment_space(target, np.array([target.fp_position(i) for i in shared]))[:, :2]
    # The face's points only: the top and back of the skull sit where the angle wraps.
    # Points that nearly coincide (the inner lips meet in the neutral face) would make
    # sliver triangles that tear the warp: keep the first of each close pair.
    uniq = []
    for k in range(len(shared)):
        if abs(s_fp[k, 0]) >= 2.0 or abs(t_fp[k, 0]) >= 2.0:
            continue
        if all(np.linalg.norm(t_fp[k] - t_fp[j]) > 0.015 and np.linalg.norm(s_fp[k] - s_fp[j]) > 0.015 for j in uniq):
            uniq.append(k)
    uniq = np.array(uniq)
    aligned = align_to_source(t_space[:, :2], t_fp[uniq], s_fp[uniq])
    # Depth in the source's terms: the target's radius scaled by the two radii of the nose
    # tip (the axis sits where the mouth spans the same angle, so radii scale with the mouth).
    r_nose = [alignment_space(h, h.fp_position("9.3")[None])[0, 2] for h in (source, target)]
    depth = t_space[:, 2] * (r_nose[0] / r_nose[1])
    # 4: per-target normalised motion of the source skin, interpolated; lips kept apart.
    motion = np.concatenate([source.morph_targets[n]["skin"].dense(len(s_v)) / s_scale
                             if "skin" in source.morph_targets[n] else np.zeros_like(s_v) for n in names], axis=1)
    s_lip = _lip_class(source, s_space)
    t_lip = _lip_class(target, t_space)  # each head's lips by its own feature points
    tris = source.skin.triangles
    out_motion = np.zeros((len(t_v), motion.shape[1]))
    for who, forbidden in ((t_lip == 0, None), (t_lip > 0, s_lip < 0), (t_lip < 0, s_lip > 0)):
        if who.any():
            out_motion[who] = interpolate_motion(aligned[who], depth[who], s_space, tris, motion, forbidden)
    # 5: back to metres with the target's scales; rigid parts by their mean motion.
    result: dict[str, dict[str, SparseDisplacement]] = {}
    s_centre_scale = np.array([source.fapu.MW0, 3 * source.fapu.MNS0, 3 * source.fapu.MNS0])
    t_centre_scale = np.array([target.fapu.MW0, 3 * target.fapu.MNS0, 3 * target.fapu.MNS0])
    for j, n in enumerate(names):
        d = out_motion[:, 3 * j:3 * j + 3] * t_scale
        result[n] = {"skin": SparseDisplacement.from_dense(d, tol=1e-7)}
        for part, disp in source.morph_targets[n].items():
            if part == "skin" or part not in target.parts:
                continue
            mean = disp.dense(source.parts[part].n_vertices).mean(axis=0) / s_centre_scale * t_centre_scale
            if np.abs(mean).max() > 1e-7:
                result[n][part] = SparseDisplacement(np.arange(target.parts[part].n_vertices),
                                                     np.tile(mean, (target.parts[part].n_vertices, 1)))
    return result


def clone(source: Head, target: Head) -> tuple[Head, list[str]]:
    """The target with the source's morph targets and Facial Animation Tables cloned onto it.

    Morph targets keep their names. The FAT's mesh tables travel as morph targets
    (:func:`mpeg4.fat.fat_to_morph_targets`, in the source's FAPU) and are rebuilt on the
    target in its own FAPU; its transforms are re-centred on the target (eyes about the
    target's eye centres, the head about the target's 7.1).

    Returns
    -------
    head : Head
    warnings : list of str
        Parts or centres the target lacks (their motion is left out).
    """
    from mpeg4.fat import FAT, FaceDefTable, FaceDefTransform, fat_from_morph_targets, fat_to_morph_targets

    warnings = []
    targets = dict(source.morph_targets)
    specs = []
    if source.fat is not None and len(source.fat):
        fat_targets, specs = fat_to_morph_targets(source.fat, source.fapu)
        targets.update(fat_targets)
    if not targets:
        raise InputError("the source head has no morph targets or animation tables to clone",
                         fix="give a source with motion (fmc author, or a GLB with morph targets)")
    src = Head(source.parts, source.feature_points, targets, metadata=source.metadata)
    cloned = clone_targets(src, target)
    missing = sorted({p for t in targets.values() for p in t if p not in target.parts})
    if missing:
        warnings.append(f"the target has no parts {', '.join(missing)}: their motion is left out")
    out = target.copy()
    out.morph_targets = {n: cloned[n] for n in source.morph_targets}
    if specs:
        transforms = FAT()
        for key, table in source.fat.items():
            moved = []
            for t in table.transforms:
                if t.part is None:
                    centre = target.fp_position("7.1") if "7.1" in target.feature_points else None
                    if centre is None:
                        warnings.append(f"FAP {key[0]}: the target has no 7.1; its head rotation is left out")
                        continue
                elif t.part in target.parts and target.parts[t.part].centre is not None:
                    centre = target.parts[t.part].centre
                elif t.part in target.parts and t.kind != "rotation":
                    centre = t.centre
                else:
                    warnings.append(f"FAP {key[0]}: the target has no '{t.part}' with a centre; left out")
                    continue
                moved.append(FaceDefTransform(t.part, t.kind, centre, t.axis, t.amount))
            transforms.add(FaceDefTable(table.fap, table.high_level, [], moved))
        fat_targets = {s.target: cloned[s.target] for s in specs}
        out.fat = fat_from_morph_targets(fat_targets, specs, target.fapu, transforms)
        for key, table in transforms.items():
            if key not in out.fat:
                out.fat.add(table)
    out.metadata = dict(out.metadata, cloned_from=str(source.metadata.get("name", "source head")))
    return out, sorted(set(warnings))
