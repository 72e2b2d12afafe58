"""2D points cast back onto the mesh's surface (:func:`lift`).

Front points along the front ray, profile points where the side ray meets the mirror
plane, side-only points along the side ray (grazing rays take the rim they graze), pupils
on a separate eyeball at its front.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.head import Head
from mpeg4.io.fdp_json import FdpFile

from .frame import _combined
from .views import Views

__all__ = ["Hit", "lift"]


@dataclass
class Hit:
    """A feature point on the surface.

    Attributes
    ----------
    point : (3,) float64
        Neutral frame, metres.
    part : str
    triangle : int
        In the part.
    weights : (3,) float64
        Barycentric weights of the triangle's corners.
    confidence : float
        In [0, 1].
    how : str
        Which rule placed it (``front ray``, ``profile``, ``side ray``, ``mirrored``,
        ``eye front``; after :func:`fitted_points` ``fitted`` for a found point smoothed by
        the fitted generic head and ``shape`` for the fitted generic head's own; ``teeth``,
        ``tongue``, ``generic``).
    """

    point: np.ndarray
    part: str
    triangle: int
    weights: np.ndarray
    confidence: float
    how: str


class _Surface:
    """Ray and closest-point queries on all parts of a head (trimesh, built once)."""

    def __init__(self, head: Head):
        import trimesh

        self.names, v, t, self.part_of, self.local = _combined(head)
        self.mesh = trimesh.Trimesh(v, t, process=False, validate=False)
        self.vertices, self.triangles = v, t

    def cast(self, origins: np.ndarray, directions: np.ndarray, radius: float = 0.001):
        """First hit of each ray: (K,) triangle (−1 for none) and (K, 3) locations.

        A ray that passes within ``radius`` of the surface before it hits it (a point on a
        silhouette, such as the rim of an ear, seen edge-on) takes the surface point
        nearest to where it passes closest.
        """
        from scipy.spatial import cKDTree

        tri = np.full(len(origins), -1, dtype=np.int64)
        loc = np.full((len(origins), 3), np.nan)
        if not len(origins):
            return tri, loc
        t, r, p = self.mesh.ray.intersects_id(origins, directions, multiple_hits=False, return_locations=True)
        if len(r):  # with no hit at all trimesh gives the locations as an empty (0,) array
            tri[r], loc[r] = t, np.reshape(p, (-1, 3))
        if radius <= 0:
            return tri, loc
        if not hasattr(self, "_tree"):
            self._tree = cKDTree(self.vertices)
        reach = 4 * radius  # vertices this near the ray may carry a face nearer than radius
        for k in range(len(origins)):
            o, d = origins[k], directions[k] / np.linalg.norm(directions[k])
            far = np.inf if tri[k] < 0 else float((loc[k] - o) @ d)
            # The stretch of the ray inside the mesh's bounding sphere, up to the hit.
            mid = float((self.mesh.bounds.mean(axis=0) - o) @ d)
            half = 0.5 * float(np.linalg.norm(self.mesh.extents))
            stretch = np.arange(max(mid - half, 0.0), min(far, mid + half) + reach, reach)
            steps = o + np.outer(stretch, d)
            near = set()
            for ids in self._tree.query_ball_point(steps, 1.5 * reach):
                near.update(ids)
            if not near:
                continue
            ids = np.fromiter(near, dtype=np.int64)
            rel = self.vertices[ids] - o
            along = rel @ d
            off = np.linalg.norm(rel - np.outer(along, d), axis=1)
            ok = (off < reach) & (along < far - 2 * radius)
            if not ok.any():
                continue
            # Along the stretch where the ray passes those vertices, how near is the surface?
            a = along[ok]
            t_near = np.arange(max(a.min() - reach, 0.0), min(a.max() + reach, far - 2 * radius), radius / 2)
            if not len(t_near):
                continue
            c_tri, c_pt = self.closest(o + np.outer(t_near, d))
            gap = np.linalg.norm(c_pt - (o + np.outer(t_near, d)), axis=1)
            close = np.flatnonzero(gap < radius)
            if len(close):
                tri[k], loc[k] = c_tri[close[0]], c_pt[close[0]]
        return tri, loc

    def on_midline(self, points: np.ndarray):
        """Nearest point of the mesh's cut by the plane x = 0 (the profile curve) to each of
        (K, 3) points on that plane: (K,) triangles, (K, 3) points; the closest surface
        point where nothing crosses the plane."""
        import trimesh

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        try:
            seg, faces = trimesh.intersections.mesh_plane(self.mesh, [1.0, 0.0, 0.0], [0.0, 0.0, 0.0],
                                                          return_faces=True)
        except (ValueError, IndexError):
            seg = np.zeros((0, 2, 3))
        if not len(seg):
            return self.closest(points)
        a, b = seg[:, 0, 1:], seg[:, 1, 1:]  # (y, z) of each piece of the profile
        ab = b - a
        tri = np.empty(len(points), dtype=np.int64)
        out = np.empty_like(points)
        for k, q in enumerate(points[:, 1:]):
            s = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30), 0, 1)
            near = a + s[:, None] * ab
            j = int(np.argmin(np.sum((near - q) ** 2, axis=1)))
            tri[k], out[k] = faces[j], np.r_[seg[j, 0, 0] + s[j] * (seg[j, 1, 0] - seg[j, 0, 0]), near[j]]
        return tri, out

    def closest(self, points: np.ndarray, parts: list[str] | None = None):
        """Closest surface point (of the given parts) to each point: (K,) triangles, (K, 3) points."""
        import trimesh

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if parts is None:
            p, _, tri = trimesh.proximity.closest_point(self.mesh, points)
            return np.asarray(tri, dtype=np.int64), p
        return self._closest_among(points, np.flatnonzero(np.isin(self.part_of, [self.names.index(n) for n in parts])))

    def _closest_among(self, points: np.ndarray, keep: np.ndarray):
        """:meth:`closest` among the triangles ``keep`` (indices into all parts')."""
        import trimesh

        sub = trimesh.Trimesh(self.vertices, self.triangles[keep], process=False, validate=False)
        p, _, tri = trimesh.proximity.closest_point(sub, points)
        return keep[np.asarray(tri, dtype=np.int64)], p

    def closest_on_side(self, point: np.ndarray, towards: np.ndarray) -> tuple[int, np.ndarray]:
        """The closest surface point to ``point`` (3,) among the triangles wholly on the side
        of it that ``towards`` (3,) points to: (triangle, (3,) point)."""
        point = np.asarray(point, dtype=np.float64)
        ahead = (self.vertices - point) @ np.asarray(towards, dtype=np.float64) >= 0
        keep = np.flatnonzero(ahead[self.triangles].all(axis=1))
        tri, p = self._closest_among(point[None], keep) if len(keep) else self.closest(point[None])
        return int(tri[0]), p[0]

    def piece_of(self, h: Hit) -> np.ndarray:
        """Vertex ids (into all parts) of the connected piece a hit lies on."""
        if not hasattr(self, "_labels"):
            self._labels = _pieces(type("P", (), {"n_vertices": len(self.vertices), "triangles": self.triangles})())
        return np.flatnonzero(self._labels == self._labels[self.triangles[self.index(h)][0]])

    def index(self, h: Hit) -> int:
        """The hit's triangle among all parts'."""
        k = self.names.index(h.part)
        return int(np.flatnonzero((self.part_of == k) & (self.local == h.triangle))[0])

    def hit(self, tri: int, point: np.ndarray, confidence: float, how: str) -> Hit:
        import trimesh

        corners = self.vertices[self.triangles[tri]]
        w = trimesh.triangles.points_to_barycentric(corners[None], np.asarray(point)[None])[0]
        w = np.clip(w, 0.0, None)
        w /= w.sum()
        return Hit(w @ corners, self.names[self.part_of[tri]], int(self.local[tri]), w, float(confidence), how)


def _rays(camera, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origins (on the camera's plane) and directions of an orthographic camera's pixel rays."""
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    cx, cy = camera.principal
    local = np.c_[(pixels[:, 0] - cx) / camera.scale_px, -(pixels[:, 1] - cy) / camera.scale_px,
                  np.zeros(len(pixels))]
    origins = camera.centre + local @ camera.rotation
    return origins, np.tile(-camera.rotation[2], (len(pixels), 1))


#: Points on the rims of the face's openings (the inner lip contour, the eyelids and eye
#: corners): from the front their rays may run through the opening (parted lips, a mesh
#: without eyeballs) into the head.
RIM_POINTS = ("2.2", "2.3", "2.4", "2.5", "2.6", "2.7", "2.8", "2.9", "3.1", "3.2", "3.3", "3.4", "3.7", "3.8",
              "3.9", "3.10", "3.11", "3.12")


#: Rim points on the upper (+1) or lower (-1) edge of their opening.
_RIM_SIDE = {"2.2": 1.0, "2.6": 1.0, "2.7": 1.0, "3.1": 1.0, "3.2": 1.0,
             "2.3": -1.0, "2.8": -1.0, "2.9": -1.0, "3.3": -1.0, "3.4": -1.0}

_OPENING_PROBE = 0.003  # metres above and below a rim point where the surface is looked for
_OPENING_DEPTH = 0.008  # a hit this far behind the surface above and below went through an opening


def _through_openings(surface, camera, rays: dict) -> dict[str, float]:
    """The rim points whose front ray ran through an opening (its hit lies well behind the
    surface just above and below it, or it hit nothing), each with the depth along its ray
    of that surface."""
    if not rays:
        return {}
    ids = list(rays)
    up = camera.rotation[1]
    out = {}
    near = []
    for sign in (1.0, -1.0):
        o = np.array([rays[i][2] for i in ids]) + sign * _OPENING_PROBE * up
        d = np.array([rays[i][3] for i in ids])
        tri, loc = surface.cast(o, d, radius=0.0)
        near.append(np.where(tri >= 0, np.einsum("ij,ij->i", loc - o, d), np.inf))
    front_depth = np.minimum(*near)
    for k, i in enumerate(ids):
        tri, p, o, d = rays[i]
        depth = np.inf if tri < 0 else float((p - o) @ d)
        if np.isfinite(front_depth[k]) and depth > front_depth[k] + _OPENING_DEPTH:
            out[i] = float(front_depth[k])
    return out


def lift(head: Head, views: Views, found: FdpFile, surface: _Surface | None = None) -> dict[str, Hit]:
    """3D feature points on the surface from points found in the two renders.

    The rule per point (the catalogue's visibility): a profile point on the midline (side
    view ``P``) is where the side ray meets the mirror plane x = 0, moved to the nearest
    point of the profile curve (the mesh cut by that plane); a point clear in the front
    view is the front ray's first hit, its confidence lowered where the side view puts it
    elsewhere; a point only the side view shows clearly is the side ray's first hit (a ray
    grazing a rim takes the rim); its right partner (the side view shows the left) is the
    mirror image, snapped; a pupil on a separate eyeball is the eyeball's front (on a head
    whose eyes are named parts, wherever the detector put it).

    Parameters
    ----------
    head : Head
        The rendered head (neutral frame).
    views : Views
    found : FdpFile
        ``front`` and ``side`` views: FP id → pixel, with confidences (1 where absent).

    Returns
    -------
    dict of str to Hit
    """
    surface = surface or _Surface(head)
    front = found.views.get("front")
    side = found.views.get("side")
    fpx = {} if front is None else front.points
    spx = {} if side is None else side.points

    def conf(view, i):
        v = found.views.get(view)
        return 1.0 if v is None else float(v.confidence.get(i, 1.0))

    def cast(view, ids, radius):
        px = np.array([(fpx if view == "front" else spx)[i] for i in ids]).reshape(-1, 2)
        o, d = _rays(views.cameras[view], px)
        tri, loc = surface.cast(o, d, radius=radius)
        return {i: (t, p, o[k], d[k]) for k, (i, t, p) in enumerate(zip(ids, tri, loc))}

    out: dict[str, Hit] = {}
    profile = [i for i in spx if FEATURE_POINTS[i].side == "C" and FEATURE_POINTS[i].side_view == "P"]
    if profile:
        o, d = _rays(views.cameras["side"], np.array([spx[i] for i in profile]))
        # The side rays run along -x: they meet x = 0 at o + o_x * d / (-d_x)...
        t = -o[:, 0] / d[:, 0]
        on_plane = o + t[:, None] * d
        tri, snapped = surface.on_midline(on_plane)
        for k, i in enumerate(profile):
            gap = float(np.linalg.norm(snapped[k] - on_plane[k]))
            out[i] = surface.hit(tri[k], snapped[k], conf("side", i) * np.exp(-(gap / 0.003) ** 2), "profile")
    front_ids = [i for i in fpx if i not in out and FEATURE_POINTS[i].front != "N"
                 and not (FEATURE_POINTS[i].front == "~" and FEATURE_POINTS[i].side_view == "Y")]
    rays = cast("front", front_ids, 0.0)
    # A rim point whose ray ran through its opening is the rim: the surface nearest the ray
    # at the depth of the surface around it.
    through = _through_openings(surface, views.cameras["front"], {i: rays[i] for i in front_ids if i in RIM_POINTS})
    if through:
        ids = list(through)
        at = np.array([rays[i][2] + through[i] * rays[i][3] for i in ids])
        tris, pts = surface.closest(at)
        up = views.cameras["front"].rotation[1]
        for k, i in enumerate(ids):
            # An upper rim is on the surface above the opening, a lower one below it: with the
            # lips barely parted the nearest surface may be the other lip.
            side = _RIM_SIDE.get(i, 0.0)
            if side and side * float((pts[k] - at[k]) @ up) < 0:
                tris[k], pts[k] = surface.closest_on_side(at[k], side * up)
        rays.update({i: (tris[k], pts[k], rays[i][2], rays[i][3]) for k, i in enumerate(ids)})
    for i, (tri, p, o, d) in rays.items():
        if tri < 0:
            continue
        c = conf("front", i)
        if i in spx and FEATURE_POINTS[i].side_view == "Y":
            # The side view sees the same point at (depth, height): how far off is it?
            cam = views.cameras["side"]
            seen = cam.project(p[None])[0]
            gap_px = float(np.linalg.norm(seen - spx[i]))
            c *= float(np.exp(-(gap_px / cam.scale_px / 0.005) ** 2))
        out[i] = surface.hit(tri, p, c, "front ray")
    side_ids = [i for i in spx if i not in out and FEATURE_POINTS[i].side in ("C", "L")]
    # The side view sees the ears edge-on: a ray that grazes a rim takes the rim.
    for i, (tri, p, o, d) in cast("side", side_ids, 0.0015).items():
        if tri >= 0:
            out[i] = surface.hit(tri, p, conf("side", i), "side ray")
    # A pupil on a separate eyeball: the front of the cornea (an untextured eye shows no
    # pupil to a detector; a neutral eye looks straight ahead).
    for i in ("3.5", "3.6"):
        h = out.get(i)
        if h is None:
            continue
        eye = surface.piece_of(h)
        front = surface.vertices[eye]
        apex = front[np.argmax(front[:, 2])]
        if len(eye) < 0.5 * len(surface.vertices) and np.linalg.norm(apex - h.point) < 0.008:
            tri, snapped = surface.closest(apex[None], [h.part])
            out[i] = surface.hit(tri[0], snapped[0], h.confidence, "eye front")
    # Once the eyes are named parts (the last pass), a pupil is the front of its eyeball
    # wherever the detector put it; a detector far from it is trusted less.
    for i, role in (("3.5", "eye_l"), ("3.6", "eye_r")):
        h = out.get(i)
        if h is None or h.how == "eye front" or role not in head.parts:
            continue
        eye = head.parts[role].vertices
        tri, snapped = surface.closest(eye[np.argmax(eye[:, 2])][None], [role])
        near = np.linalg.norm(snapped[0] - h.point) < 0.008
        out[i] = surface.hit(tri[0], snapped[0], h.confidence * (1.0 if near else 0.5), "eye front")
    # Right partners of points only the (left) side view shows.
    partners = [(FEATURE_POINTS[i].mirror, i) for i in list(out) if FEATURE_POINTS[i].side == "L"
                and FEATURE_POINTS[i].mirror not in out and out[i].how == "side ray"]
    if partners:
        pts = np.array([out[i].point * [-1.0, 1.0, 1.0] for _, i in partners])
        tri, snapped = surface.closest(pts)
        for k, (j, i) in enumerate(partners):
            gap = float(np.linalg.norm(snapped[k] - pts[k]))
            out[j] = surface.hit(tri[k], snapped[k], 0.8 * out[i].confidence * np.exp(-(gap / 0.004) ** 2),
                                 "mirrored")
    return {i: out[i] for i in FP_IDS if i in out}


def _pieces(part) -> np.ndarray:
    """(N,) connected-piece label of each vertex of a part."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n, t = part.n_vertices, part.triangles
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]]]) if len(t) else np.zeros((0, 2), dtype=np.int64)
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    return connected_components(g, directed=False)[1]
