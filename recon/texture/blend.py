"""Merging images under masks: the Burt–Adelson multiresolution spline, and the two blends
it replaces (a hard cut and a feathered edge) with a measure of how smooth seams are.

References
----------
P. J. Burt and E. H. Adelson, "A multiresolution spline with application to image
mosaics", ACM Transactions on Graphics 2(4), 1983.
"""

from __future__ import annotations

import cv2
import numpy as np

from mpeg4.errors import InputError

__all__ = ["blend_multiband", "blend_hard", "blend_feather", "seam_band", "seam_gradient"]


_REACH = 8  # a layer is fed within this many times 2^levels pixels of its mask


def _levels(shape, levels):
    # Five levels at 2048² (four at 1024²): the coarsest band spans about a tenth of the
    # face, enough to even out the photos' lighting across the seams without recolouring
    # the middle of the face (more levels reach further in; benchmarks/texture_fidelity.py).
    if levels is not None:
        return int(levels)
    return max(1, int(np.log2(min(shape[:2]))) - 6)


def blend_multiband(images, masks, levels: int | None = None, method: str = "opencv") -> np.ndarray:
    """Burt–Adelson multiresolution spline of images under complementary masks.

    Parameters
    ----------
    images : sequence of (H, W, 3) uint8
        Layers defined over the whole frame (fill what they cannot show beforehand).
    masks : sequence of (H, W) bool
        Where each layer is wanted; together they should cover the frame once.
    levels : int, optional
        Pyramid levels; ``log2(min(H, W)) - 6`` by default (4 at 1024², 5 at 2048²).
    method : {"opencv", "opencv-detail", "skimage"}
        OpenCV's multi-band blender's 16-bit spline: computed here band by band
        (:func:`_blend_opencv16`, the same bytes with less work; 8-bit RGB layers), or by
        the blender itself (``cv2.detail_MultiBandBlender``); or Laplacian and Gaussian
        pyramids built with scikit-image in floating point — the same spline; the
        benchmark compares their speed.

    Returns
    -------
    (H, W, 3) uint8
    """
    images = [np.asarray(i) for i in images]
    masks = [np.asarray(m, dtype=bool) for m in masks]
    if not images or len(images) != len(masks):
        raise InputError(f"{len(images)} images but {len(masks)} masks", where="blend_multiband",
                         fix="give one mask per image")
    h, w = images[0].shape[:2]
    for im, m in zip(images, masks):
        if im.shape[:2] != (h, w) or m.shape != (h, w):
            raise InputError("the images and masks differ in size", where="blend_multiband",
                             fix="bring every layer to the same frame first")
    n = _levels((h, w), levels)
    if method == "opencv" and all(im.dtype == np.uint8 and im.ndim == 3 and im.shape[2] == 3 for im in images):
        return _blend_opencv16(images, masks, n)
    if method in ("opencv", "opencv-detail"):
        blender = cv2.detail_MultiBandBlender(0, n)
        blender.prepare((0, 0, w, h))
        # Each layer is fed only around its mask (_fed_crop).
        for im, m in zip(images, masks):
            m8 = m.astype(np.uint8)
            fed = _fed_crop(m8, n)
            if fed is None:
                continue
            x0, y0, x1, y1 = fed[1]
            blender.feed(im[y0:y1, x0:x1].astype(np.int16), m8[y0:y1, x0:x1] * 255, (x0, y0))
        out, _ = blender.blend(None, None)
        return np.clip(out, 0, 255).astype(np.uint8)
    if method == "skimage":
        return _blend_skimage(images, masks, n)
    raise InputError(f"unknown blend method {method!r}", where="blend_multiband",
                     fix="use 'opencv', 'opencv-detail' or 'skimage'")


def _fed_crop(m8: np.ndarray, n: int):
    """The box (x, y, width, height) of a layer's (H, W) uint8 mask and the crop (x0, y0,
    x1, y1) of the layer fed to the blender around it, or None for an empty mask.

    The 5-tap kernels reach less than 2^(k+1) pixels by level k: the mask's weights and the
    layer's pyramid under them reach less than 6 x 2^levels pixels from the mask, so the
    rest of the layer cannot change the result."""
    h, w = m8.shape
    x, y, bw, bh = cv2.boundingRect(m8)
    if not bw:
        return None
    reach = _REACH << n
    return (x, y, bw, bh), (max(0, x - reach), max(0, y - reach), min(w, x + bw + reach), min(h, y + bh + reach))


