"""Regions of the face for cloning: FAPU normalisation and the two lips.

Motion is compared between heads in FAPU terms: each vertex takes the scale of the
region of its nearest feature points (the mouth and jaw: x by MW0, y and z by 3·MNS0;
the rest of the face: x by ES0, y and z by 2·ENS0, the factors of a visage-derived
implementation, reference section 7), so a displacement divided by the source's scales
and multiplied by the target's is the same motion for the target's proportions [1]_.

The lips are told apart by polygons of their feature points in the alignment space (the
outer lip contour, split by the line where the lips meet) and, inside them, by which
lip's feature points are nearer along the mesh.

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from skimage.measure import points_in_poly

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.head import Head

from mpeg4.surface import edge_graph, nearest_seed_labels

from .space import alignment_space

__all__ = ["MOUTH_REGION_FPS", "region_scales", "normalisation", "mouth_scale", "face_scale", "LIP_FPS",
           "UPPER_LIP_FPS", "LOWER_LIP_FPS", "CORNER_FPS", "lip_sides_on_mesh", "lip_classes", "lip_vertex_classes",
           "lip_sides"]

#: Skin feature points of the mouth region (lips, chin and jaw, the soft cheeks, the
#: bottom of the nose); all other skin points belong to the upper face.
MOUTH_REGION_FPS = frozenset([i for i, fp in FEATURE_POINTS.items() if fp.group in (2, 8)] + ["9.15", "5.1", "5.2"])

# Width of the soft border between the two regions, in ES0.
_BORDER = 0.2


def mouth_scale(head: Head) -> np.ndarray:
    """(3,) metres per normalised unit in the mouth region: MW0, 3·MNS0, 3·MNS0."""
    f = head.fapu
    return np.array([f.MW0, 3 * f.MNS0, 3 * f.MNS0])


def face_scale(head: Head) -> np.ndarray:
    """(3,) metres per normalised unit in the upper face: ES0, 2·ENS0, 2·ENS0."""
    f = head.fapu
    return np.array([f.ES0, 2 * f.ENS0, 2 * f.ENS0])


def region_scales(head: Head, points: np.ndarray) -> np.ndarray:
    """(K, 3) scales (metres per normalised unit) at ``points`` (K, 3, metres).

    Each point takes its region's scale by its nearest skin feature point; across the
    border the two blend smoothly over :data:`_BORDER`·ES0, so that no vertex's scale
    jumps where its nearest point changes region (it would do so at different places on
    two heads).
    """
    ids = [i for i, b in head.feature_points.items() if b.part == "skin"]
    pts = np.array([head.fp_position(i) for i in ids])
    mouth = np.array([i in MOUTH_REGION_FPS for i in ids])
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    f = head.fapu  # measured afresh on every access: once here
    m_scale, f_scale = np.array([f.MW0, 3 * f.MNS0, 3 * f.MNS0]), np.array([f.ES0, 2 * f.ENS0, 2 * f.ENS0])
    if not mouth.any() or mouth.all():
        return np.tile(m_scale if mouth.any() else f_scale, (len(p), 1))
    d_mouth = cKDTree(pts[mouth]).query(p)[0]
    d_face = cKDTree(pts[~mouth]).query(p)[0]
    t = np.clip(0.5 + (d_face - d_mouth) / (_BORDER * f.ES0), 0.0, 1.0)
    w = (t * t * (3 - 2 * t))[:, None]
    return w * m_scale + (1 - w) * f_scale


def normalisation(head: Head, vertices: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) scales of the skin's vertices (or of ``vertices``): a displacement divided by
    them is in normalised (FAPU) terms, multiplied by them back in metres."""
    return region_scales(head, head.skin.vertices if vertices is None else vertices)


#: The outer lip contour in order round the mouth, then the inner points of the line
#: where the lips meet (from the left corner to the right one, mean of each upper/lower pair).
LIP_FPS = ("8.3", "8.5", "8.10", "8.1", "8.9", "8.6", "8.4", "8.8", "8.2", "8.7",
           "2.4", "2.6", "2.8", "2.2", "2.3", "2.7", "2.9", "2.5")

# How far beyond the outer contour (as a fraction of its size about its centre) a point
# still belongs to a lip: the vermilion border and the lips' inner surfaces.
_LIP_MARGIN = 0.25

# How far along the mesh (in MW0) a lip's feature points claim vertices for their lip.
_LIP_REACH = 0.5


