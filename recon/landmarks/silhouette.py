"""The head's silhouette in a photo: a person mask sharpened by GrabCut, and its outline.

The selfie segmentation (:func:`recon.landmarks.models.person_mask`) finds the person but
at a 256-pixel resolution, so its edge is a few pixels soft; GrabCut [1]_, started from it
(sure background and foreground where the segmentation is sure, probable in between),
moves the edge onto the photo's colour boundary. The outline is then read row by row: the
leftmost and rightmost pixel of the head in each row, which for a profile photo are the
face's profile curve and the back of the head.

References
----------
.. [1] C. Rother, V. Kolmogorov, A. Blake, "GrabCut: interactive foreground extraction using
   iterated graph cuts", ACM Transactions on Graphics 23(3) (2004).
"""

from __future__ import annotations

import numpy as np

__all__ = ["head_mask", "row_extents", "on_left_edge", "largest_component", "bumpiness"]

#: GrabCut works on the photo scaled so that its longer side is at most this (pixels).
GRABCUT_SIDE = 720


def largest_component(mask: np.ndarray) -> np.ndarray:
    """The largest 8-connected region of a boolean mask, with its holes filled."""
    from scipy import ndimage as ndi

    lab, n = ndi.label(mask, structure=np.ones((3, 3)))
    if n == 0:
        return np.zeros_like(mask, dtype=bool)
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    return ndi.binary_fill_holes(lab == np.argmax(sizes))


def head_mask(image: np.ndarray, probability: np.ndarray | None = None, iterations: int = 3) -> np.ndarray:
    """(H, W) bool: the person in a photo, edge refined by GrabCut.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.
    probability : (H, W) float, optional
        Person probability; :func:`recon.landmarks.models.person_mask` when omitted.
    iterations : int
        GrabCut iterations.

    Returns
    -------
    (H, W) bool
        The largest connected region, holes filled; all False when no person is found.
    """
    import cv2

    from .models import person_mask

    prob = person_mask(image) if probability is None else np.asarray(probability, dtype=np.float32)
    h, w = prob.shape
    coarse = largest_component(prob > 0.5)
    if coarse.sum() < 0.002 * h * w:
        return np.zeros((h, w), bool)
    f = min(1.0, GRABCUT_SIDE / max(h, w))
    small = cv2.resize(image, (max(1, round(w * f)), max(1, round(h * f))), interpolation=cv2.INTER_AREA)
    p = cv2.resize(prob, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_LINEAR)
    gc = np.full(p.shape, cv2.GC_PR_BGD, np.uint8)
    gc[p > 0.5] = cv2.GC_PR_FGD
    gc[p > 0.97] = cv2.GC_FGD
    gc[p < 0.03] = cv2.GC_BGD
    if not np.any(gc == cv2.GC_FGD) or not np.any(gc == cv2.GC_BGD):
        return coarse
    bgd, fgd = np.zeros((1, 65)), np.zeros((1, 65))
    cv2.setRNGSeed(0)  # its colour models start from k-means: the same photo, the same mask
    try:
        cv2.grabCut(cv2.cvtColor(small, cv2.COLOR_RGB2BGR), gc, None, bgd, fgd, iterations, cv2.GC_INIT_WITH_MASK)
    except cv2.error:  # a degenerate colour model: keep the segmentation
        return coarse
    fg = np.isin(gc, (cv2.GC_FGD, cv2.GC_PR_FGD)).astype(np.float32)
    fine = cv2.resize(fg, (w, h), interpolation=cv2.INTER_LINEAR) > 0.5
    fine = largest_component(fine)
    # GrabCut can lose a thin part the network was sure of (or run into a similar
    # background); keep it only where it agrees with the segmentation broadly.
    if fine.sum() < 0.7 * coarse.sum() or fine.sum() > 1.3 * coarse.sum():
        return coarse
    return fine


def head_masks(images: list[np.ndarray], iterations: int = 3) -> list[np.ndarray]:
    """:func:`head_mask` of several photos, the GrabCut refinements side by side.

    The segmentation model runs on one photo after the other (one model, one caller at a
    time); GrabCut, most of the time, runs in a thread a photo (OpenCV releases the
    interpreter while it works, and seeds each thread's random numbers alike), so two
    photos take about the time of one on two cores.
    """
    from concurrent.futures import ThreadPoolExecutor

    from .models import person_mask

    probs = [person_mask(im) for im in images]
    with ThreadPoolExecutor(max_workers=max(1, len(images)), thread_name_prefix="grabcut") as pool:
        return list(pool.map(lambda pair: head_mask(pair[0], pair[1], iterations), zip(images, probs)))


def row_extents(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Leftmost and rightmost column of the mask in each row (NaN for empty rows).

    Returns
    -------
    left, right : (H,) float64
    """
    mask = np.asarray(mask, bool)
    any_ = mask.any(axis=1)
    left = np.where(any_, np.argmax(mask, axis=1), np.nan).astype(np.float64)
    right = np.where(any_, mask.shape[1] - 1 - np.argmax(mask[:, ::-1], axis=1), np.nan).astype(np.float64)
    return left, right


def on_left_edge(left: np.ndarray) -> np.ndarray:
    """(H,) bool: rows whose silhouette starts at the photo's left edge (column 0 of
    :func:`row_extents`' ``left``): a silhouette cut off by the photo there. NaN rows are
    False."""
    left = np.asarray(left, float)
    return np.isfinite(left) & (left < 0.5)


def bumpiness(curve: np.ndarray, scale: int) -> float:
    """Largest outward bump of a silhouette curve (x per row, outward = smaller x) at ``scale``
    rows: how far a row stands out of the chord between the rows ``scale`` above and below."""
    ok = np.isfinite(curve)
    y = np.flatnonzero(ok)
    if len(y) < 3 * scale:
        return 0.0
    c = np.interp(np.arange(y[0], y[-1] + 1), y, curve[ok])
    out = 0.5 * (c[:-2 * scale] + c[2 * scale:]) - c[scale:-scale]
    return float(out.max())
