"""Glasses in a photo: their frames found and inpainted out of the skin.

A pair of glasses seen on a face is a frame of thin lines around the eyes, a bridge over
the nose and the temples running back to the ears. Textured as it is, it is painted on the
skin: a ring round each eye and a band across the cheek that move with the skin when the
head animates. Here the frames are looked for where glasses sit (the skin a band around
the eyes' height, from the nose back to the ears) as what is both *not skin* by the face's
own colour model (:func:`recon.texture.clothes.skin_model`) and *thin*: what a
morphological opening (a disk a few hundredths of the eye separation across) removes.
A frame the skin's own colour (gold on brown skin) is found as what stands out from the
median of the pixels around it. Lens tint and shadows are blobs the opening keeps; a
crease or a stray hair is a short line; the eye openings and the brows are left out. What
is left is taken for frames only when, over both photos of a person, it is long (its
skeleton, in eye separations) and rings the eyes (a line in a good share of the
directions round each eye, :func:`wears_glasses`); then it is inpainted (Telea's fast
marching method, OpenCV) from the skin around it. The lenses themselves cannot be taken
out: glare and tint stay.

References
----------
A. Telea, "An image inpainting technique based on the fast marching method", Journal of
Graphics Tools 9(1), 2004.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from skimage.morphology import skeletonize

from mpeg4.camera import Camera
from mpeg4.head import Head

from .clothes import face_skin_model, skin_pixels

__all__ = ["GLASSES_COVER", "GLASSES_LENGTH", "Glasses", "find_glasses", "wears_glasses", "remove_glasses"]

#: Lines at least this long, a photo's mean (skeleton length in eye separations, the
#: lines of 0.15 eye separations or more only), may be glasses. Two rims round the eyes
#: are about 4 eye separations of line and a temple seen from the side about 1; a face's
#: own lines (a crease, the lashes' edge, a brow's stray hairs) add up to a fraction of one.
GLASSES_LENGTH = 1.0

#: A line stands out from the median around it by this ΔE (CIELAB) at least, and by this
#: many times the zone's median difference (a grainy photo's own texture).
_CONTRAST, _NOISE = 7.0, 3.0

#: ... and they ring the eyes: a line in at least this share of the directions round
#: them, a photo's mean. A face's own lines meet a few directions (under 0.2 on the real
#: portraits); a rim, the directions it is seen in (its faint or hidden parts missed).
GLASSES_COVER = 0.3

_LIDS = {"l": ("3.7", "3.1", "3.11", "3.3"), "r": ("3.8", "3.2", "3.12", "3.4")}


@dataclass
class Glasses:
    """Frames found in one photo.

    Attributes
    ----------
    mask : (H, W) bool
        The frames' pixels, widened by the opening's radius: what is inpainted.
    length : float
        The lines' skeleton length, eye separations.
    cover : float
        The share of directions round the eyes (their mean) in which a line rings them
        (:func:`_ring_cover`).
    ipd_px : float
        The eye separation in the photo, pixels.
    """

    mask: np.ndarray
    length: float
    cover: float
    ipd_px: float



def _zone(head: Head, camera: Camera, seen: np.ndarray, normals: np.ndarray, shape: tuple[int, int],
          ipd_m: float) -> np.ndarray:
    """(H, W) uint8: the skin a pair of glasses may lie on, from the eyes' height 0.5 eye
    separations down to 0.4 up, back to 2 cm behind the ears' fronts (10.7–10.10: the
    temples run to the ears, and a fitted head's ears may sit a little forward of the
    photo's), as the camera sees it within 60°."""
    pts = head.fp_positions()
    v = head.skin.vertices
    y_eye = 0.5 * (pts["3.5"][1] + pts["3.6"][1])
    inside = seen & (v[:, 1] > y_eye - 0.5 * ipd_m) & (v[:, 1] < y_eye + 0.4 * ipd_m)
    # Skin seen squarely: not the outline (hair, ear and backdrop meet there).
    inside &= np.sum(normals * camera.towards(v), axis=1) >= np.cos(np.radians(60.0))
    ears = [pts[i][2] for i in ("10.9", "10.10", "10.7", "10.8") if i in pts]
    if ears:
        inside &= v[:, 2] > np.mean(ears) - 0.02
    tris = head.skin.triangles
    tris = tris[inside[tris].all(axis=1)]
    zone = np.zeros(shape, np.uint8)
    if len(tris):
        px = camera.project(v)
        cv2.fillPoly(zone, list(np.rint(px[tris]).astype(np.int32)), 1)
    return zone


