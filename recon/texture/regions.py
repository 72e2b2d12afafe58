"""Which photo each part of the skin is textured from: the feature lines and the regions.

The side photo's **feature line** (the feature points from the top of the skull down to the
chin, :data:`~recon.texture.warp.FEATURE_LINE`) is laid on the head's skin for each side
(:func:`feature_line`). With both photos at hand the front photo's region ends further
forward below the brow, where the two photos see the skin equally squarely
(:func:`view_line`); with the front camera that line bounds the front photo's polygon
(:func:`feature_polygon`). Each skin vertex then takes a region (:data:`REGIONS`): the front
photo inside that polygon where the front camera sees it, the seen or the mirrored side
photo elsewhere by the side of the midline it lies on, hidden inside the mouth and eye
sockets, or a fold next to seen skin (:func:`vertex_regions`). Triangles take the region of
most of their corners, and vertices shared by triangles of different regions are
duplicated (:func:`split_by_region`), so that each corner samples its own layer.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import cv2
import numpy as np
from scipy.spatial import ConvexHull

from mpeg4.camera import Camera
from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.unlit import render_depth
from mpeg4.errors import InputError
from mpeg4.head import Head

from .cameras import FittedCamera
from .warp import FEATURE_LINE, convex_outline, sections

__all__ = ["REGIONS", "FRONT", "SEEN", "MIRRORED", "HIDDEN", "FOLD", "SPLIT_STIFFNESS", "line_ids", "feature_line",
           "view_line", "smoothest_splits", "on_skin", "OVER_SKULL", "feature_polygon", "feature_envelope",
           "vertex_regions", "line_depth", "triangle_regions", "split_by_region"]

_NECK_STEP = 0.01  # metres between the neck line's points

#: Texture regions of the skin: which layer a triangle samples.
REGIONS = ("front", "seen side", "mirrored side", "hidden", "fold")
FRONT, SEEN, MIRRORED, HIDDEN, FOLD = range(5)

_VISIBLE_TOL = 0.003  # metres: a vertex this close behind the nearest surface is seen
_FOLD = 0.004  # metres: hidden skin this close to seen skin is a fold and takes its colour


def line_ids(side: str) -> tuple[str, ...]:
    """The feature line of the face's ``"L"`` (as listed) or ``"R"`` side (mirrored ids)."""
    if side == "L":
        return FEATURE_LINE
    return tuple(FEATURE_POINTS[i].mirror or i for i in FEATURE_LINE)


def feature_line(points3d: Mapping[str, np.ndarray], skin_vertices: np.ndarray, skin_triangles: np.ndarray,
                 side: str) -> tuple[np.ndarray, np.ndarray]:
    """The feature line of one side of the face, top to bottom.

    Its feature points (:data:`FEATURE_LINE`, mirrored for ``"R"``), over the skull (from
    its top to the brow's end, :data:`OVER_SKULL` of them) with points on the skin between
    them every :data:`_NECK_STEP` (:func:`on_skin`), and, below the last of them (the ear's
    front), a line down the neck: at every :data:`_NECK_STEP` down to the bottom of the
    skin, the point of the skin's cross-section (its convex outline) that faces half way
    between the front and the side, where both photos see the neck at 45°. The front photo
    gets the neck's front, the side photos what lies behind.

    Returns
    -------
    points : (K, 3) float64
        Metres.
    is_fp : (K,) bool
        Which of them are feature points.
    """
    ids = line_ids(side)
    missing = [i for i in ids if i not in points3d]
    if missing:
        raise InputError(f"the head lacks the feature points {', '.join(missing)} of the texture's feature lines",
                         where="texture", fix="give the head all of " + ", ".join(ids))
    fps = np.array([np.asarray(points3d[i], float) for i in ids])
    sign = 1.0 if side == "L" else -1.0
    v = np.asarray(skin_vertices, float)
    heights = np.arange(fps[-1, 1] - _NECK_STEP, v[:, 1].min() + 0.004, -_NECK_STEP)
    neck = []
    for y, xz in zip(heights, sections(v, skin_triangles, heights)):
        if (xz[:, 0] * sign > 0).sum() < 3:
            break
        hull = convex_outline(xz)
        if hull is None:  # a degenerate section: the line ends here
            break
        # The outline's point that faces half way between the two cameras (its support
        # point along the 45° direction): both photos see the neck there at 45°, not the
        # front one at a grazing angle.
        k = int(np.argmax(hull @ np.array([sign, 1.0])))
        neck.append([hull[k, 0], y, hull[k, 1]])
    skull, skull_fp = on_skin(fps[:OVER_SKULL], v, skin_triangles, _NECK_STEP)
    points = np.vstack([skull, fps[OVER_SKULL:], np.array(neck).reshape(-1, 3)])
    return points, np.r_[skull_fp, np.ones(len(fps) - OVER_SKULL, bool), np.zeros(len(neck), bool)]


