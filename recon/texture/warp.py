"""The side photo deformed onto the front photo's frame along a feature line.

The warp of Lee et al.'s texture generation (section 2.2.1): the side photo's feature line
— points from the top of the skull down the side of the face and the neck — is laid onto
the same line in the front photo, and what lies behind the line unrolls outwards beside the
face. :class:`FeatureLineWarp` is that map, piecewise affine over a triangulation of control
points on and around the line, used both ways: side-photo pixels of the head's vertices to
the composite frame (their texture coordinates), and composite pixels back to the side photo
(the warped image).

References
----------
W.-S. Lee and N. Magnenat-Thalmann, "Fast head modeling for animation", Image and Vision
Computing 18(4), 2000, section 2.2.1.
"""

from __future__ import annotations

import cv2
import numpy as np

from mpeg4.errors import InputError

from .cameras import FittedCamera

__all__ = ["FEATURE_LINE", "FeatureLineWarp", "sections", "convex_outline"]

#: The feature points of the feature line on the face's left, from the top of the skull to
#: the ear's front at the lobe (Lee et al. end it at the angle of the jaw; since 2.13 is
#: the gonion, 20 mm in front of the lobe and 32 mm below it, a line ending there gave the
#: side of the jaw to the front photo at a grazing angle: on ten synthetic people the lit
#: reprojection fell 26.2 -> 25.5 dB, ending at 10.7 it is 26.8); below it the line runs
#: down the neck where it faces half way between the photos
#: (:func:`recon.texture.feature_line`). The right line is the mirror image.
FEATURE_LINE = ("11.4", "11.3", "4.5", "10.9", "10.7")

# Arc lengths (metres) behind (+) and in front of (−) the feature line at which a row's
# control points are placed; _FAR makes the warp cover the whole photo.
_ARC = (-0.06, -0.03, -0.015, 0.0, 0.01, 0.02, 0.035, 0.055, 0.08, 0.11, 0.15, 0.2, 0.26)
_FAR = 1.5
# Rows of control points added above the top and below the bottom of the line (metres).
_ABOVE, _BELOW = (0.05, 1.0), (0.02, 0.04, 0.06, 0.09, 0.12, 0.16, 1.0)
_K0 = 1 + _ARC.index(0.0)  # a row's anchor among its points (after the far one)