def _feed_box(crop: tuple[int, int, int, int], frame: tuple[int, int], n: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) pixels that OpenCV's ``MultiBandBlender.feed`` works a layer's crop
    over: grown by 3 x 2^n, its corner and size made multiples of 2^n, kept within the
    (H, W) frame (itself a multiple of 2^n)."""
    x0, y0, x1, y1 = crop
    height, width = frame
    step, gap = 1 << n, 3 << n
    tx, ty = (max(0, x0 - gap) >> n) << n, (max(0, y0 - gap) >> n) << n
    bx = tx - (-(min(width, x1 + gap) - tx) // step) * step
    by = ty - (-(min(height, y1 + gap) - ty) // step) * step
    dx, dy = max(bx - width, 0), max(by - height, 0)
    return tx - dx, ty - dy, bx - dx, by - dy


def _blend_opencv16(images, masks, n: int) -> np.ndarray:
    """OpenCV's multi-band blender's spline (``cv2.detail_MultiBandBlender``: 16-bit bands,
    float weights, products and quotients truncated), the same arithmetic with less work.

    Parameters
    ----------
    images : sequence of (H, W, 3) uint8
    masks : sequence of (H, W) bool
    n : int
        Pyramid levels.

    Returns
    -------
    (H, W, 3) uint8
        The bytes :func:`blend_multiband` gets from OpenCV's blender fed the same way (each
        layer over its mask's box and ``8 x 2^n`` pixels around it).

    Notes
    -----
    The finest band's weights are the masks themselves, 0 or 1: that band is needed only
    inside each mask's box (one 2x expansion there instead of over the fed rectangle), and
    divided by a weight of 1 (+ OpenCV's 1e-5) and truncated it is x - sign(x). The
    Gaussian pyramids are 8-bit: OpenCV rounds 8- and 16-bit reductions and expansions the
    same way, so they hold the values of its 16-bit ones.
    """
    h, w = masks[0].shape
    n = min(n, int(np.ceil(np.log2(max(h, w)))))
    step = 1 << n
    height, width = -(-h // step) * step, -(-w // step) * step
    acc = [np.zeros((height >> k, width >> k, 3), np.int16) for k in range(n + 1)]
    wsum = [np.zeros((height >> k, width >> k), np.float32) for k in range(n + 1)]
    count = np.zeros((height, width), np.uint8)  # how many masks hold each pixel
    for im, m in zip(images, masks):
        m8 = m.astype(np.uint8)
        fed = _fed_crop(m8, n)
        if fed is None:
            continue
        (x, y, bw, bh), crop = fed
        cx0, cy0, cx1, cy1 = crop
        tx, ty, bx, by = _feed_box(crop, (height, width), n)
        border = (cy0 - ty, by - cy1, cx0 - tx, bx - cx1)
        g = [cv2.copyMakeBorder(im[cy0:cy1, cx0:cx1], *border, cv2.BORDER_REFLECT)]
        wt = [cv2.copyMakeBorder(m8[cy0:cy1, cx0:cx1], *border, cv2.BORDER_CONSTANT).astype(np.float32)]
        for _ in range(n):
            g.append(cv2.pyrDown(g[-1]))
            wt.append(cv2.pyrDown(wt[-1]))
        # The finest band inside the mask's box: the level below expanded over the box and
        # two coarse pixels around it (the expansion's reach).
        lx, ly = x - tx, y - ty
        ux0, uy0 = max(0, lx // 2 - 2), max(0, ly // 2 - 2)
        ux1, uy1 = min(g[1].shape[1], (lx + bw + 1) // 2 + 2), min(g[1].shape[0], (ly + bh + 1) // 2 + 2)
        up = cv2.pyrUp(g[1][uy0:uy1, ux0:ux1], dstsize=(2 * (ux1 - ux0), 2 * (uy1 - uy0)))
        box = np.s_[y:y + bh, x:x + bw]
        band = cv2.subtract(im[box], up[ly - 2 * uy0:ly - 2 * uy0 + bh, lx - 2 * ux0:lx - 2 * ux0 + bw],
                            dtype=cv2.CV_16S)
        cv2.add(acc[0][box], band, dst=acc[0][box], mask=m8[box])
        cv2.add(count[box], m8[box], dst=count[box])
        for k in range(1, n + 1):
            if k < n:
                band = cv2.subtract(g[k], cv2.pyrUp(g[k + 1], dstsize=g[k].shape[1::-1]), dtype=cv2.CV_16S)
            else:
                band = g[k].astype(np.int16)
            roi = np.s_[ty >> k:by >> k, tx >> k:bx >> k]
            # Truncated, as OpenCV's; (h, 3w) planes, which numpy multiplies far faster than
            # it broadcasts a weight over (h, w, 3).
            weighted = band.reshape(len(band), -1) * np.repeat(wt[k], 3, axis=1)
            acc[k][roi] += weighted.astype(np.int16).reshape(band.shape)
            wsum[k][roi] += wt[k]
    eps = np.float32(1e-5)  # OpenCV's WEIGHT_EPS
    overlap = np.nonzero(count > 1) if cv2.countNonZero(cv2.compare(count, 1, cv2.CMP_GT)) else None
    if overlap is not None:  # masks that overlap: the quotient itself there
        exact = (acc[0][overlap] / (count[overlap].astype(np.float32) + eps)[:, None]).astype(np.int16)
    flat = acc[0].reshape(height, -1)
    cv2.subtract(flat, 1, dst=flat, mask=cv2.compare(flat, 0, cv2.CMP_GT))
    cv2.add(flat, 1, dst=flat, mask=cv2.compare(flat, 0, cv2.CMP_LT))
    if overlap is not None:
        acc[0][overlap] = exact
    for k in range(1, n + 1):
        quotient = acc[k].reshape(len(acc[k]), -1) / np.repeat(wsum[k] + eps, 3, axis=1)
        acc[k] = quotient.astype(np.int16).reshape(acc[k].shape)
    out = acc[n]
    for k in range(n - 1, -1, -1):
        out = cv2.add(cv2.pyrUp(out, dstsize=acc[k].shape[1::-1]), acc[k])
    out = out[:h, :w]
    if cv2.countNonZero(count[:h, :w]) < h * w:
        out[count[:h, :w] == 0] = 0  # OpenCV blanks what no mask holds
    return cv2.convertScaleAbs(cv2.max(out, 0))  # clipped to bytes (the absolute value of >= 0 is itself)


def _blend_skimage(images, masks, levels: int) -> np.ndarray:
    """The spline with scikit-image's pyramid steps: G_{k+1} = reduce(G_k),
    L_k = G_k - expand(G_{k+1}), the coarsest G_n kept; blended per level with the mask's
    Gaussian pyramid and collapsed by G_k = L_k + expand(G_{k+1})."""
    from skimage.transform import pyramid_expand, pyramid_reduce

    def expand(a, shape):
        up = pyramid_expand(a, upscale=2, channel_axis=-1 if a.ndim == 3 else None)
        pad = [(0, max(0, shape[0] - up.shape[0])), (0, max(0, shape[1] - up.shape[1]))] + [(0, 0)] * (a.ndim - 2)
        return np.pad(up, pad, mode="edge")[:shape[0], :shape[1]]

    acc = weight = None
    for im, m in zip(images, masks):
        g = [im.astype(np.float64) / 255.0]
        gm = [m.astype(np.float64)]
        for _ in range(levels):
            g.append(pyramid_reduce(g[-1], downscale=2, channel_axis=-1))
            gm.append(pyramid_reduce(gm[-1], downscale=2))
        lap = [g[k] - expand(g[k + 1], g[k].shape) for k in range(levels)] + [g[-1]]
        if acc is None:
            acc = [np.zeros_like(x) for x in lap]
            weight = [np.zeros(x.shape[:2]) for x in lap]
        for k in range(len(lap)):
            acc[k] += lap[k] * gm[k][..., None]
            weight[k] += gm[k]
    acc = [a / np.maximum(wt, 1e-12)[..., None] for a, wt in zip(acc, weight)]
    out = acc[-1]
    for k in range(len(acc) - 2, -1, -1):
        out = acc[k] + expand(out, acc[k].shape)
    return np.clip(np.round(out * 255.0), 0, 255).astype(np.uint8)


def blend_hard(images, masks) -> np.ndarray:
    """Each pixel from the layer whose mask holds it (the seams' worst case)."""
    out = np.zeros_like(np.asarray(images[0]))
    for im, m in zip(images, masks):
        out[np.asarray(m, dtype=bool)] = np.asarray(im)[np.asarray(m, dtype=bool)]
    return out


def blend_feather(images, masks, width: float = 16.0) -> np.ndarray:
    """Alpha blend with masks blurred over ``width`` pixels (a feathered edge)."""
    acc = np.zeros(np.asarray(images[0]).shape, dtype=np.float64)
    total = np.zeros(acc.shape[:2])
    for im, m in zip(images, masks):
        a = cv2.GaussianBlur(np.asarray(m, dtype=np.float64), (0, 0), max(width / 2.0, 0.5))
        acc += a[..., None] * np.asarray(im, dtype=np.float64)
        total += a
    return np.clip(np.round(acc / np.maximum(total, 1e-12)[..., None]), 0, 255).astype(np.uint8)


def seam_band(masks, width: int = 8, within: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: pixels within ``width`` of a border between two masks (optionally only
    inside ``within``)."""
    label = np.zeros(np.asarray(masks[0]).shape, dtype=np.int32)
    for k, m in enumerate(masks):
        label[np.asarray(m, dtype=bool)] = k + 1
    edge = np.zeros(label.shape, dtype=bool)
    edge[:, 1:] |= label[:, 1:] != label[:, :-1]
    edge[1:, :] |= label[1:, :] != label[:-1, :]
    band = cv2.dilate(edge.astype(np.uint8), np.ones((2 * width + 1, 2 * width + 1), np.uint8)) > 0
    return band & within if within is not None else band


def seam_gradient(image: np.ndarray, band: np.ndarray) -> float:
    """Mean gradient magnitude (grey levels per pixel) of an image inside a band."""
    g = cv2.cvtColor(np.asarray(image), cv2.COLOR_RGB2GRAY).astype(np.float64)
    gx = cv2.Sobel(g, cv2.CV_64F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(g, cv2.CV_64F, 0, 1, ksize=3) / 8.0
    return float(np.hypot(gx, gy)[band].mean())