#: The feature line's points over the skull: its top, the hairline's end and the brow's end.
OVER_SKULL = 3


def on_skin(points: np.ndarray, skin_vertices: np.ndarray, skin_triangles: np.ndarray,
            step: float) -> tuple[np.ndarray, np.ndarray]:
    """A polyline of points on the skin with points added between them, every ``step``
    metres or less, on the skin's cross-section at their height (the nearest point of it to
    the chord): the line runs over the surface instead of under it.

    Over the skull the feature line's points lie 40-70 mm apart; the straight chords between
    them pass up to 15 mm under the skin. The front region ends at the line's depth and the side
    photo's warp is anchored on it: on a chord, the front photo's crown and the side photo's
    meet at two places of the texture that are not side by side, a seam no blend can reach
    (a dark cap on the crown bounded by the hair's outline, in a real pair).

    Returns
    -------
    points : (K, 3) float64
    is_given : (K,) bool
        Which of them are the given points.
    """
    p = np.asarray(points, float)
    out, given, added = [p[0]], [True], []
    for a, b in zip(p[:-1], p[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        for j in range(1, k):
            added.append(len(out))
            out.append(a + (b - a) * (j / k))
            given.append(False)
        out.append(b)
        given.append(True)
    out = np.array(out)
    if added:
        cuts = sections(np.asarray(skin_vertices, float), np.asarray(skin_triangles), out[added, 1])
        for i, xz in zip(added, cuts):
            if len(xz):
                near = xz[np.argmin(np.sum((xz - out[i, [0, 2]]) ** 2, axis=1))]
                out[i, [0, 2]] = near
    return out, np.array(given)


def view_line(points3d: Mapping[str, np.ndarray], skin_vertices: np.ndarray, skin_triangles: np.ndarray,
              side: str, toward_front: np.ndarray, toward_side: np.ndarray,
              step: float = _NECK_STEP, normals: np.ndarray | None = None,
              registration: tuple[float, float] = (1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """The line along which the front and the side photo see one side of the head alike,
    top to bottom: where the front region ends when both photos are at hand.

    The feature line (:func:`feature_line`) runs down the front of the ear: the cheek before
    it faces the side camera, and the front photo sees it edge-on, its skin squeezed into a
    few pixels (the texture's horizontal streaks there). This line keeps the feature line's
    points above the outer end of the brow (the top of the skull, the hairline's end, the
    brow's end: exact in both photos). Below the brow's end, every ``step`` metres down to
    the feature line's end, it splits the band of skin ahead of the feature line at that
    height, ordered outwards, where the least skin area goes to the photo that sees it
    worse: a vertex is better seen from the front when its colour lands closer to it from
    there. A photo whose pixels land within ``r`` of where they belong (its registration)
    puts a surface seen at angle θ within ``r / cos θ``, so the front wins when
    ``n . toward_front / r_front >= n . toward_side / r_side``: with equal registrations,
    when it faces the front camera at least as squarely as the side camera.
    One split per band, weighed by area, so that the side of the nose or a hollow at the
    temple moves it only by their own area instead of cutting the face there.

    The split never falls inside the face's features (:func:`feature_envelope`: the brows,
    eyes, nose and lips of that side, and a margin): a side photo's pixels land there worst
    (the eye sits deep in its socket, the lids and brows are seen edge-on), and on the side
    the side photo does not show, its mirror image would paint the *other* eye; an eye
    made of two photos, or of the wrong one, is what a viewer sees first.

    Parameters
    ----------
    points3d, skin_vertices, skin_triangles, side
        As :func:`feature_line`.
    toward_front, toward_side : (3,) float
        Unit directions from the head towards the front camera and towards the side camera
        on this side of the face (the side photo's, or its mirror image).
    step : float
        Metres between the line's points below the brow.
    normals : (N, 3) float, optional
        The skin's vertex normals (computed when None).
    registration : (float, float)
        How far the front and the side photo's pixels may land from the skin they belong
        to (:meth:`recon.texture.cameras.FittedCamera.registration_m`); only their ratio
        counts.

    Returns
    -------
    points : (K, 3) float64
        Metres.
    is_fp : (K,) bool
        Which of them are feature points.
    """
    from mpeg4.render import vertex_normals

    ear, ear_fp = feature_line(points3d, skin_vertices, skin_triangles, side)
    top = int(np.flatnonzero(ear_fp)[OVER_SKULL - 1]) + 1  # down to the brow's end
    sign = 1.0 if side == "L" else -1.0
    v = np.asarray(skin_vertices, float)
    n = vertex_normals(v, np.asarray(skin_triangles)) if normals is None else normals
    order = np.argsort(ear[:, 1])
    z_ear = np.interp(v[:, 1], ear[order, 1], ear[order, 2])
    r_front, r_side = registration
    better = (n @ np.asarray(toward_front, float)) * r_side - (n @ np.asarray(toward_side, float)) * r_front >= 0
    area = np.zeros(len(v))  # each vertex's share of the skin's area
    t = np.asarray(skin_triangles)
    np.add.at(area, t.ravel(), np.repeat(0.5 / 3 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]],
                                                                            v[t[:, 2]] - v[t[:, 0]]), axis=1), 3))
    ahead = np.flatnonzero((v[:, 0] * sign > 0) & (v[:, 2] >= z_ear))
    heights = np.arange(ear[top - 1, 1] - step, ear[-1, 1] - 0.5 * step, -step)
    inner = feature_envelope(points3d, side, heights)
    bands, costs = [], []
    for y, lim in zip(heights, inner):
        k = ahead[np.abs(v[ahead, 1] - y) <= 0.5 * step]
        if len(k) < 2:
            continue
        k = k[np.argsort(v[k, 0] * sign, kind="stable")]
        w, good = area[k], better[k]
        # Split the band where the least skin area is left with the photo that sees it worse:
        # vertices 0..j front, the rest side (a hollow at the temple or the side of the
        # nose only moves the split by its own area), never inside the features.
        cost = np.cumsum(w * ~good) + (np.sum(w * good) - np.cumsum(w * good))
        cost[:max(int(np.searchsorted(v[k, 0] * sign, lim)) - 1, 0)] = np.inf
        bands.append((y, k))
        costs.append(cost)
    splits = smoothest_splits(costs, [v[k][:, [0, 2]] for _, k in bands], SPLIT_STIFFNESS * step)
    line = [[v[k[j], 0], y, v[k[j], 2]] for (y, k), j in zip(bands, splits)]
    points = np.vstack([ear[:top], np.array(line).reshape(-1, 3)])
    return points, np.r_[ear_fp[:top], np.zeros(len(line), bool)]


