"""What a front photo alone cannot show: a skin (and hair) model for the head's sides.

Built from one front photo, the texture takes the face from the photo up to the feature
lines (where a profile photo would take over) and the sides, ears and back of the head
from a model of the person's skin fitted to the face: at each height, the median colour
of the face's border in the front photo (skin, or hair above the hairline), smoothed down
the head, with a soft mottle as strong as the skin's own fine variation. A photo seen at
a grazing angle is not stretched over the sides, so the texture has no streaks; the
multiresolution blend joins the layers.

The layout needs a side camera: :func:`virtual_side_camera` stands one where a profile
photo would have been taken, so that the sides unroll as in the two-photo route.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from mpeg4.camera import Camera

from .cameras import FittedCamera

__all__ = ["SkinModel", "fit_skin_model", "virtual_side_camera", "skin_model_layer"]

_MOTTLE_MAX = 0.03  # the strongest mottle painted (relative)
_BAND = 0.012  # width of the face's border band sampled, share of the texture's side
_ROW_SMOOTH = 0.025  # smoothing of the colours down the head, share of the texture's side


@dataclass
class SkinModel:
    """A person's skin (and hair) colour down the head, RGB 0–255.

    Attributes
    ----------
    rows : (S, 3) float64
        Colour of each texture row: the median of the face's border in the front photo's
        layer at that height (skin, or hair above the hairline), smoothed down the head.
    mottle : float
        Relative standard deviation of the skin's fine-scale variation in the front photo.
    """

    rows: np.ndarray
    mottle: float


def fit_skin_model(front_layer: np.ndarray, front_mask: np.ndarray, head_mask: np.ndarray | None = None,
                   hair_row: float | None = None, chin_row: float | None = None) -> SkinModel:
    """The skin model of the front photo's layer in texture space.

    Down the face, each row takes the median colour of the face just inside its border;
    below the chin the neck keeps the chin's colour (a collar is not skin); above
    ``hair_row`` the sides take the hair's colour: the median of what the front photo shows
    of the head just outside the face's border there (the face's own colour when it shows
    none).

    Parameters
    ----------
    front_layer : (S, S, 3) uint8
        The (de-lit) front photo brought into texture space.
    front_mask : (S, S) bool
        Where the texture takes the front photo (inside the feature lines).
    head_mask : (S, S) bool, optional
        Where the front photo shows the head, in texture space.
    hair_row, chin_row : float, optional
        Texture rows of the ears' tops (where the hair at the sides usually ends) and of
        the chin.
    """
    size = front_layer.shape[0]
    band_px = max(2, int(round(_BAND * size)))
    inner = cv2.erode(front_mask.astype(np.uint8), np.ones((2 * band_px + 1,) * 2, np.uint8)) > 0
    band = front_mask & ~inner
    img = front_layer.astype(np.float64)
    rows = np.full((size, 3), np.nan)
    for r in np.flatnonzero(band.sum(axis=1) >= 3):
        rows[r] = np.median(img[r][band[r]], axis=0)
    index = np.arange(size)
    if chin_row is not None:
        rows[index > chin_row] = np.nan
    have = np.flatnonzero(np.isfinite(rows[:, 0]))
    if not len(have):  # no border: the face's own median
        rows[:] = np.median(img[front_mask] if front_mask.any() else img.reshape(-1, 3), axis=0)
    else:
        for k in range(3):  # rows above and below take the nearest known colour
            rows[:, k] = np.interp(index, have, rows[have, k])
    if hair_row is not None and head_mask is not None:
        near = cv2.dilate(front_mask.astype(np.uint8), np.ones((6 * band_px + 1,) * 2, np.uint8)) > 0
        hair = near & ~front_mask & head_mask & (index < hair_row)[:, None]
        if hair.sum() >= 20:
            rows[index < hair_row] = np.median(img[hair], axis=0)
    rows = cv2.GaussianBlur(rows[:, None, :].astype(np.float32), (1, 0), _ROW_SMOOTH * size)[:, 0].astype(float)
    # The skin's fine variation (robust: the band crosses eyebrows, ears and hair edges).
    fine = (img - rows[:, None, :])[band].mean(axis=1) if band.any() else np.zeros(1)
    spread = 1.4826 * float(np.median(np.abs(fine - np.median(fine))))
    mottle = float(np.clip(spread / max(float(np.median(rows.mean(axis=1))), 1.0), 0.0, _MOTTLE_MAX))
    return SkinModel(rows, mottle)


def virtual_side_camera(vertices: np.ndarray, width: int, height: int) -> FittedCamera:
    """An orthographic camera where a profile photo showing the face's left would stand."""
    return FittedCamera(Camera.fit(vertices, width, height, yaw_deg=90.0), {})


def skin_model_layer(model: SkinModel, seed: int = 0) -> np.ndarray:
    """(S, S, 3) uint8: the model painted in texture space (each row its colour, mottled)."""
    size = len(model.rows)
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), max(1.0, size / 256))
    noise /= max(float(noise.std()), 1e-9)
    layer = model.rows[:, None, :].astype(np.float32) * (1 + model.mottle * noise)[..., None]
    return np.clip(layer, 0, 255).astype(np.uint8)
