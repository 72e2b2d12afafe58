"""How a head built from real photos agrees with them, with no 3D ground truth.

Each figure compares a head built by ``recon build FRONT SIDE`` (points detected, nothing
reviewed) with photos of the person, through the cameras the build fitted to them (or, for
a photo the build never saw, a camera fitted to the points detected on it):

- :func:`point_agreement`: the detected points against the head's points projected, RMS in
  % of the interpupillary distance (IPD) as the photo shows it;
- :func:`silhouette_iou`: the rendered head against the photo's head region (the person's
  silhouette, hair counted as head), both cut at the chin so that the neck and the clothes
  below it do not count;
- :func:`profile_line`: in a profile, the face-side outline from the brow down to the chin
  (forehead, nose, lips, chin: the part no hair hides) against the rendered head's, mean
  distance in % IPD;
- :func:`skin_delta_e`: CIEDE2000 between the median skin colour of the photo (cheeks and
  forehead) and the texture's there, rendered unlit;
- :func:`cheek_psnr`: in a profile, the textured head relit as the photo is lit against the
  photo over the cheek (between the eye, the ear, the mouth and the jaw), PSNR: where the
  side photo's layer meets the front photo's, the seam a texture shows first.

``benchmarks/real_photos.py`` runs them over folders of people.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.camera import Camera
from mpeg4.head import Head
from mpeg4.preview import head_meshes
from mpeg4.render import render

__all__ = ["ipd_px", "rendered_mask", "point_misses", "point_agreement", "head_region", "silhouette_iou", "profile_line",
           "skin_delta_e", "relit", "cheek_box", "cheek_psnr", "BROW_IDS"]

#: Eyebrow points: where the profile line starts (the highest one a photo shows).
BROW_IDS = ("4.1", "4.2", "4.3", "4.4", "4.5", "4.6")


def ipd_px(head: Head, camera: Camera) -> float:
    """The head's interpupillary distance as the camera shows it at the pupils, pixels
    (measured upright, so that a profile shows it too)."""
    p = head.fp_position("3.5")
    d = np.linalg.norm(head.fp_position("3.5") - head.fp_position("3.6"))
    a, b = camera.project(np.array([p, p + [0.0, d, 0.0]]))
    return float(np.linalg.norm(a - b))


def rendered_mask(head: Head, camera: Camera, textured: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """(H, W) bool: where the head covers the photo; and its unlit (albedo) render when
    ``textured``."""
    image, depth = render(head_meshes(head), camera, return_depth=True, samples=0, ambient=1.0)
    return np.isfinite(depth), (image if textured else None)


def point_misses(head: Head, camera: Camera, points: Mapping[str, np.ndarray]) -> dict[str, float]:
    """FP id → distance between ``points`` (FP id → pixel) and the head's feature point
    projected by ``camera``, in % of the IPD the photo shows."""
    ids = [i for i in points if i in head.feature_points]
    if not ids:
        return {}
    proj = camera.project(np.array([head.fp_position(i) for i in ids]))
    d = np.linalg.norm(proj - np.array([points[i] for i in ids]), axis=1)
    return dict(zip(ids, (100 * d / ipd_px(head, camera)).tolist()))


def point_agreement(head: Head, camera: Camera, points: Mapping[str, np.ndarray]) -> float:
    """RMS of :func:`point_misses`: the detected points against the head's, % of the IPD."""
    d = np.array(list(point_misses(head, camera, points).values()))
    return float(np.sqrt(np.mean(d ** 2))) if len(d) else float("nan")


def head_region(image: np.ndarray) -> np.ndarray:
    """(H, W) bool: the person's head and body in a photo (hair counted), by the project's
    head segmentation (:func:`recon.landmarks.silhouette.head_masks`)."""
    from recon.landmarks.silhouette import head_masks

    (mask,) = head_masks([image])
    return np.asarray(mask, bool)


def _above(mask: np.ndarray, row: float) -> np.ndarray:
    out = mask.copy()
    out[int(np.ceil(row)):] = False
    return out


def silhouette_iou(photo_mask: np.ndarray, render_mask: np.ndarray, chin_row: float) -> float:
    """Intersection over union of the photo's head region and the rendered head, both above
    ``chin_row`` (the chin's row in the photo: the neck and clothes below it are left out)."""
    a, b = _above(photo_mask, chin_row), _above(render_mask, chin_row)
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else float("nan")


def _front_edge(mask: np.ndarray, rows: np.ndarray, facing: str) -> np.ndarray:
    """(len(rows),) the face-side column of ``mask`` in each row (NaN where empty)."""
    out = np.full(len(rows), np.nan)
    for k, r in enumerate(rows):
        cols = np.flatnonzero(mask[r])
        if len(cols):
            out[k] = cols[0] if facing == "left" else cols[-1]
    return out