#: How dearly the view line pays for a sideways step between neighbouring bands, per metre
#: stepped, as a share of the band's height (the most skin area a step of that length can
#: move to the better photo). Below 1 a split can move; at 0.5 a lone band never jumps
#: from its neighbours (it would pay for two steps what it gains on one), and a stretch of
#: ``k`` bands moves when more than ``1 / k`` of the skin it passes over is better seen
#: from the other photo: the split follows the face's shape, not the noise of single
#: normals (one band's jump to the ear and back shears the side photo's warp into a
#: zig-zag, a seam across the cheek).
SPLIT_STIFFNESS = 0.5


def smoothest_splits(costs, points, penalty: float) -> list[int]:
    """The split of each band that minimises the bands' costs plus ``penalty`` times the
    length of the steps between consecutive bands' splits (dynamic programming, exact).

    Parameters
    ----------
    costs : sequence of (n_i,) float
        Each band's cost of splitting at each of its candidates (``inf``: never there).
    points : sequence of (n_i, D) float
        Where each candidate lies (metres).
    penalty : float
        Cost per metre stepped between bands.

    Returns
    -------
    list of int
        The chosen candidate of each band.
    """
    if not costs:
        return []
    total, back = np.asarray(costs[0], float), []
    for c, p0, p1 in zip(costs[1:], points[:-1], points[1:]):
        step = np.linalg.norm(np.asarray(p0, float)[:, None] - np.asarray(p1, float)[None], axis=2)
        reach = total[:, None] + penalty * step  # (n_prev, n_next)
        best = np.argmin(reach, axis=0)
        total = reach[best, np.arange(reach.shape[1])] + np.asarray(c, float)
        back.append(best)
    out = [int(np.argmin(total))]
    for best in reversed(back):
        out.append(int(best[out[-1]]))
    return out[::-1]