#: Lip feature points by the lip they lie on: their vertices are on that lip whatever
#: the line says (the inner points of the two lips touch, and may cross, in the neutral
#: face); the corners belong to both.
UPPER_LIP_FPS = ("2.2", "2.6", "2.7", "8.1", "8.5", "8.6", "8.9", "8.10")
LOWER_LIP_FPS = ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8")
CORNER_FPS = ("2.4", "2.5", "8.3", "8.4")


def lip_vertex_classes(head: Head, classes: np.ndarray) -> np.ndarray:
    """``classes`` (N,) of the skin's vertices with the lip feature points' own vertices
    set to their lip (+1 upper, −1 lower, 0 the corners)."""
    out = np.array(classes, dtype=np.float64, copy=True)
    for ids, side in ((UPPER_LIP_FPS, 1.0), (LOWER_LIP_FPS, -1.0), (CORNER_FPS, 0.0)):
        for i in ids:
            b = head.feature_points.get(i)
            if b is not None and b.part == "skin":
                out[list(b.vertices)] = side
    return out


def lip_sides_on_mesh(head: Head, reach: float) -> np.ndarray:
    """(N,) +1 / −1 for skin vertices nearer (along the mesh) to the upper / lower lip's
    feature points, 0 beyond ``reach`` metres of both.

    Along the mesh the two lips meet only at the corners (and deep in the mouth), so a
    lip's inner surface, which curls back behind the other lip, stays with its own lip.
    """
    skin = head.skin
    seeds, side = [], []
    for ids, sign in ((UPPER_LIP_FPS, 1.0), (LOWER_LIP_FPS, -1.0)):
        for i in ids:
            b = head.feature_points.get(i)
            if b is not None and b.part == "skin":
                seeds += list(b.vertices)
                side += [sign] * len(b.vertices)
    return nearest_seed_labels(edge_graph(skin.vertices, skin.triangles), seeds, side, reach)


def lip_classes(space: np.ndarray, lip_fps: dict[str, np.ndarray]) -> np.ndarray:
    """(K,) +1 upper lip, −1 lower lip, 0 elsewhere.

    Parameters
    ----------
    space : (K, 2) float
        Points of one head in its alignment space (angle, height).
    lip_fps : dict of str to (2,) array
        That head's :data:`LIP_FPS` in the same space.
    """
    p = {i: np.asarray(lip_fps[i], dtype=np.float64) for i in LIP_FPS}
    outer = np.array([p[i] for i in LIP_FPS[:10]])
    centre = outer.mean(axis=0)
    poly = centre + (1 + _LIP_MARGIN) * (outer - centre)
    line = np.array([p["8.4"], p["2.5"], 0.5 * (p["2.7"] + p["2.9"]), 0.5 * (p["2.2"] + p["2.3"]),
                     0.5 * (p["2.6"] + p["2.8"]), p["2.4"], p["8.3"]])
    line = line[np.argsort(line[:, 0])]
    space = np.asarray(space, dtype=np.float64)[:, :2]
    inside = points_in_poly(space, poly)
    line_y = np.interp(space[:, 0], line[:, 0], line[:, 1])
    return np.where(inside, np.where(space[:, 1] >= line_y, 1.0, -1.0), 0.0)


def lip_sides(source: Head, target: Head, source_space: np.ndarray, target_space: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(N_s,) and (N_t,) lip classes of the two skins (+1 upper, −1 lower, 0 neither), each
    by its own feature points, and a warning when they cannot be told apart.

    The lips' zone is the polygon of their feature points (:func:`lip_classes`); inside
    it a vertex is on the lip whose feature points are nearer along the mesh
    (:func:`lip_sides_on_mesh`; the lower lip's inner surface curls up behind the upper
    lip, above the line where they meet), else on its side of that line.
    """
    if not all(i in source.feature_points and i in target.feature_points for i in LIP_FPS):
        missing = [i for i in LIP_FPS if i not in source.feature_points or i not in target.feature_points]
        return (np.zeros(len(source_space)), np.zeros(len(target_space)),
                [f"the lips are not told apart: {', '.join(missing)} are missing"])
    sides = []
    for head, space in ((source, source_space), (target, target_space)):
        fps = dict(zip(LIP_FPS, alignment_space(head, np.array([head.fp_position(i) for i in LIP_FPS]))))
        zone = lip_classes(space, fps)
        along = lip_sides_on_mesh(head, _LIP_REACH * head.fapu.MW0)
        sides.append(lip_vertex_classes(head, np.where(zone != 0, np.where(along != 0, along, zone), 0.0)))
    return sides[0], sides[1], []
