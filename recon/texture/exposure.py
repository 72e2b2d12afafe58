"""The side photo's colour brought to the front photo's: one gain per channel.

Two photos taken apart differ in exposure and white balance; de-lit each on its own
(:mod:`recon.texture.delight` keeps each photo's mean skin colour) they still differ by
their light's intensity and colour, and when one of them keeps its light (a fit judged
implausible) by its shading too. (Two photos that both keep their light are left as taken:
between them a gain would measure their shading as much as their exposure.) The texture takes the face from the front photo and the
cheek, ear and back of the head from the side photo: uncorrected, the cheek's skin steps
in tone at the seam, which the multiresolution blend only spreads, and the face seen from
the front is two people's colours. As in the gain
compensation of panorama stitching (Brown and Lowe), the side photo is scaled by the
gains that make it agree with the front photo where both see the same skin — the cheek
that faces both cameras at moderate angles — measured as a ratio of medians, so that a
strand of hair or a misplaced pixel does not move it.

References
----------
M. Brown and D. G. Lowe, "Automatic panoramic image stitching using invariant features",
International Journal of Computer Vision 74(1), 2007, section 6.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_SAMPLES", "GAIN_RANGE", "side_gain", "apply_gain"]

#: Fewer skin vertices seen well by both photos than this: no correction.
MIN_SAMPLES = 50

#: Gains outside this range are clipped: beyond it the photos are not of one skin, or the
#: points are wrong, and a larger change would do more harm than the step it removes.
GAIN_RANGE = (0.5, 2.0)


def side_gain(front_photo: np.ndarray, side_photo: np.ndarray, front_px: np.ndarray, side_px: np.ndarray,
              usable: np.ndarray) -> np.ndarray:
    """(3,) float: per-channel gains that bring the side photo's skin to the front photo's.

    Parameters
    ----------
    front_photo, side_photo : (H, W, 3) uint8
        RGB, as they go into the texture (de-lit or not).
    front_px, side_px : (N, 2) float
        Pixels (x, y) of the same N skin vertices in each photo.
    usable : (N,) bool
        Vertices both photos see well: skin (not hair, brows, lips), visible to both
        cameras, facing each within a moderate angle.

    Returns
    -------
    gain : (3,) float
        Median of the front photo's colour over median of the side photo's, per channel,
        clipped to :data:`GAIN_RANGE`; ones when fewer than :data:`MIN_SAMPLES` vertices
        are usable or a channel is black.
    """
    a = _sample(front_photo, front_px)
    b = _sample(side_photo, side_px)
    # Only where neither photo is black or burnt out: clipped values carry no ratio.
    ok = np.asarray(usable, bool) & np.all((a > 8) & (a < 250) & (b > 8) & (b < 250), axis=1)
    if ok.sum() < MIN_SAMPLES:
        return np.ones(3)
    gain = np.median(a[ok], axis=0) / np.median(b[ok], axis=0)
    return np.clip(gain, *GAIN_RANGE)


def apply_gain(photo: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8: the photo with each channel scaled by its gain (rounded, clipped)."""
    scaled = photo.astype(np.float32) * np.asarray(gain, np.float32)
    return np.clip(np.rint(scaled), 0, 255).astype(np.uint8)


def _sample(photo: np.ndarray, px: np.ndarray) -> np.ndarray:
    """(N, 3) float colours at the nearest pixels (-1 outside the photo)."""
    h, w = photo.shape[:2]
    p = np.rint(np.asarray(px, float)).astype(np.int64)
    inside = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
    out = np.full((len(p), 3), -1.0)
    out[inside] = photo[p[inside, 1], p[inside, 0]]
    return out