#: The face's features whose texture comes from one photo whole: brows, eyes, lips, nose.
_FEATURE_GROUPS = (3, 4, 8, 9)
#: How far beyond its feature points a feature's skin reaches, in eye separations (ES0):
#: the upper lid's fold and the crow's feet run about 5 mm past the eye's outer corner,
#: and the multiresolution blend spreads a seam over about as much again.
FEATURE_MARGIN_ES = 0.15


def feature_envelope(points3d: Mapping[str, np.ndarray], side: str, heights: np.ndarray,
                     margin: float | None = None) -> np.ndarray:
    """How far out from the midline the face's features reach on one side, per height.

    The convex hull, in (height, distance from the midline), of the brow, eye, lip and nose
    feature points on ``side`` and the midline (MPEG-4 groups 3, 4, 8 and 9), widened by
    ``margin``.

    Parameters
    ----------
    points3d : mapping of str to (3,) float
        The head's feature points, metres (x to the head's left, y up).
    side : {"L", "R"}
        ``"L"``: x > 0.
    heights : (K,) float
        Metres.
    margin : float, optional
        Metres; :data:`FEATURE_MARGIN_ES` eye separations (3.5 to 3.6) by default.

    Returns
    -------
    (K,) float64
        Distance from the midline, metres; -inf at heights above or below every feature
        (nothing to keep there).
    """
    sign = 1.0 if side == "L" else -1.0
    own = [np.asarray(p, float) for i, p in points3d.items()
           if i in FEATURE_POINTS and FEATURE_POINTS[i].group in _FEATURE_GROUPS
           and FEATURE_POINTS[i].side in (side, "C")]
    heights = np.asarray(heights, float)
    out = np.full(len(heights), -np.inf)
    if len(own) < 3:
        return out
    if margin is None:
        es = (np.linalg.norm(np.asarray(points3d["3.5"]) - np.asarray(points3d["3.6"]))
              if "3.5" in points3d and "3.6" in points3d else 0.063)
        margin = FEATURE_MARGIN_ES * es
    p = np.array([[q[1], max(q[0] * sign, 0.0)] for q in own])
    p = np.vstack([p, [[p[:, 0].max(), 0.0], [p[:, 0].min(), 0.0]]])  # closed at the midline
    hull = p[ConvexHull(p).vertices]
    a, b = hull, np.roll(hull, -1, axis=0)
    for k, y in enumerate(heights):
        lo, hi = np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 0], b[:, 0])
        e = (lo <= y) & (y <= hi) & (hi > lo)
        if e.any():
            t = (y - a[e, 0]) / (b[e, 0] - a[e, 0])
            out[k] = np.max(a[e, 1] + t * (b[e, 1] - a[e, 1])) + margin
    return out