def profile_line(photo_mask: np.ndarray, render_mask: np.ndarray, points: Mapping[str, np.ndarray],
                 facing: str, ipd: float) -> float:
    """Mean distance between the photo's and the render's face-side outline, from the
    highest brow point the photo shows down to the chin (2.1), in % of ``ipd`` (pixels)."""
    brows = [points[i][1] for i in BROW_IDS if i in points]
    if not brows or "2.1" not in points:
        return float("nan")
    rows = np.arange(int(round(min(brows))), int(round(points["2.1"][1])) + 1)
    rows = rows[(rows >= 0) & (rows < photo_mask.shape[0])]
    d = np.abs(_front_edge(photo_mask, rows, facing) - _front_edge(render_mask, rows, facing))
    return float(100 * np.nanmean(d) / ipd) if np.isfinite(d).any() else float("nan")


def _skin_samples(image: np.ndarray, points: Mapping[str, np.ndarray], ipd: float) -> np.ndarray:
    """(K, 3) RGB pixels of the cheeks and the forehead: discs of a fifth of the IPD."""
    centres = []
    for a, b in (("3.5", "2.13"), ("3.6", "2.14")):  # cheeks: between a pupil and the jaw's corner
        if a in points and b in points:
            centres.append(0.5 * (np.asarray(points[a]) + np.asarray(points[b])))
    if "3.5" in points and "3.6" in points:  # the forehead: above the pupils by an IPD
        centres.append(0.5 * (np.asarray(points["3.5"]) + np.asarray(points["3.6"])) - [0.0, ipd])
    h, w = image.shape[:2]
    yy, xx = np.mgrid[:h, :w]
    r = 0.2 * ipd
    take = np.zeros((h, w), bool)
    for c in centres:
        take |= (xx - c[0]) ** 2 + (yy - c[1]) ** 2 <= r * r
    return image[take]


def skin_delta_e(photo: np.ndarray, texture_render: np.ndarray, render_mask: np.ndarray,
                 points: Mapping[str, np.ndarray], ipd: float) -> float:
    """CIEDE2000 between the median skin colour of the photo and of the head's unlit render
    over the same cheek and forehead discs (only where the head covers the photo)."""
    from skimage.color import deltaE_ciede2000, rgb2lab

    where = np.where(render_mask[..., None], photo, 0)
    covered = _skin_samples(render_mask[..., None].repeat(3, axis=2).astype(np.uint8), points, ipd)[:, 0] > 0
    a = _skin_samples(where, points, ipd)[covered]
    b = _skin_samples(texture_render, points, ipd)[covered]
    if len(a) < 10:
        return float("nan")
    lab = rgb2lab(np.array([[np.median(a, axis=0), np.median(b, axis=0)]]) / 255.0)[0]
    return float(deltaE_ciede2000(lab[0], lab[1]))


def relit(texture_render: np.ndarray, lighting) -> np.ndarray | None:
    """The head's unlit (albedo) render lit as the photo is: times the shading the build
    fitted to the photo (``recon.texture.delight.Lighting.shading``, 1 off the head); the
    render itself when the build kept the photo's light (``lighting.fallback``); None when
    the shading was fitted on a photo of another size."""
    if lighting.fallback is not None:
        return texture_render
    shading = lighting.shading
    if shading.shape != texture_render.shape[:2]:
        return None
    out = texture_render.astype(np.float32) * shading[..., None]
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def cheek_box(points: Mapping[str, np.ndarray], shape: tuple[int, int]) -> np.ndarray | None:
    """(H, W) bool: the cheek in a profile photo, from its detected points: rows from the
    eye's outer corner down half way from the mouth's corner to the chin, columns from the
    mouth's corner back to the ear's front (whichever side's ids the photo carries); None
    when the photo lacks them."""
    def first(*ids):
        return next((np.asarray(points[i], float) for i in ids if i in points), None)

    eye, mouth, chin = first("3.7", "3.12"), first("8.3", "8.4"), first("2.1")
    ear = first("10.7", "10.8", "10.9", "10.10")
    if any(p is None for p in (eye, mouth, chin, ear)):
        return None
    r0, r1 = eye[1], mouth[1] + 0.5 * (chin[1] - mouth[1])
    c0, c1 = sorted((mouth[0], ear[0]))
    out = np.zeros(shape, bool)
    rows = slice(max(int(np.ceil(r0)), 0), max(int(r1) + 1, 0))
    cols = slice(max(int(np.ceil(c0)), 0), max(int(c1) + 1, 0))
    out[rows, cols] = True
    return out


def cheek_psnr(photo: np.ndarray, render: np.ndarray, region: np.ndarray) -> float:
    """PSNR (dB, RGB) of a render against the photo over ``region``, after the one gain that
    brings the render's luma to the photo's there (a de-lit texture is the albedo up to the
    light's strength, which no photo tells)."""
    from recon.evaluate.fidelity import matched_gain, psnr

    if region.sum() < 100:
        return float("nan")
    return psnr(matched_gain(render, photo, region), photo, region)