def _keep_out(head: Head, camera: Camera, shape: tuple[int, int], ipd_px: float) -> np.ndarray:
    """(H, W) uint8: what is not looked at for frames — the eye openings between the lids
    (corners and lid midpoints) widened for the lashes, and the brows (4.x, a band 0.16
    eye separations wide): both are thin dark lines of their own."""
    pts = head.fp_positions()
    out = np.zeros(shape, np.uint8)
    for ids in _LIDS.values():
        if not all(i in pts for i in ids):
            continue
        corner_o, top, corner_i, bottom = camera.project(np.array([pts[i] for i in ids]))
        centre = 0.5 * (corner_o + corner_i)
        # A smooth eye: the corners' axis and the lids' midpoints on either side of it.
        t = np.linspace(0.0, np.pi, 16)
        half = 0.5 * (corner_i - corner_o)
        upper = centre[None] - np.cos(t)[:, None] * half + np.sin(t)[:, None] * (top - centre)
        lower = centre[None] + np.cos(t)[:, None] * half + np.sin(t)[:, None] * (bottom - centre)
        cv2.fillPoly(out, [np.rint(np.vstack([upper, lower])).astype(np.int32)], 1)
    pad = max(1, int(round(0.05 * ipd_px)))
    out = cv2.dilate(out, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * pad + 1,) * 2))
    for ids in (("4.1", "4.3", "4.5"), ("4.2", "4.4", "4.6")):
        brow = [pts[i] for i in ids if i in pts]
        if len(brow) >= 2:
            line = np.rint(camera.project(np.array(brow))).astype(np.int32)
            cv2.polylines(out, [line], False, 1, thickness=max(1, int(round(0.16 * ipd_px))))
    return out


def _ring_cover(lines: np.ndarray, keep_out: np.ndarray, zone: np.ndarray, centre: np.ndarray,
                ipd_px: float, rays: int = 24) -> float:
    """The share of directions round an eye's centre (pixels, x y) in which a ray from 0.12
    to 0.6 eye separations out meets a line: near 1 for a rim round the eye, low for the
    scattered lines of a face without glasses. Rays that run mostly outside the zone or
    through the brows and lids are not counted."""
    h, w = lines.shape
    t = np.linspace(0.12, 0.6, 24) * ipd_px
    hits = counted = 0
    for a in np.linspace(0.0, 2 * np.pi, rays, endpoint=False):
        x = np.clip(np.rint(centre[0] + t * np.cos(a)).astype(int), 0, w - 1)
        y = np.clip(np.rint(centre[1] + t * np.sin(a)).astype(int), 0, h - 1)
        usable = (zone[y, x] > 0) & (keep_out[y, x] == 0)
        if usable.mean() < 0.5:
            continue
        counted += 1
        hits += bool(lines[y, x].any())
    return hits / counted if counted >= rays // 3 else 0.0