def feature_polygon(front: FittedCamera, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """(K, 2) front-photo pixels of the closed outline of the front region: the left
    feature line from the top of the skull down the neck, then the right one back up."""
    return front.project(np.vstack([left, right[::-1][:-1]]))


def _visible(points: np.ndarray, cam: Camera, depth: np.ndarray) -> np.ndarray:
    """(K,) bool: the camera sees the points.

    A point is seen when nothing lies nearer than it anywhere in the 5 x 5 pixels around
    its projection but a surface within :data:`_VISIBLE_TOL`: the farthest depth of the
    neighbourhood is what it is compared with, which keeps surfaces seen at grazing angles
    (their depth changes fast from pixel to pixel) and points on the silhouette.
    """
    # (Nothing drawn is +inf, the largest of all: a point beside the silhouette is seen.)
    far = cv2.dilate(np.asarray(depth, np.float32), np.ones((5, 5), np.uint8))
    px = np.round(cam.project(points)).astype(np.int64)
    h, w = depth.shape
    inside = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
    out = np.zeros(len(points), dtype=bool)
    d = cam.depth(points[inside])
    out[inside] = d <= far[px[inside, 1], px[inside, 0]] + _VISIBLE_TOL
    return out


# Extra directions (yaw, pitch in degrees) from which a vertex may be seen, to tell the
# inside of the mouth and the eye sockets (seen from nowhere) from surfaces the photos
# merely miss (behind the ears, under the chin).
_AROUND = ((180.0, 0.0), (135.0, 0.0), (-135.0, 0.0), (0.0, 70.0), (0.0, -60.0), (45.0, 0.0), (-45.0, 0.0))


def _seen_from_around(head: Head, points: np.ndarray, size: int = 384) -> np.ndarray:
    """(K,) bool: some camera around the head sees the points."""
    meshes = _head_meshes(head)
    allv = np.concatenate([m.vertices for m in meshes])
    out = np.zeros(len(points), dtype=bool)
    for yaw, pitch in _AROUND:
        todo = np.flatnonzero(~out)  # a point one camera sees needs no other
        if not len(todo):
            break
        cam = Camera.fit(allv, size, size, yaw_deg=yaw, pitch_deg=pitch, margin=0.02)
        out[todo] = _seen_in_box(points[todo], meshes, cam)
    return out


def _seen_in_box(points: np.ndarray, meshes, cam: Camera) -> np.ndarray:
    """(K,) bool: :func:`_visible` of (K, 3) points, the depth rendered only over the
    points' box of pixels and their 5 x 5 neighbourhoods (a camera with the same pixel
    centres there): the same test with a quarter less of the renderer's work."""
    px = np.round(cam.project(points)).astype(np.int64)
    x0, y0 = np.maximum(px.min(axis=0) - 2, 0)
    x1, y1 = np.minimum(px.max(axis=0) + 3, (cam.width, cam.height))
    if x0 >= x1 or y0 >= y1:  # every point beside the image
        return np.zeros(len(points), dtype=bool)
    cx, cy = cam.principal
    box = dataclasses.replace(cam, width=int(x1 - x0), height=int(y1 - y0), principal=(cx - x0, cy - y0))
    return _visible(points, box, _depth(meshes, box))


def vertex_regions(vertices: np.ndarray, polygon_px: np.ndarray, front_px: np.ndarray, line_depth: np.ndarray,
                   seen_anywhere: np.ndarray, seen_sign: float, depth_margin: float = 0.005) -> np.ndarray:
    """Which layer each skin vertex takes its colour from.

    Parameters
    ----------
    vertices : (N, 3) float
        Skin vertices, metres.
    polygon_px : (K, 2) float
        :func:`feature_polygon`.
    front_px : (N, 2) float
        The vertices' front-photo pixels.
    line_depth : (N,) float
        Depth (z, metres) of the feature lines at each vertex's height (:func:`line_depth`).
    seen_anywhere : (N,) bool
        Whether any camera around the head sees them (the photos' and others).
    seen_sign : {+1, -1}
        +1 if the side photo shows the face's left (x > 0), -1 for its right.
    depth_margin : float
        Metres behind the line's depth still counted as the face.

    Returns
    -------
    (N,) int8
        :data:`REGIONS` index: front inside the polygon and in front of the feature lines'
        depth (the face, including the few places the front camera does not quite see,
        such as the nostrils); hidden where no camera around the head sees the vertex
        (the mouth and eye sockets); otherwise the side of the midline it lies on.
    """
    from skimage.measure import points_in_poly

    v = np.asarray(vertices)
    inside = points_in_poly(front_px, polygon_px) & (v[:, 2] >= np.asarray(line_depth) - depth_margin)
    region = np.where(v[:, 0] * seen_sign >= 0, SEEN, MIRRORED).astype(np.int8)
    region[~np.asarray(seen_anywhere)] = HIDDEN
    region[inside & np.asarray(seen_anywhere)] = FRONT
    return region


def line_depth(left: np.ndarray, right: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """(N,) z (metres) of the feature lines at the given heights (y, metres): linear along
    each line by height, the mean of the left and right lines, held beyond the ends."""
    out = []
    for p in (np.asarray(left), np.asarray(right)):
        order = np.argsort(p[:, 1])
        out.append(np.interp(heights, p[order, 1], p[order, 2]))
    return 0.5 * (out[0] + out[1])


def triangle_regions(vertex_region: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(M,) int8: the region most of a triangle's corners belong to (ties: the first in
    :data:`REGIONS`, so the front photo wins)."""
    r = np.asarray(vertex_region)[np.asarray(triangles)].T  # (3, M): the corners as rows
    counts = np.stack([(r[0] == k).astype(np.int8) + (r[1] == k) + (r[2] == k) for k in range(HIDDEN + 1)], axis=1)
    return np.argmax(counts, axis=1).astype(np.int8)


def _folds(vertices: np.ndarray, triangles: np.ndarray, tri_region: np.ndarray, vertex_region: np.ndarray,
           reach: float = None) -> np.ndarray:
    """Hidden triangles that touch skin a camera sees within ``reach`` metres become folds
    (:data:`FOLD`): creases and rims that open up when the face moves, to be coloured like
    the skin beside them rather than like the inside of the mouth."""
    from scipy.spatial import cKDTree

    reach = _FOLD if reach is None else reach
    out = np.asarray(tri_region).copy()
    seen = np.asarray(vertex_region) != HIDDEN
    hid = np.flatnonzero(out == HIDDEN)
    if not len(hid) or not seen.any():
        return out
    corners = np.unique(np.asarray(triangles)[hid])
    dist, _ = cKDTree(vertices[seen]).query(vertices[corners])
    near = np.zeros(len(vertices), bool)
    near[corners[dist < reach]] = True
    out[hid[near[np.asarray(triangles)[hid]].any(axis=1)]] = FOLD
    return out


def split_by_region(triangles: np.ndarray, tri_region: np.ndarray, vertex_region: np.ndarray,
                    n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Duplicate the vertices shared by triangles of different regions (except along the
    front region's border, where the side triangles share the front's vertex).

    Returns
    -------
    source : (V',) int64
        For each vertex of the split mesh, the original vertex; the first ``n_vertices``
        are the originals themselves (so feature-point bindings and per-vertex tables stay
        valid), the duplicates follow.
    triangles : (M, 3) int64
        The triangles over the split vertices.
    region : (V',) int8
        The region each split vertex samples. An original keeps its own region when one
        of its triangles uses it, else the first region its triangles use.
    """
    tri = np.asarray(triangles, dtype=np.int64)
    corner_region = np.repeat(np.asarray(tri_region, dtype=np.int64), 3)
    corner_vertex = tri.reshape(-1)
    nr = len(REGIONS)
    used = np.zeros((n_vertices, nr), dtype=bool)
    used[corner_vertex, corner_region] = True
    # Along the feature lines the side triangles take the front copy of a shared vertex:
    # both sides of the seam then sample the same place of the blended texture, and the
    # side triangles bend into their own layer within one ring.
    side_corner = (corner_region == SEEN) | (corner_region == MIRRORED)
    corner_region = np.where(side_corner & used[corner_vertex, FRONT], FRONT, corner_region)
    used[:] = False
    used[corner_vertex, corner_region] = True
    own = np.asarray(vertex_region, dtype=np.int64)
    keep = np.where(used[np.arange(n_vertices), own], own, np.argmax(used, axis=1))
    keep[~used.any(axis=1)] = own[~used.any(axis=1)]  # vertices of no triangle
    # New ids for (vertex, region) pairs other than the kept one.
    extra = used.copy()
    extra[np.arange(n_vertices), keep] = False
    ev, er = np.nonzero(extra)
    new_id = np.full((n_vertices, nr), -1, dtype=np.int64)
    new_id[np.arange(n_vertices), keep] = np.arange(n_vertices)
    new_id[ev, er] = n_vertices + np.arange(len(ev))
    out_tri = new_id[corner_vertex, corner_region].reshape(-1, 3)
    source = np.r_[np.arange(n_vertices), ev]
    region = np.r_[keep, er].astype(np.int8)
    return source, out_tri, region


def _head_meshes(head: Head):
    """The head's parts for depth renders only: no textures to upload, no normals to compute."""
    from mpeg4.render import RenderMesh

    return [RenderMesh(p.vertices, p.triangles, normals=np.zeros_like(p.vertices)) for p in head.parts.values()]


def _depth(meshes, cam: Camera) -> np.ndarray:
    return render_depth(meshes, cam)
