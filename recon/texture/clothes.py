"""The neck below the collar: found in a photo and filled from the skin above it.

The head's mesh runs down the neck to the top of the chest; a photo shows a shirt there.
Textured as it is, the collar and the shirt are painted onto the neck. Here the skin's
colours are learnt from the face (a Gaussian in CIELAB over the pixels of skin vertices the
photo sees), and below the chin the pixels that are not skin by that model and that rise
from the bottom of the head's region — the shirt comes up from below — are taken for
clothes. Each column of them is filled by reflecting the skin just above the collar
downwards, back and forth over that band (a triangle wave of rows): the fill has the skin's
own colour, grain and shading, not a smooth inpainted wash.
"""

from __future__ import annotations

import cv2
import numpy as np

from mpeg4.head import Head
from mpeg4.render import Camera, vertex_normals

from .delight import fit_mask

__all__ = ["SKIN_CHI2", "skin_model", "face_skin_model", "skin_pixels", "clothes_mask", "fill_from_above", "remove_clothes"]

#: Squared Mahalanobis distance (3 degrees of freedom) beyond which a colour is not skin:
#: the 99.9th percentile of the chi-squared law, so that the skin itself is almost never
#: taken for clothes.
SKIN_CHI2 = 16.27


def _lab(pixels: np.ndarray) -> np.ndarray:
    """(..., 3) float32 CIELAB (L 0–100) of RGB uint8 pixels."""
    p = np.asarray(pixels, np.uint8)
    flat = p.reshape(-1, 1, 3).astype(np.float32) / 255.0
    return cv2.cvtColor(flat, cv2.COLOR_RGB2LAB).reshape(p.shape[:-1] + (3,))


