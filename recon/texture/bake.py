"""Texture-space rasterisation, baking and gap filling.

A texture layout is a set of triangles in texture coordinates. :func:`rasterize_uv` finds,
for every texel, the triangle it lies in and its barycentric coordinates, so that any
per-vertex quantity (a 3D position, a second set of texture coordinates) can be carried to
texels; :func:`bake` uses it to resample one textured layout into another (the ``--atlas``
re-packing). :func:`fill_empty` extends an image's valid pixels into the rest by a
push–pull pyramid, so that bilinear and mip-mapped sampling near the edge of a chart (or of
a head's silhouette in a photo) never picks up what lies beyond it.
"""

from __future__ import annotations

import cv2
import numpy as np

from mpeg4.errors import InputError

__all__ = ["uv_to_pixels", "rasterize", "rasterize_uv", "interpolate", "bake", "fill_empty", "dilate_charts"]

_SHIFT = 8  # sub-pixel bits for OpenCV's polygon filling


def uv_to_pixels(uv: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Texture coordinates to pixel coordinates.

    Parameters
    ----------
    uv : (..., 2) float
        (s, t) with t = 0 at the bottom row.
    size : (height, width)

    Returns
    -------
    (..., 2) float64
        (x, y) with the top-left pixel's centre at (0, 0).
    """
    h, w = size
    uv = np.asarray(uv, dtype=np.float64)
    return np.stack([uv[..., 0] * w - 0.5, (1.0 - uv[..., 1]) * h - 0.5], axis=-1)


def rasterize(corners: np.ndarray, triangles: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Which triangle covers each pixel, and where in it.

    Parameters
    ----------
    corners : (N, 2) float
        Pixel coordinates (x right, y down; the top-left pixel's centre at (0, 0)).
    triangles : (M, 3) int
        Corner indices into ``corners``.
    size : (height, width)

    Returns
    -------
    triangle : (H, W) int32
        Index of the covering triangle, -1 where none. Where triangles overlap, the later
        one wins.
    barycentric : (H, W, 3) float64
        Weights of the triangle's corners at the pixel centre (clamped to the triangle
        and summing to 1 where covered; 0 elsewhere).
    """
    h, w = int(size[0]), int(size[1])
    if h < 1 or w < 1:
        raise InputError(f"image size {w}x{h} is empty", where="rasterize", fix="give a positive size")
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    px = np.asarray(corners, dtype=np.float64).reshape(-1, 2)[tri]  # (M, 3, 2)
    fixed = np.round(px * (1 << _SHIFT)).astype(np.int32)
    ids = np.full((h, w), -1, dtype=np.int32)
    for k in range(len(tri)):
        cv2.fillConvexPoly(ids, fixed[k], int(k), lineType=cv2.LINE_8, shift=_SHIFT)
    bary = np.zeros((h, w, 3))
    ys, xs = np.nonzero(ids >= 0)
    if not len(ys):
        return ids, bary
    p = np.c_[xs, ys].astype(np.float64)
    b = _barycentric(p, px[ids[ys, xs]], clamp=False)
    # Polygon filling also takes pixels its edges merely touch: give such a texel the
    # neighbouring triangle (of the 3 x 3 around it) that really holds its centre.
    for _ in range(3):  # a texel's rightful neighbour may itself be put right in the pass before
        off = b.min(axis=1) < -1e-9
        if not off.any():
            break
        oy, ox, po = ys[off], xs[off], p[off]
        padded = np.pad(ids, 1, constant_values=-1)
        own = ids[oy, ox]
        best_t, best_b, best_m = own.copy(), b[off], b[off].min(axis=1)
        for dy, dx in ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)):
            t = padded[oy + 1 + dy, ox + 1 + dx]
            k = np.flatnonzero((t >= 0) & (t != own))  # the texel's own triangle cannot do better
            if not len(k):
                continue
            bj = _barycentric(po[k], px[t[k]], clamp=False)
            mj = bj.min(axis=1)
            better = mj > best_m[k]
            kb = k[better]
            best_t[kb], best_b[kb], best_m[kb] = t[kb], bj[better], mj[better]
        if (best_t == own).all():
            break
        ids[oy, ox] = best_t
        b[off] = best_b
    b = np.clip(b, 0.0, None)
    bary[ys, xs] = b / b.sum(axis=1, keepdims=True)
    return ids, bary


