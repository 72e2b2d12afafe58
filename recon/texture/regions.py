"""Which photo each part of the skin is textured from: the regions.

The feature lines (:mod:`recon.texture.lines`: the side photo's feature line laid on the
skin, or where the two photos see the skin alike), seen by the front camera, bound the
front photo's polygon (:func:`feature_polygon`). Each skin vertex then takes a region
(:data:`REGIONS`): the front photo inside that polygon where the front camera sees it, the seen or the mirrored side
photo elsewhere by the side of the midline it lies on, hidden inside the mouth and eye
sockets, or a fold next to seen skin (:func:`vertex_regions`). Triangles take the region of
most of their corners, and vertices shared by triangles of different regions are
duplicated (:func:`split_by_region`), so that each corner samples its own layer.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from mpeg4.camera import Camera
from mpeg4.unlit import render_depth
from mpeg4.head import Head

from .cameras import FittedCamera

__all__ = ["REGIONS", "FRONT", "SEEN", "MIRRORED", "HIDDEN", "FOLD", "feature_polygon", "vertex_regions",
           "triangle_regions", "split_by_region"]

#: Texture regions of the skin: which layer a triangle samples.
REGIONS = ("front", "seen side", "mirrored side", "hidden", "fold")
FRONT, SEEN, MIRRORED, HIDDEN, FOLD = range(5)

_VISIBLE_TOL = 0.003  # metres: a vertex this close behind the nearest surface is seen
_FOLD = 0.004  # metres: hidden skin this close to seen skin is a fold and takes its colour


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