def find_glasses(head: Head, photo: np.ndarray, camera: Camera, seen: np.ndarray, normals: np.ndarray,
                 model: tuple[np.ndarray, np.ndarray]) -> Glasses | None:
    """The frames of a pair of glasses in a photo of ``head``.

    Parameters
    ----------
    head : Head
        Fitted to the photo, with the pupils (3.5, 3.6), the lids (3.1–3.4, 3.7, 3.8,
        3.11, 3.12) and the brows (4.1–4.6).
    photo : (H, W, 3) uint8
        RGB.
    camera : mpeg4.camera.Camera
        The photo's camera.
    seen : (N,) bool
        The skin vertices the camera sees.
    normals : (N, 3) float
        The skin's vertex normals.
    model : (mean, inverse covariance)
        The face's skin colour in this photo (:func:`recon.texture.clothes.skin_model`).

    Returns
    -------
    Glasses or None
        The long thin lines round the eyes, frames or not (:func:`wears_glasses` decides);
        None without the pupils.
    """
    pts = head.fp_positions()
    if "3.5" not in pts or "3.6" not in pts:
        return None
    h, w = photo.shape[:2]
    ipd_m = float(np.linalg.norm(pts["3.5"] - pts["3.6"]))
    # The eye separation in pixels, measured upright: the same in a front and a side view.
    c = 0.5 * (pts["3.5"] + pts["3.6"])
    a, b = camera.project(np.array([c, c + (0.0, ipd_m, 0.0)]))
    ipd_px = float(np.linalg.norm(a - b))
    r = max(1, int(round(0.035 * ipd_px)))
    zone = _zone(head, camera, seen, normals, (h, w), ipd_m)
    keep_out = _keep_out(head, camera, (h, w), ipd_px)
    search = zone & (1 - keep_out)
    rows, cols = np.flatnonzero(search.any(axis=1)), np.flatnonzero(search.any(axis=0))
    empty = Glasses(np.zeros((h, w), bool), 0.0, 0.0, ipd_px)
    if not len(rows):
        return empty
    pad = 2 * r + 2
    box = np.s_[max(rows[0] - pad, 0):rows[-1] + pad + 1, max(cols[0] - pad, 0):cols[-1] + pad + 1]
    crop = np.ascontiguousarray(photo[box])
    other = (~skin_pixels(crop, model)).astype(np.uint8)
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)
    thin = other & (1 - cv2.morphologyEx(other, cv2.MORPH_OPEN, disk))
    # A line of the skin's own colour (a gold frame on brown skin) still stands out from
    # what is around it: its colour against the median of a window twice its width.
    lab = cv2.cvtColor(crop, cv2.COLOR_RGB2LAB)
    diff = lab.astype(np.float32) - cv2.medianBlur(lab, 2 * r + 1).astype(np.float32)
    diff[..., 0] *= 100.0 / 255.0
    de = np.sqrt(np.sum(diff * diff, axis=-1))
    z = search[box] > 0
    noise = float(np.median(de[z]))
    thin |= (de > max(_CONTRAST, _NOISE * noise)).astype(np.uint8)
    thin &= search[box]
    thin = cv2.morphologyEx(thin, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))  # a frame's JPEG-broken line
    n, labels, stats, _ = cv2.connectedComponentsWithStats(thin, connectivity=8)
    extent = np.hypot(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    long = np.flatnonzero(extent >= 0.15 * ipd_px)
    long = long[long > 0]
    if not len(long):
        return empty
    lines = np.zeros((h, w), bool)
    lines[box] = np.isin(labels, long)
    length = float(skeletonize(lines[box]).sum() / ipd_px)
    cover = []
    for ids in _LIDS.values():
        if ids[0] in pts and ids[2] in pts:
            centre = camera.project(np.array([0.5 * (pts[ids[0]] + pts[ids[2]])]))[0]
            cover.append(_ring_cover(lines, keep_out, zone, centre, ipd_px))
    mask = cv2.dilate(lines.astype(np.uint8), disk) > 0
    # Both eyes are ringed by a pair of glasses (in a side photo, the one it shows).
    return Glasses(mask, length, float(np.mean(cover)) if cover else 0.0, ipd_px)


def wears_glasses(found: list[Glasses]) -> bool:
    """Whether the lines found in the photos of one person are a pair of glasses: their
    mean length at least :data:`GLASSES_LENGTH` and their mean ring round the eyes at least
    :data:`GLASSES_COVER` (both photos weigh in: a front photo shows the rims, a side photo
    the rim before the eye and the temple behind it)."""
    if not found:
        return False
    return (np.mean([g.length for g in found]) >= GLASSES_LENGTH
            and np.mean([g.cover for g in found]) >= GLASSES_COVER)


def remove_glasses(head: Head, photos: dict[str, np.ndarray], cameras: dict[str, Camera],
                   seen: dict[str, np.ndarray], normals: np.ndarray,
                   skin: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, Glasses]]:
    """The photos of ``head`` with the frames of its glasses inpainted from the skin round
    them, when :func:`wears_glasses` says the person wears them.

    Parameters
    ----------
    head : Head
        As :func:`find_glasses`.
    photos : dict of str to (H, W, 3) uint8
        RGB, by view (``"front"``, ``"side"``).
    cameras, seen : dict by view
        Each photo's camera, and the skin vertices it sees ((N,) bool).
    normals : (N, 3) float
        The skin's vertex normals.
    skin : (N,) bool
        The skin vertices whose colour is skin (:func:`recon.texture.delight.fit_mask`).

    Returns
    -------
    photos : dict of str to (H, W, 3) uint8
        A new dict; a photo with nothing removed is the photo itself.
    glasses : dict of str to Glasses
        The frames removed from each photo; empty when the person wears no glasses (or the
        photos have no skin model or the head no pupils).
    """
    found = {}
    for key, photo in photos.items():
        model = face_skin_model(head, photo, cameras[key], seen[key], normals, skin)
        g = None if model is None else find_glasses(head, photo, cameras[key], seen[key], normals, model)
        if g is not None:
            found[key] = g
    out = dict(photos)
    if not wears_glasses(list(found.values())):
        return out, {}
    for key, g in found.items():
        if g.mask.any():
            radius = max(3.0, 0.06 * g.ipd_px)
            out[key] = cv2.inpaint(np.ascontiguousarray(photos[key]), g.mask.astype(np.uint8), radius,
                                   cv2.INPAINT_TELEA)
    return out, found