def skin_model(photo: np.ndarray, skin_px: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The skin's colour in a photo: a Gaussian in CIELAB.

    Parameters
    ----------
    photo : (H, W, 3) uint8
        RGB.
    skin_px : (K, 2) float
        Pixels (x, y) of skin the photo shows (the face's cheeks and forehead).

    Returns
    -------
    (mean, inverse covariance) : (3,), (3, 3) float64, or None
        After one pass that leaves out the samples beyond :data:`SKIN_CHI2` (a lock of hair,
        a brow). None
        when fewer than 30 pixels are inside the photo.
    """
    h, w = photo.shape[:2]
    p = np.rint(np.asarray(skin_px, float)).astype(np.int64)
    p = p[(p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)]
    if len(p) < 30:
        return None
    lab = _lab(photo[p[:, 1], p[:, 0]]).astype(np.float64)
    keep = np.ones(len(lab), bool)
    for _ in range(2):
        mean = np.median(lab[keep], axis=0)
        cov = np.cov(lab[keep].T) + np.eye(3) * 1.0  # a floor of 1 unit²: flat synthetic skin
        d2 = np.einsum("ij,jk,ik->i", lab - mean, np.linalg.inv(cov), lab - mean)
        keep = d2 < SKIN_CHI2
        if keep.sum() < 30:
            return None
    return mean, np.linalg.inv(cov)


def skin_pixels(photo: np.ndarray, model: tuple[np.ndarray, np.ndarray], rows: slice = slice(None),
                lightness: float = 1.0) -> np.ndarray:
    """(H', W) bool over the photo's ``rows``: pixels whose colour is skin by the model
    (squared Mahalanobis distance within :data:`SKIN_CHI2`), with the model's spread in
    lightness multiplied by ``lightness`` (2 for the neck's shadow under the chin: a white,
    grey or dark shirt still differs in chroma)."""
    mean, inv = model
    s = np.diag([1.0 / lightness, 1.0, 1.0])
    d = _lab(photo[rows]) - mean.astype(np.float32)
    return np.sum((d @ (s @ inv @ s).astype(np.float32)) * d, axis=-1) <= SKIN_CHI2


def clothes_mask(photo: np.ndarray, head_mask: np.ndarray, model: tuple[np.ndarray, np.ndarray],
                 chin_row: float, open_px: int = 5) -> np.ndarray:
    """(H, W) bool: the clothes over the head's neck in a photo.

    Parameters
    ----------
    photo : (H, W, 3) uint8
    head_mask : (H, W) bool
        Where the photo shows the head (the rendered head less the backdrop).
    model : (mean, inverse covariance)
        :func:`skin_model`.
    chin_row : float
        The chin's row (2.1): nothing above it is clothes.
    open_px : int
        Not-skin specks narrower than this (stubble, a crease's shadow) are left alone.

    Returns
    -------
    (H, W) bool
        In each column, from the top of the not-skin regions that reach the bottom of the
        head's region down to that bottom.
    """
    h, w = head_mask.shape
    top = int(np.clip(np.ceil(chin_row), 0, h))
    below = np.zeros((h, w), bool)
    below[top:] = head_mask[top:]
    if not below.any():
        return below
    other = np.zeros((h, w), np.uint8)
    other[top:] = ~skin_pixels(photo, model, slice(top, h), lightness=2.0) & below[top:]
    k = np.ones((open_px, open_px), np.uint8)
    other = cv2.morphologyEx(other, cv2.MORPH_OPEN, k)
    # The clothes rise from the bottom of the head's region: keep the parts that touch it.
    _, labels = cv2.connectedComponents(other, connectivity=8)
    cols = np.flatnonzero(below.any(axis=0))
    bottom = h - 1 - np.argmax(below[::-1, cols], axis=0)  # the lowest head row per column
    touching = np.unique(labels[np.clip(bottom - open_px, 0, h - 1), cols])
    rising = np.isin(labels, touching[touching > 0])
    # Each column from its clothes' top down: the V of an open collar stays skin.
    first = np.where(rising.any(axis=0), np.argmax(rising, axis=0), h)
    return below & (np.arange(h)[:, None] >= first[None, :])


def fill_from_above(photo: np.ndarray, mask: np.ndarray, skin: np.ndarray, band_px: int,
                    min_band: int = 4) -> np.ndarray:
    """The photo with each column's masked run replaced by the skin above it.

    Parameters
    ----------
    photo : (H, W, 3) uint8
    mask : (H, W) bool
        :func:`clothes_mask`: per column, one run from its top down.
    skin : (H, W) bool
        Pixels that may be copied: skin of the head by the model's own spread
        (:func:`skin_pixels` within the head's region, below the chin; not hair lying on a
        shoulder, which the looser test for clothes lets pass).
    band_px : int
        At most this many rows of skin right above a column's run are reflected down it,
        back and forth (a triangle wave of rows).
    min_band : int
        A column with fewer skin rows above its run (a shoulder under the backdrop, a collar
        up to the chin) copies the nearest column that has enough.

    Returns
    -------
    (H, W, 3) uint8
        A copy; unmasked pixels unchanged (the photo itself when nothing is masked or no
        column has skin above it).
    """
    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    if not len(ys):
        return photo
    first = np.where(mask.any(axis=0), np.argmax(mask, axis=0), h)
    # Skin rows running up from just above each column's run.
    run = np.zeros(w, np.int64)
    band = np.zeros(w, np.int64)
    for y in range(h):
        run = np.where(skin[y], run + 1, 0)
        at = first == y + 1
        band[at] = run[at]
    band = np.minimum(band, band_px)
    good = np.flatnonzero(band >= min_band)
    if not len(good):
        return photo
    # Columns short of skin borrow the nearest good column's band, at its own height.
    near = good[np.clip(np.searchsorted(good, np.arange(w)), 0, len(good) - 1)]
    left = good[np.clip(np.searchsorted(good, np.arange(w)) - 1, 0, len(good) - 1)]
    near = np.where(np.abs(left - np.arange(w)) < np.abs(near - np.arange(w)), left, near)
    src_x = np.where(band >= min_band, np.arange(w), near)[xs]
    b = band[src_x]
    r = (ys - first[xs]) % (2 * b)
    up = np.where(r < b, r, 2 * b - 1 - r)  # 0, 1, .., b-1, b-1, .., 0, ...
    out = photo.copy()
    out[ys, xs] = photo[np.clip(first[src_x] - 1 - up, 0, h - 1), src_x]
    return out


def face_skin_model(head: Head, photo: np.ndarray, camera: Camera, seen: np.ndarray,
                    normals: np.ndarray | None = None,
                    skin: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`skin_model` of a photo from the face of the head fitted to it: the skin
    vertices (``skin``, :func:`recon.texture.delight.fit_mask` when None) the camera sees
    (``seen``, (N,) bool), above the chin (2.1) and facing the camera within 45° — not the
    neck (it may be under a collar), nor the rims and sideburns seen edge-on. None as
    :func:`skin_model`."""
    v = head.skin.vertices
    normals = vertex_normals(v, head.skin.triangles) if normals is None else normals
    skin = fit_mask(head) > 0 if skin is None else skin
    facing = np.sum(normals * camera.towards(v), axis=1) >= np.cos(np.radians(45.0))
    face = skin & seen & facing
    if "2.1" in head.feature_points:
        face &= v[:, 1] > head.fp_position("2.1")[1]
    return skin_model(photo, camera.project(v[face]))


def remove_clothes(head: Head, photo: np.ndarray, head_mask: np.ndarray, camera: Camera,
                   seen: np.ndarray, normals: np.ndarray | None = None,
                   skin: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """A photo of ``head`` with the clothes over its neck filled from the skin above them.

    Parameters
    ----------
    head : Head
        Fitted to the photo, with the chin (2.1) and the nose tip (9.3).
    photo : (H, W, 3) uint8
        RGB, as it goes into the texture (de-lit or not).
    head_mask : (H, W) bool
        Where the photo shows the head.
    camera : mpeg4.render.Camera
        The photo's camera.
    seen : (N,) bool
        The head's skin vertices the camera sees.
    normals : (N, 3) float, optional
        The skin's vertex normals (computed when None).
    skin : (N,) bool, optional
        The skin vertices whose colour is skin (:func:`recon.texture.delight.fit_mask` when
        None).

    Returns
    -------
    photo : (H, W, 3) uint8
        The photo itself when there is nothing to fill.
    share : float
        Of the head's region the clothes covered.
    """
    pts = head.fp_positions()
    if "2.1" not in pts or "9.3" not in pts:
        return photo, 0.0
    model = face_skin_model(head, photo, camera, seen, normals, skin)
    if model is None:
        return photo, 0.0
    chin, nose = camera.project(np.array([pts["2.1"], pts["9.3"]]))
    # Only the head's region below the chin is looked at.
    top = int(np.clip(np.ceil(chin[1]), 0, photo.shape[0]))
    cols = np.flatnonzero(head_mask[top:].any(axis=0))
    rows = np.flatnonzero(head_mask[top:].any(axis=1))
    if not len(cols):
        return photo, 0.0
    box = np.s_[top:top + rows[-1] + 1, cols[0]:cols[-1] + 1]
    crop, crop_head = photo[box], head_mask[box]
    mask = clothes_mask(crop, crop_head, model, 0.0)
    if not mask.any():
        return photo, 0.0
    source = crop_head & skin_pixels(crop, model) & ~mask
    # Half the chin's height under the nose: the neck's skin right above a collar.
    band = max(8, int(round(0.5 * abs(chin[1] - nose[1]))))
    out = photo.copy()
    out[box] = fill_from_above(crop, mask, source, band)
    return out, float(mask.sum() / max(head_mask.sum(), 1))
