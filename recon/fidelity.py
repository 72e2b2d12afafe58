"""How faithfully a built head gives back its photo: re-projection PSNR and SSIM, and the
seams' smoothness.

:func:`reprojection` renders the textured head with the front photo's camera, unlit (the
texture already holds the photo's light), and compares it with the photo inside the face
— the front region's outline (:func:`recon.texture.feature_polygon`), where both the
render and the photo show the head, shrunk by a few pixels so that silhouettes do not
count. :func:`seam_smoothness` measures the mean gradient in a band across the borders
between the texture's layers for the multiresolution spline and for the two blends it
replaces (a hard cut and a feathered edge).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from mpeg4.head import Head

from .cameras import FittedCamera

__all__ = ["Fidelity", "face_mask", "reprojection", "seam_smoothness"]


@dataclass
class Fidelity:
    """Re-projection figures of one head.

    Attributes
    ----------
    psnr_db : float
        Peak signal-to-noise ratio inside the face (RGB, 8 bits).
    ssim : float
        Mean structural similarity inside the face (grey levels, 7 x 7 windows).
    pixels : int
        Size of the face region compared.
    """

    psnr_db: float
    ssim: float
    pixels: int


def face_mask(head: Head, front: FittedCamera, shape: tuple[int, int], shrink: int = 4) -> np.ndarray:
    """(H, W) bool: inside the front region's outline in the photo, shrunk by ``shrink``
    pixels."""
    from .texture import feature_line, feature_polygon

    pts = head.fp_positions()
    skin = head.skin
    lines = [feature_line(pts, skin.vertices, skin.triangles, s)[0] for s in ("L", "R")]
    poly = feature_polygon(front, *lines)
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round(poly * 256).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=8)
    if shrink:
        mask = cv2.erode(mask, np.ones((2 * shrink + 1, 2 * shrink + 1), np.uint8))
    return mask > 0


def reprojection(head: Head, photo: np.ndarray, front: FittedCamera, photo_mask: np.ndarray | None = None,
                 shrink: int = 4) -> Fidelity:
    """Render ``head`` with the front camera and compare it with ``photo`` in the face,
    where the skin is what the camera sees.

    Parameters
    ----------
    head : Head
        Textured.
    photo : (H, W, 3) uint8
        The front photo the texture came from.
    front : FittedCamera
    photo_mask : (H, W) bool, optional
        Where the head is in the photo (all of it when None).
    shrink : int
        Pixels taken off the region's rim.
    """
    from skimage.metrics import structural_similarity

    from mpeg4.preview import head_meshes
    from mpeg4.render import render

    image, depth = render(head_meshes(head), front.camera, return_depth=True, ambient=1.0, samples=4)
    # Only where the skin is the surface seen (the eyes and teeth have textures of their own).
    skin_only = render(head_meshes(head)[:1] if next(iter(head.parts)) == "skin" else
                       [m for m, n in zip(head_meshes(head), head.parts) if n == "skin"],
                       front.camera, return_depth=True, samples=0)[1]
    both = np.isfinite(depth) & np.isfinite(skin_only)
    gap = np.full(depth.shape, np.inf)
    gap[both] = np.abs(skin_only[both] - depth[both])
    skin_seen = gap < 1e-4
    skin_seen = cv2.erode(skin_seen.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    region = face_mask(head, front, photo.shape[:2], shrink) & skin_seen
    if photo_mask is not None:
        region &= cv2.erode(photo_mask.astype(np.uint8), np.ones((2 * shrink + 1,) * 2, np.uint8)) > 0
    diff = image[region].astype(np.float64) - photo[region].astype(np.float64)
    mse = float(np.mean(diff ** 2))
    psnr = float(10 * np.log10(255.0 ** 2 / max(mse, 1e-12)))
    ys, xs = np.nonzero(region)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    a = cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_RGB2GRAY)
    b = cv2.cvtColor(np.ascontiguousarray(photo[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    _, smap = structural_similarity(a, b, data_range=255, win_size=7, full=True)
    ssim = float(smap[region[y0:y1, x0:x1]].mean())
    return Fidelity(psnr, ssim, int(region.sum()))


def seam_smoothness(layers, masks, band: int = 8) -> dict[str, float]:
    """Mean gradient magnitude (grey levels per pixel) across the layers' borders, for the
    multiresolution spline, a hard cut and a feathered edge (16 px), on the same layers."""
    from .blend import blend_feather, blend_hard, blend_multiband, seam_band, seam_gradient

    where = seam_band(masks, band)
    return {"multiband": seam_gradient(blend_multiband(layers, masks), where),
            "hard": seam_gradient(blend_hard(layers, masks), where),
            "feather": seam_gradient(blend_feather(layers, masks), where)}
