"""Skin and hair colour models: where the hairline is, whether an ear is skin.

A model is the mean and covariance of colours (:func:`to_lab`) sampled where a class is known to
be (the face mesh's forehead and cheeks for skin, the crown of the head for hair). A pixel
belongs to the class it is nearer to in Mahalanobis distance; with no hair model (a bald
head or a shaved one), to "not skin" when it is far from the skin. Comparing the two
classes, rather than thresholding the distance to the skin alone, keeps a shaded temple
(darker skin, the same hue) on the skin's side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ColourModel", "to_lab", "lab_at", "sample_patches", "hair_share", "hairline_on"]

#: A floor on the spread (CIELAB L, a, b variances): a flat-lit forehead would otherwise
#: make every shadow look foreign.
_FLOOR = np.diag([9.0, 4.0, 4.0])
#: Squared Mahalanobis distance beyond which a colour is not of a class (about 4 sigma in 3D).
FAR = 16.0


@dataclass(frozen=True)
class ColourModel:
    """A Gaussian in CIELAB.

    Attributes
    ----------
    mean : (3,) float
    icov : (3, 3) float
        Inverse covariance.
    n : int
        Number of samples.
    """

    mean: np.ndarray
    icov: np.ndarray
    n: int

    @classmethod
    def fit(cls, lab: np.ndarray) -> ColourModel:
        """From (K, 3) CIELAB samples (K >= 2)."""
        lab = np.asarray(lab, float).reshape(-1, 3)
        cov = np.cov(lab.T) + _FLOOR
        return cls(lab.mean(axis=0), np.linalg.inv(cov), len(lab))

    def distance2(self, lab: np.ndarray) -> np.ndarray:
        """Squared Mahalanobis distances of (..., 3) CIELAB colours."""
        d = np.asarray(lab, float) - self.mean
        return np.einsum("...i,ij,...j->...", d, self.icov, d)


def to_lab(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 colours of an (H, W, 3) uint8 RGB photo that shading changes little.

    CIELAB (D65) with its chroma divided by the lightness: (L, 50 a / L, 50 b / L), L
    floored at 10. Shade scales a surface's colour down, which lowers L and shrinks a and b
    roughly in proportion; the ratios keep skin in the shadow of a temple near lit skin
    while the hair's different hue stays apart.
    """
    import cv2

    lab = cv2.cvtColor(np.asarray(image, np.float32) / 255.0, cv2.COLOR_RGB2Lab)
    light = np.maximum(lab[..., :1], 10.0)
    lab[..., 1:] *= 50.0 / light
    return lab


def lab_at(lab: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(K, 3) colours of a CIELAB image (:func:`to_lab`) at (K, 2) pixel positions
    (nearest pixel, clipped to the image)."""
    h, w = lab.shape[:2]
    xy = np.clip(np.round(np.asarray(pts, float)).astype(int), 0, [w - 1, h - 1])
    return lab[xy[:, 1], xy[:, 0]]


def sample_patches(lab: np.ndarray, centres: np.ndarray, radius: int, mask: np.ndarray | None = None) -> np.ndarray:
    """(K, 3) colours of a CIELAB image in squares of side ``2 radius + 1`` around (M, 2)
    centres, only where ``mask`` (H, W) is True when given."""
    h, w = lab.shape[:2]
    out = []
    for x, y in np.round(np.asarray(centres, float)).astype(int):
        x0, x1, y0, y1 = max(0, x - radius), min(w, x + radius + 1), max(0, y - radius), min(h, y + radius + 1)
        if x1 <= x0 or y1 <= y0:
            continue
        patch = lab[y0:y1, x0:x1]
        if mask is not None:
            patch = patch[mask[y0:y1, x0:x1]]
        out.append(patch.reshape(-1, 3))
    return np.concatenate(out) if out else np.zeros((0, 3))


def hair_share(lab: np.ndarray, skin: ColourModel, hair: ColourModel | None) -> float:
    """Share of (K, 3) colours that are hair rather than skin (or, with no hair model,
    far from the skin)."""
    ds = skin.distance2(lab)
    if hair is None:
        return float(np.mean(ds > FAR))
    dh = hair.distance2(lab)
    return float(np.mean((dh < ds) & (ds > 0.25 * FAR)))


def hairline_on(lab: np.ndarray, centres: np.ndarray, across: np.ndarray, half_width: float, skin: ColourModel,
                hair: ColourModel | None, scale: float) -> tuple[int | None, float]:
    """Where a path up the head passes from skin to hair.

    The colour is averaged across a band ``half_width`` pixels either side of the path at
    each of its points; the hairline is the first sharp change of colour (the colours
    ``scale`` points above and below differ by a good part of the difference between skin
    and hair, less in the shade) with hair above it and skin below (:func:`hair_share`), at
    the steepest place of that change. A smooth change, such as shading over the temple, is no hairline
    however dark it gets.

    Parameters
    ----------
    lab : (H, W, 3) float
        The photo's colours (:func:`to_lab`).
    centres : (K, 2) float
        The path, one point per pixel of it, going up.
    across : (2,) or (K, 2) float
        Unit vector(s) across the path.
    half_width : float
        Half the band's width, pixels.
    skin, hair : ColourModel
        The skin's colours, and the hair's (None: no hair sampled).
    scale : float
        How far above and below a place the colours are compared, in points of the path.

    Returns
    -------
    index : int or None
        The path's point at the hairline; None when there is none.
    strength : float
        Share of the band that is hair just above the hairline, in [0, 1].
    """
    centres = np.asarray(centres, float)
    across = np.broadcast_to(np.asarray(across, float), centres.shape)
    n = max(2, int(round(scale)))
    if len(centres) < 2 * n + 2:
        return None, 0.0
    offsets = np.linspace(-half_width, half_width, 9)
    band = lab_at(lab, (centres[:, None, :] + offsets[None, :, None] * across[:, None, :]).reshape(-1, 2))
    band = band.reshape(len(centres), -1, 3)
    mean = band.mean(axis=1)
    cum = np.r_[np.zeros((1, 3)), np.cumsum(mean, axis=0)]
    k = np.arange(n, len(centres) - n)
    below = (cum[k] - cum[k - n]) / n
    above = (cum[k + n] - cum[k]) / n
    contrast = np.linalg.norm(above - below, axis=1)
    # The change to expect: a good part of the skin-to-hair difference, less in the shade
    # (a darker patch of skin is nearer dark hair).
    shade = np.clip(below[:, 0] / max(skin.mean[0], 1.0), 0.3, 1.0)
    need = np.maximum(0.3 * (np.linalg.norm(hair.mean - skin.mean) if hair is not None else 40.0) * shade, 4.0)
    for j in np.flatnonzero(contrast > need):
        share = hair_share(band[min(len(band) - 1, k[j] + n)], skin, hair)
        # Hair above, skin below (not a change within the hair, a fringe's shadow).
        if share < 0.6 or hair_share(band[max(0, k[j] - n)], skin, hair) > 0.4:
            continue
        # The steepest place of this change.
        run = j
        while run + 1 < len(k) and contrast[run + 1] > need[run + 1]:
            run += 1
        return int(k[j + int(np.argmax(contrast[j:run + 1]))]), share
    return None, 0.0