def rasterize_uv(uv: np.ndarray, triangles: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rasterize` for corners given as texture coordinates (t = 0 at the bottom)
    of a ``size`` = (height, width) texture."""
    return rasterize(uv_to_pixels(uv, size), triangles, size)


def _barycentric(p: np.ndarray, c: np.ndarray, clamp: bool = True) -> np.ndarray:
    """(K, 3) barycentric coordinates of points (K, 2) in triangles (K, 3, 2); with
    ``clamp`` clamped to the triangle (texels on its rim fall a hair outside) and
    renormalised."""
    v0, v1 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    d = p - c[:, 0]
    den = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    den = np.where(np.abs(den) < 1e-12, 1e-12, den)
    b1 = (d[:, 0] * v1[:, 1] - d[:, 1] * v1[:, 0]) / den
    b2 = (v0[:, 0] * d[:, 1] - v0[:, 1] * d[:, 0]) / den
    b = np.c_[1.0 - b1 - b2, b1, b2]
    if not clamp:
        return b
    b = np.clip(b, 0.0, None)
    return b / b.sum(axis=1, keepdims=True)


def interpolate(values: np.ndarray, triangles: np.ndarray, triangle: np.ndarray,
                barycentric: np.ndarray) -> np.ndarray:
    """Carry per-corner values to texels.

    Parameters
    ----------
    values : (N, C) float
        One row per corner (the indices ``triangles`` refers to).
    triangles : (M, 3) int
    triangle, barycentric
        From :func:`rasterize_uv`.

    Returns
    -------
    (H, W, C) float64
        Zero where no triangle covers the texel.
    """
    values = np.asarray(values, dtype=np.float64)
    values = values.reshape(len(values), -1)
    tri = np.asarray(triangles, dtype=np.int64)
    out = np.zeros(triangle.shape + (values.shape[1],))
    ys, xs = np.nonzero(triangle >= 0)
    corner = tri[triangle[ys, xs]]  # (K, 3)
    out[ys, xs] = np.einsum("kc,kcd->kd", barycentric[ys, xs], values[corner])
    return out


def fill_empty(image: np.ndarray, valid: np.ndarray, levels: int | None = None) -> np.ndarray:
    """Extend an image's valid pixels over the rest (push–pull).

    Valid pixels are kept exactly; every other pixel takes the colour of the nearest
    valid region, smoothly, from a pyramid of valid-weighted averages.

    Parameters
    ----------
    image : (H, W[, C]) array
    valid : (H, W) bool
        Pixels whose colour is known. At least one must be set.
    levels : int, optional
        Pyramid depth; enough to cover the whole image by default.

    Returns
    -------
    (H, W[, C]) array of the input dtype
    """
    valid = np.asarray(valid, dtype=bool)
    if not valid.any():
        raise InputError("no valid pixel to fill from", where="fill_empty",
                         fix="check that the mask covers part of the image")
    img = np.asarray(image)
    squeeze = img.ndim == 2
    f = img.astype(np.float32).reshape(img.shape[0], img.shape[1], -1)
    nc = f.shape[2]
    if levels is None:
        levels = int(np.ceil(np.log2(max(img.shape[:2])))) + 1
    # Push: valid-weighted averages down the pyramid, the weight as the last channel (one
    # resampling per level for both).
    base = np.empty(f.shape[:2] + (nc + 1,), np.float32)
    base[..., nc] = valid
    np.multiply(f, base[..., nc:], out=base[..., :nc])
    stack = [base]
    for _ in range(levels):
        if min(stack[-1].shape[:2]) <= 1:
            break
        stack.append(_down(stack[-1]))
    # Pull: fill each level's gaps from the coarser level's estimate. With the weight c of
    # a cell and a = min(c, 1), its estimate is a (sum / c) + (1 - a) coarser, that is
    # sum / max(c, 1) + (1 - a) coarser (the sum is 0 where c is).
    top = stack[-1]
    cw = top[..., nc]
    est = top[..., :nc] / np.maximum(cw, 1e-12)[..., None]
    # Cells of the coarsest level with no valid pixel under them take the overall mean
    # (the push keeps the ratio of the sums).
    total = top.reshape(-1, nc + 1).sum(axis=0, dtype=np.float64)
    est[cw <= 0] = (total[:nc] / total[nc]).astype(np.float32)
    for level in reversed(stack[:-1]):
        cw = level[..., nc:]
        est = cv2.resize(est, (cw.shape[1], cw.shape[0]), interpolation=cv2.INTER_LINEAR).reshape(cw.shape[:2] + (nc,))
        est *= 1.0 - np.minimum(cw, 1.0)
        est += level[..., :nc] / np.maximum(cw, 1.0)
    est = cv2.copyTo(f, valid.astype(np.uint8), est).reshape(f.shape)  # (numpy's masked copy is far slower)
    if np.issubdtype(img.dtype, np.integer):
        info = np.iinfo(img.dtype)
        est = np.clip(np.round(est), info.min, info.max)
    out = est.astype(img.dtype)
    return out[..., 0] if squeeze else out


def dilate_charts(image: np.ndarray, valid: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Grow the valid texels of a texture outwards, one ring per iteration, each new texel
    the mean of its valid neighbours: the gutter around every chart takes that chart's own
    colours, so filtering near its edge never mixes in another chart.

    Returns
    -------
    image : array of the input dtype
    valid : (H, W) bool
        The grown mask.
    """
    img = np.asarray(image).astype(np.float32)
    img = img.reshape(img.shape[0], img.shape[1], -1)
    ok = np.asarray(valid, dtype=bool).copy()
    kernel = np.ones((3, 3), np.float32)
    for _ in range(int(iterations)):
        w = ok.astype(np.float32)
        count = cv2.filter2D(w, -1, kernel, borderType=cv2.BORDER_CONSTANT)
        grow = (count > 0) & ~ok
        if not grow.any():
            break
        total = cv2.filter2D(img * w[..., None], -1, kernel, borderType=cv2.BORDER_CONSTANT)
        total = total.reshape(img.shape)
        img[grow] = total[grow] / count[grow][:, None]
        ok |= grow
    out = img.reshape(np.asarray(image).shape)
    if np.issubdtype(np.asarray(image).dtype, np.integer):
        out = np.clip(np.round(out), 0, 255)
    return out.astype(np.asarray(image).dtype), ok


def _down(a: np.ndarray) -> np.ndarray:
    """Sum-preserving 2x downsampling (a box of four), odd sizes padded with zeros."""
    h, w = a.shape[:2]
    if h % 2 or w % 2:
        a = cv2.copyMakeBorder(a, 0, h % 2, 0, w % 2, cv2.BORDER_CONSTANT, value=0)
    # OpenCV's area resampling of an exact halving is that box mean.
    out = cv2.resize(a, ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA)
    return out.reshape(out.shape[:2] + a.shape[2:])


def bake(source: np.ndarray, source_uv: np.ndarray, target_uv: np.ndarray, triangles_source: np.ndarray,
         triangles_target: np.ndarray, size: tuple[int, int], margin_fill: bool = True) -> np.ndarray:
    """Resample a texture from one layout into another of the same surface.

    Parameters
    ----------
    source : (Hs, Ws, 3) uint8
        The texture in the source layout (row 0 at the top).
    source_uv : (Ns, 2) float
        Source texture coordinates of the corners ``triangles_source`` refers to.
    target_uv : (Nt, 2) float
        Target texture coordinates of the corners ``triangles_target`` refers to.
    triangles_source, triangles_target : (M, 3) int
        The same M triangles, corner by corner, in each layout.
    size : (height, width)
        Size of the baked texture.
    margin_fill : bool
        Extend the charts into the empty texels (:func:`fill_empty`).

    Returns
    -------
    (H, W, 3) uint8
    """
    ts, tt = np.asarray(triangles_source), np.asarray(triangles_target)
    if ts.shape != tt.shape:
        raise InputError(f"{len(ts)} source triangles but {len(tt)} target triangles", where="bake",
                         fix="give the same triangles in both layouts")
    ids, bary = rasterize_uv(target_uv, tt, size)
    covered = ids >= 0
    # Per target corner, the source coordinate of the same triangle corner.
    src_px = uv_to_pixels(np.asarray(source_uv, dtype=np.float64), source.shape[:2])
    corner_src = src_px[ts]  # (M, 3, 2)
    ys, xs = np.nonzero(covered)
    where = np.einsum("kc,kcd->kd", bary[ys, xs], corner_src[ids[ys, xs]])
    map_xy = np.full(size + (2,), -1.0, dtype=np.float32)
    map_xy[ys, xs] = where
    out = cv2.remap(np.ascontiguousarray(source), map_xy[..., 0], map_xy[..., 1], cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    if margin_fill:
        out, grown = dilate_charts(out, covered, iterations=max(2, min(size) // 128))
        out = fill_empty(out, grown)
    return out