class FeatureLineWarp:
    """A side photo deformed onto the front photo's frame along a feature line.

    The control points lie on rows, one through each feature-line point and through
    points between them (every ``row_step`` metres), more below the chin and above the
    skull. A row follows the head's horizontal outline at its height (the convex hull of
    the skin's cross-section) backwards and forwards from the line: each of its points is
    placed in the side photo where the side camera sees that point of the outline, and in
    the composite frame where the front camera sees the row's anchor; from there the
    outline unrolls outwards at the front photo's scale, so that the cheek behind the
    line and the back of the head spread beside the face instead of being squeezed into
    the few pixels the front photo gives skin it sees edge-on. (Rows below the line,
    anchored on the front midline, follow the front view out to the outline's silhouette.) Beyond the outline's ends (the back
    and front midlines) and on rows with no outline (above the skull), rows continue
    straight along the head's depth (side photo) and width (front photo). Every row keeps
    its anchor's height in each photo, and consecutive rows are joined by two triangles per
    pair of neighbouring points, so no triangle can fold; each triangle of the side photo
    maps affinely onto the same triangle of composite points — one piecewise-affine map,
    exactly invertible, so vertex coordinates (:meth:`forward`) and the warped image
    (:meth:`inverse_map`) agree, and near the line they agree with the front photo's own
    projection of the head.

    Parameters
    ----------
    side, front : FittedCamera
        The cameras of the side photo (or of the flipped side photo) and of the front one.
    line : (K, 3) float
        The feature line, top to bottom, metres (:func:`feature_line`).
    line_fp : (K,) bool
        Which of its points are feature points (they are never left out).
    outward : {+1, -1}
        +1 when the line is on the face's left (behind it lies +x), -1 on its right.
    skin : (vertices, triangles), optional
        The head's skin, for the outlines; without it every row is straight.
    row_step : float
        Largest height step between rows along the line, metres.
    """

    def __init__(self, side: FittedCamera, front: FittedCamera, line: np.ndarray, line_fp: np.ndarray,
                 outward: float, skin: tuple[np.ndarray, np.ndarray] | None = None, row_step: float = 0.01):
        where = "texture, feature line"
        self._side, self._front, self._sigma = side, front, float(outward)
        X = np.asarray(line, dtype=np.float64)
        line_fp = np.asarray(line_fp, dtype=bool)
        # Anchors: the line's points and points between them, then rows below its end.
        anchors, is_fp = [X[0]], [bool(line_fp[0])]
        for a, b, fb in zip(X[:-1], X[1:], line_fp[1:]):
            k = max(1, int(np.ceil(np.linalg.norm(a - b) / row_step)))
            anchors += [a + (b - a) * (j / k) for j in range(1, k + 1)]
            is_fp += [False] * (k - 1) + [bool(fb)]
        anchors = _descending(np.array(anchors), np.array(is_fp), side, front)
        last = anchors[-1]
        below = [last - np.array([0.0, h, 0.0]) for h in _BELOW]
        mesh = None
        if skin is not None:
            heights = np.array([a[1] for a in anchors] + [b[1] for b in below])
            mesh = dict(zip(heights.tolist(), sections(np.asarray(skin[0], float), np.asarray(skin[1]), heights)))
        rows = [self._straight_row(X[0], lift) for lift in reversed(_ABOVE)]
        for x in anchors:
            rows.append(self._outline_row(mesh, x) if mesh is not None else None)
            if rows[-1] is None:
                rows[-1] = self._straight_row(x, 0.0)
        for h, b in zip(_BELOW, below):
            row = self._outline_row(mesh, b, midline=True) if mesh is not None and h < 0.5 else None
            rows.append(row if row is not None else self._straight_row(last, -h))
        src = np.array([r[0] for r in rows])  # (R, C, 2)
        dst = np.array([r[1] for r in rows])
        for k, name, pts in ((0, "side", src), (1, "front", dst)):
            v = pts[:, 0, 1]
            if (np.diff(v) <= 0).any():
                raise InputError(f"the feature line does not run downwards in the {name} photo", where=where,
                                 fix=f"check the heights of {', '.join(FEATURE_LINE)} in the {name} photo")
        n_rows, n_cols = src.shape[:2]
        self._shape = (n_rows, n_cols)
        self.source = src.reshape(-1, 2)
        self.target = dst.reshape(-1, 2)
        k = np.arange(n_rows * n_cols).reshape(n_rows, n_cols)
        a, b, c, d = k[:-1, :-1], k[:-1, 1:], k[1:, :-1], k[1:, 1:]
        self.simplices = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[b.ravel(), d.ravel(), c.ravel()]]
        a_s = _signed_areas(self.source, self.simplices)
        a_t = _signed_areas(self.target, self.simplices)
        self.folded = int(np.sum(np.sign(a_s) != np.sign(a_t)))
        if self.folded:
            raise InputError(f"the side photo's feature line folds over itself when laid on the front photo's "
                             f"({self.folded} triangles flip)", where=where,
                             fix="check the positions of " + ", ".join(FEATURE_LINE) + " in both photos")

    # Rows: (C, 2) side pixels and (C, 2) composite pixels, at _ARC offsets then the far ones.
    def _directions(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Side-photo pixels per metre towards the back of the head, and front-photo pixels
        per metre outwards, at a point."""
        d = 0.01
        s0, s1 = self._side.project(np.array([x, x + [0.0, 0.0, -d]]))
        f0, f1 = self._front.project(np.array([x, x + [self._sigma * d, 0.0, 0.0]]))
        return (s1 - s0) / d, (f1 - f0) / d

    def _straight_row(self, x: np.ndarray, lift: float):
        d = 0.01
        up = np.array([0.0, d, 0.0])
        s0, s1 = self._side.project(np.array([x, x + up]))
        f0, f1 = self._front.project(np.array([x, x + up]))
        s0 = s0 + (s1 - s0) * (lift / d)
        f0 = f0 + (f1 - f0) * (lift / d)
        ds, df = self._directions(x)
        t = np.r_[-_FAR, _ARC, _FAR]
        # Rows are horizontal in both photos (so that they cannot cross).
        return (np.c_[s0[0] + ds[0] * t, np.full(len(t), s0[1])],
                np.c_[f0[0] + df[0] * t, np.full(len(t), f0[1])])

    def _outline_row(self, sections, x: np.ndarray, midline: bool = False):
        """The row along the head's outline at the height of ``x`` (None when the section
        is too small to follow)."""
        xz = sections.get(float(x[1]))
        if xz is None or len(xz) < 8:
            return None
        hull = convex_outline(xz)
        if hull is None:  # a flat section: nothing to follow
            return None
        ring = np.vstack([hull, hull[:1]])
        seglen = np.linalg.norm(np.diff(ring, axis=0), axis=1)
        if seglen.sum() < 0.05:
            return None
        cum = np.concatenate([[0.0], np.cumsum(seglen)])
        perimeter = cum[-1]
        zc = 0.5 * (hull[:, 1].min() + hull[:, 1].max())
        sig = self._sigma

        rx, rz = ring[:, 0].copy(), ring[:, 1].copy()

        def at(s):
            s = np.mod(np.atleast_1d(s), perimeter)
            return np.stack([np.interp(s, cum, rx), np.interp(s, cum, rz)], axis=-1)

        # Arc position of the anchor (the nearest place on the outline).
        if midline:
            s_a = self._crossing(at, cum, perimeter, ring, front=True)
            if s_a is None:
                return None
        else:
            q = np.asarray(x)[[0, 2]]
            p0, p1 = ring[:-1], ring[1:]
            dvec = p1 - p0
            t = np.clip(((q - p0) * dvec).sum(axis=1) / np.maximum((dvec ** 2).sum(axis=1), 1e-18), 0, 1)
            dist = np.linalg.norm(p0 + t[:, None] * dvec - q, axis=1)
            j = int(np.argmin(dist))
            s_a = cum[j] + t[j] * seglen[j]
        step = 1e-3
        fine = np.arange(0.0, perimeter, 1e-3)
        n = len(fine)
        # One look-up for every point the row needs of the outline: the anchor's two steps
        # (which way is backwards), then the walks back and forward from it.
        walk = at(s_a + np.concatenate([[step, -step], fine, -fine]))
        theta = np.arctan2(sig * walk[:2, 0], walk[:2, 1] - zc)
        direction = 1.0 if theta[0] > theta[1] else -1.0
        back_pts, fwd_pts = (walk[2:2 + n], walk[2 + n:]) if direction > 0 else (walk[2 + n:], walk[2:2 + n])
        # How far the outline runs back to the back midline and forward to the front midline.
        L_back = _first_crossing(fine, sig * back_pts[:, 0], back_pts[:, 1] < zc)
        L_front = _first_crossing(fine, sig * fwd_pts[:, 0], fwd_pts[:, 1] > zc)
        if midline:
            L_front = 0.0
        # The front view's silhouette: the outline's widest point between the midlines
        # (arc offsets -fine forwards, +fine backwards: the walks' points).
        ahead, behind = fine <= L_front, fine <= L_back
        span = np.concatenate([-fine[ahead][::-1], fine[behind]])
        span_x = np.concatenate([fwd_pts[ahead][::-1, 0], back_pts[behind, 0]])
        widest = span[int(np.argmax(sig * span_x))]
        # Behind a feature-line anchor the outline unrolls from the anchor itself: between
        # it and the silhouette the front photo's own frame would squeeze the skin into a
        # few pixels. The rows below the line (anchored on the front midline) keep the
        # front frame out to the silhouette.
        s_sil = max(widest, 0.0) if midline else 0.0
        y = float(x[1])
        # The row's points at the arc offsets (clamped to the outline's ends), the silhouette
        # point and the anchor, with the anchor's steps for :meth:`_directions`: one
        # projection per camera.
        arc = np.asarray(_ARC, float)
        tt = np.minimum(np.maximum(arc, -L_front), L_back)
        q = at(s_a + direction * np.concatenate([tt, [s_sil, 0.0]]))
        p = np.stack([q[:, 0], np.full(len(q), y), q[:, 1]], axis=1)
        anchor3 = p[-1] if midline else np.asarray(x, float)
        d = 0.01
        side = self._side.project(np.vstack([anchor3, anchor3 + [0.0, 0.0, -d], p[:-2]]))
        front = self._front.project(np.vstack([anchor3, anchor3 + [sig * d, 0.0, 0.0], p[:-1]]))
        s_anchor, f_anchor = side[0], front[0]
        ds, df = (side[1] - side[0]) / d, (front[1] - front[0]) / d
        side_u = side[2:, 0] + ds[0] * (arc - tt)
        on_face = front[2:-1, 0] + df[0] * (arc - tt)  # beyond the front midline: straight on
        past_silhouette = front[-1, 0] + df[0] * (arc - s_sil)
        comp_x = np.where(tt <= s_sil, on_face, past_silhouette)
        side_u = _monotone(side_u, np.sign(ds[0]) or 1.0)
        comp_x = _monotone(comp_x, np.sign(df[0]) or 1.0)
        # The far points continue the row's ends straight on.
        su = np.concatenate([[side_u[0] + ds[0] * (-_FAR - _ARC[0])], side_u, [side_u[-1] + ds[0] * (_FAR - _ARC[-1])]])
        cx = np.concatenate([[comp_x[0] + df[0] * (-_FAR - _ARC[0])], comp_x, [comp_x[-1] + df[0] * (_FAR - _ARC[-1])]])
        if not midline:
            # Exact at the anchor (a feature-line point): its own pixels in both photos.
            su[_K0], cx[_K0] = s_anchor[0], f_anchor[0]
            su = _monotone(su, np.sign(ds[0]) or 1.0, keep=_K0)
            cx = _monotone(cx, np.sign(df[0]) or 1.0, keep=_K0)
        return (np.stack([su, np.full(len(su), s_anchor[1])], axis=1),
                np.stack([cx, np.full(len(cx), f_anchor[1])], axis=1))

    @staticmethod
    def _crossing(at, cum, perimeter, ring, front: bool):
        """Arc position where the outline crosses the midline x = 0 at its front (or back)."""
        fine = np.arange(0.0, perimeter, 2.5e-4)
        p = at(fine)
        sgn = np.sign(p[:, 0])
        idx = np.flatnonzero(sgn[:-1] * sgn[1:] <= 0)
        if not len(idx):
            return None
        zs = p[idx, 1]
        j = idx[int(np.argmax(zs))] if front else idx[int(np.argmin(zs))]
        return float(fine[j])

    def forward(self, side_px: np.ndarray) -> np.ndarray:
        """(K, 2) composite-frame pixels of (K, 2) side-photo pixels."""
        p = np.asarray(side_px, dtype=np.float64).reshape(-1, 2)
        return _piecewise_affine(p, self.source, self.target, self._shape, self.simplices)

    def inverse_map(self, grid_to_composite: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        """(H, W, 2) float32 side-photo pixels for a grid of composite-frame points.

        Parameters
        ----------
        grid_to_composite : (3, 3) float
            Affine map (homogeneous) from the grid's pixel (x, y) to composite pixels.
        size : (height, width)
            The grid. Points outside the warp get (-1, -1).
        """
        h, w = int(size[0]), int(size[1])
        g = np.asarray(grid_to_composite, dtype=np.float64)
        xs, ys = np.arange(w, dtype=np.float64)[None, :], np.arange(h, dtype=np.float64)[:, None]
        grid = np.stack([(g[k, 0] * xs + g[k, 1] * ys + g[k, 2]).ravel() for k in range(2)], axis=1)
        # The composite frame's rows are horizontal too: the same search as forward's, the
        # other way (no rasterising of the triangles).
        out = _piecewise_affine(grid, self.target, self.source, self._shape, self.simplices, outside=-1.0)
        return out.reshape(h, w, 2).astype(np.float32)


def _piecewise_affine(p: np.ndarray, frm: np.ndarray, to: np.ndarray, shape: tuple[int, int], simplices: np.ndarray,
                      outside: float | None = None) -> np.ndarray:
    """(K, 2) images of points (K, 2) under the piecewise-affine map taking the control
    grid ``frm`` onto ``to`` ((R x C, 2) pixels, row-major, ``shape`` = (R, C)) triangle by
    triangle (``simplices``: each quad's (a, b, c) halves, then all its (b, d, c) halves).

    Every row of ``frm`` is horizontal and the rows run downwards, so a point's row is one
    search by height, its quad one count of the quads' sides left of it at that height and
    its half the side of the quad's diagonal it lies on. Points beyond the grid get
    ``outside``, or (None) the nearest quad's affine map extended.
    """
    n_rows, n_cols = shape
    n_quads = (n_rows - 1) * (n_cols - 1)
    gx = frm[:, 0].reshape(n_rows, n_cols)
    v_rows = frm[::n_cols, 1]
    x, y = p[:, 0], p[:, 1]
    r = np.clip(np.searchsorted(v_rows, y) - 1, 0, n_rows - 2)
    a = (y - v_rows[r]) / (v_rows[r + 1] - v_rows[r])
    # Where the quads' sides cross the point's height, left to right (or right to left),
    # one side at a time: (C, R - 1) tables looked up per point, far faster than (K, C) rows.
    low, rise = np.ascontiguousarray(gx[:-1].T), np.ascontiguousarray(np.diff(gx, axis=0).T)
    first, last = low[0][r] + rise[0][r] * a, low[-1][r] + rise[-1][r] * a
    sign = np.where(last >= first, 1.0, -1.0)
    sx = x * sign
    before = np.zeros(len(p), np.int64)  # sides lying before the point
    for k in range(n_cols):
        before += (low[k][r] + rise[k][r] * a) * sign < sx
    quad = r * (n_cols - 1) + np.clip(before - 1, 0, n_cols - 2)
    # The (a, b, c) half holds the point when it lies on a's side of the quad's diagonal b–c.
    qa, qb, qc = (frm[simplices[:n_quads, k]] for k in range(3))  # (Q, 2) each
    e, ab = qc - qb, qa - qb
    side_a = e[:, 0] * ab[:, 1] - e[:, 1] * ab[:, 0]
    side_p = e[quad, 0] * (y - qb[quad, 1]) - e[quad, 1] * (x - qb[quad, 0])
    tri = quad + np.where(side_p * side_a[quad] < 0, n_quads, 0)
    # Each triangle's affine map, (T, 2, 3): to = M [frm; 1], applied by a look-up per point.
    corners = np.concatenate([frm[simplices], np.ones(simplices.shape + (1,))], axis=2)  # (T, 3, 3)
    M = np.einsum("tec,tcd->tde", np.linalg.inv(corners), to[simplices])
    out = np.empty_like(p)
    for k in range(2):
        out[:, k] = M[:, k, 0][tri] * x + M[:, k, 1][tri] * y + M[:, k, 2][tri]
    if outside is not None:
        out[(y < v_rows[0]) | (y > v_rows[-1]) | (first * sign > sx) | (last * sign < sx)] = outside
    return out


def _descending(anchors: np.ndarray, is_fp: np.ndarray, side: FittedCamera, front: FittedCamera,
                min_gap_px: float = 2.0) -> list[np.ndarray]:
    """The anchors whose rows run strictly downwards in both photos, top to bottom.

    A person's feature line need not descend everywhere (the outer brow may sit lower than
    where the ear joins the head); rows must, so anchors are taken by height and one that
    would not sit at least ``min_gap_px`` below the previous row in both photos is left
    out — a point between feature points first, a feature point only when two of them
    share a height.
    """
    order = np.argsort(-anchors[:, 1], kind="stable")
    a, fp = anchors[order], is_fp[order]
    vs, vf = side.project(a)[:, 1], front.project(a)[:, 1]
    keep = []
    for k in range(len(a)):
        if keep:
            j = keep[-1]
            if vs[k] - vs[j] < min_gap_px or vf[k] - vf[j] < min_gap_px:
                if fp[k] and not fp[j]:
                    keep[-1] = k  # a feature point displaces the point between them
                continue
        keep.append(k)
    return [a[k] for k in keep]


def sections(vertices: np.ndarray, triangles: np.ndarray, heights: np.ndarray) -> list[np.ndarray]:
    """For each height, the (K, 2) (x, z) points where the mesh's edges cross the plane
    y = height (the cross-section's outline, unordered)."""
    tri = np.asarray(triangles)
    # Every triangle's three edges; an edge shared by two triangles gives its crossing twice,
    # which neither a hull nor a widest point minds (and saves sorting the edges).
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    # Heights first: only the crossing edges need their whole ends.
    ya, yb = vertices[edges[:, 0], 1], vertices[edges[:, 1], 1]
    lo, hi = np.minimum(ya, yb), np.maximum(ya, yb)
    heights = np.asarray(heights, float)
    # Each edge crosses the heights y with lo < y <= hi: a run of the sorted heights, found
    # by two searches instead of a test of every edge at every height.
    order = np.argsort(heights, kind="stable")
    sorted_h = heights[order]
    first = np.searchsorted(sorted_h, lo, side="right")
    count = np.searchsorted(sorted_h, hi, side="right") - first
    edge = np.repeat(np.arange(len(edges)), count)
    k = np.arange(len(edge)) - np.repeat(np.cumsum(count) - count, count) + np.repeat(first, count)
    which = order[k]  # the height each crossing belongs to
    y = heights[which]
    a, b = vertices[edges[edge, 0]], vertices[edges[edge, 1]]
    t = (y - a[:, 1]) / (b[:, 1] - a[:, 1])
    p = (a + t[:, None] * (b - a))[:, [0, 2]]
    # Grouped by height, each group's crossings in edge order (as the per-height test gave).
    by = np.argsort(which, kind="stable")
    return np.split(p[by], np.cumsum(np.bincount(which, minlength=len(heights)))[:-1])


def convex_outline(points: np.ndarray) -> np.ndarray | None:
    """(K, 2) corners of the convex hull of (N, 2) points, in order around it; None when
    they span no area (fewer than three corners).

    OpenCV's hull (on float32 copies, the corners taken from the float64 points): a tenth
    of qhull's time on the few hundred points of a cross-section.
    """
    if len(points) < 3:
        return None
    corners = cv2.convexHull(np.asarray(points, np.float32), returnPoints=False).reshape(-1)
    return np.asarray(points)[corners] if len(corners) >= 3 else None


def _first_crossing(s: np.ndarray, signed_x: np.ndarray, right_end: np.ndarray) -> float:
    """First arc length at which a walk along the outline reaches the midline (signed x
    turns negative) on the expected end (back or front); the walk's end otherwise."""
    hit = np.flatnonzero((signed_x <= 0) & right_end)
    return float(s[hit[0]]) if len(hit) else float(s[-1])


def _monotone(values: np.ndarray, sign: float, keep: int | None = None) -> np.ndarray:
    """The values made increasing along ``sign``, keeping every row's points in order.

    Without ``keep``, a running maximum (then nudged to be strict). With ``keep``, that
    value stays as it is and the others give way: a running maximum after it, a running
    minimum before it (the anchor of a row is a feature point, exact in both photos).
    """
    v = np.asarray(values, float) * sign
    if keep is None:
        v = np.maximum.accumulate(v)
        return (v + np.arange(len(v)) * 1e-6) * sign
    after = np.maximum.accumulate(v[keep:])
    before = np.minimum.accumulate(v[:keep + 1][::-1])[::-1]
    v = np.concatenate([before[:-1], after])
    steps = np.arange(len(v)) - keep
    return (v + steps * 1e-6) * sign


def _bary(p: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(K, 3) barycentric coordinates of points (K, 2) in triangles (K, 3, 2) (unclamped)."""
    v0, v1 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    d = p - c[:, 0]
    den = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    b1 = (d[:, 0] * v1[:, 1] - d[:, 1] * v1[:, 0]) / den
    b2 = (v0[:, 0] * d[:, 1] - v0[:, 1] * d[:, 0]) / den
    return np.c_[1.0 - b1 - b2, b1, b2]


def _signed_areas(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
