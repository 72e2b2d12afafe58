"""The front photo's face mesh laid onto the side photo's profile.

The face mesh of the front photo (:func:`recon.landmarks.models.face_landmarks`) has a
depth for every landmark. Seen from the side, its midline landmarks — forehead, nose
bridge and tip, under the nose, lips, chin — trace the face's profile as the front photo's
model believes it to be; the side photo's silhouette shows the real one. :func:`fit_profile`
finds the similarity (scale, a roll, a shift) that lays the first onto the second: a chamfer fit [1]_, each
landmark drawn to the nearest point of the silhouette's outline, robustly, from several
starts. The fit carries every landmark, and so every feature point the face mesh places,
into the side photo (:mod:`recon.landmarks.side`).

References
----------
.. [1] H. G. Barrow, J. M. Tenenbaum, R. C. Bolles, H. C. Wolf, "Parametric correspondence
   and chamfer matching: two new techniques for image matching", IJCAI (1977).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["MIDLINE", "ProfileFit", "fit_profile", "outline_distance"]

#: The largest roll :func:`fit_profile` considers, radians (20 degrees).
MAX_ANGLE = 0.35
#: The priors of the fit, as one standard deviation: the side photo's scale within 4 % of
#: ``scale_guess`` (photos taken alike), the roll within a degree (the head held alike;
#: the face mesh's depth, its weakest part, must not tilt the heights the front photo gives).
SCALE_SPREAD = 0.04
ROLL_SPREAD = np.radians(1.0)
#: How many midline landmarks' worth an anchor's height counts in :func:`fit_profile`.
ANCHOR_WEIGHT = 4.0
#: Face mesh landmarks on the face's midline that the profile shows, from the top of the
#: forehead to under the chin (not the inner lips, hidden behind the outer ones).
MIDLINE = (10, 151, 9, 8, 168, 6, 197, 195, 5, 4, 1, 19, 94, 2, 164, 0, 17, 18, 200, 199, 175, 152)


@dataclass(frozen=True)
class ProfileFit:
    """Face mesh (depth, height) → side photo pixels (the nose towards the image's left).

    ``uv = scale * R(angle) @ (z, y) + offset``, with z the landmarks' depth (smaller nearer
    the front camera, so further forward; the face mesh gives it in the scale of its pixels)
    and y their row in the front photo.

    Attributes
    ----------
    scale : float
        Side pixels per front pixel.
    angle : float
        Roll between the two photos' views of the profile (the head nodding between them,
        and what the face mesh's depth gets wrong), radians.
    offset : (2,) float
    cost : float
        Median distance of the midline landmarks to the outline, in side pixels.
    """

    scale: float
    angle: float
    offset: np.ndarray
    cost: float

    def apply(self, zy: np.ndarray) -> np.ndarray:
        """(K, 2) side pixels of (K, 2) face mesh (depth, height)."""
        zy = np.atleast_2d(np.asarray(zy, float))
        c, s = np.cos(self.angle), np.sin(self.angle)
        p = zy * self.scale
        return np.c_[c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]] + self.offset

    def inverse(self, uv: np.ndarray) -> np.ndarray:
        """(K, 2) face mesh (depth, height) of (K, 2) side pixels."""
        q = (np.atleast_2d(np.asarray(uv, float)) - self.offset) / self.scale
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.c_[c * q[:, 0] + s * q[:, 1], -s * q[:, 0] + c * q[:, 1]]


def outline_distance(mask: np.ndarray) -> np.ndarray:
    """(H, W) float32: distance of every pixel to the silhouette's outline, pixels."""
    from scipy import ndimage as ndi

    edge = mask & ~ndi.binary_erosion(mask, border_value=0)
    return ndi.distance_transform_edt(~edge).astype(np.float32)


def fit_profile(mask: np.ndarray, landmarks: np.ndarray, front_top: float, ipd_front: float,
                scale_guess: float = 1.0, distance: np.ndarray | None = None,
                anchors: Sequence[tuple[np.ndarray, float]] = ()) -> ProfileFit:
    """Lay the face mesh's midline onto a profile silhouette facing left.

    A chamfer fit from several starts (scales around ``scale_guess`` and around the one
    that puts the nose tip at the silhouette's most forward point): the midline landmarks
    drawn to the outline (robustly: a lip or a chin the mesh gets wrong does not pull the
    rest), the top of the head kept level with the silhouette's top, and the scale and roll
    held near the photos' own (:data:`SCALE_SPREAD`, :data:`ROLL_SPREAD`).

    Parameters
    ----------
    mask : (H, W) bool
        The head's silhouette in the side photo, the nose towards the image's left.
    landmarks : (478, 3) float
        The front photo's face mesh (pixels, and depth in the same scale).
    front_top : float
        Row of the top of the head in the front photo.
    ipd_front : float
        Distance between the pupils in the front photo, pixels.
    scale_guess : float
        Side pixels per front pixel to start from (the photos' heights' ratio when they
        were taken alike).
    distance : (H, W) float, optional
        :func:`outline_distance` of the mask, when already computed.
    anchors : sequence of ((2,) array, float)
        Face mesh (depth, height) of parts the side photo shows by themselves (the corner
        of the mouth, the eye), each with the row it was seen at: their heights are held
        to those rows (:data:`ANCHOR_WEIGHT`), which settles the fit where the outline alone
        is ambiguous (glasses before the eyes make a second nose). Only the heights:
        the mesh's depth is its weakest part.

    Returns
    -------
    ProfileFit

    Raises
    ------
    ValueError
        The silhouette has no rows to fit to.
    """
    from scipy import ndimage as ndi
    from scipy.optimize import least_squares

    from .silhouette import on_left_edge, row_extents

    dist = outline_distance(mask) if distance is None else distance
    h, w = mask.shape
    prof, _ = row_extents(mask)
    rows = np.flatnonzero(np.isfinite(prof))
    if len(rows) < 10:
        raise ValueError("no profile to fit")
    top = float(rows[0])
    zy = landmarks[list(MIDLINE)][:, [2, 1]]
    nose = landmarks[1, [2, 1]]
    tip_z, tip_y = float(nose[0]), float(nose[1])
    z_top = float(landmarks[10, 2])
    a_zy = np.array([np.asarray(zy_a, float) for zy_a, _ in anchors]).reshape(-1, 2)
    a_row = np.array([float(r) for _, r in anchors])

    def residuals(x):
        fit = ProfileFit(x[0], x[1], x[2:4], 0.0)
        uv = fit.apply(zy)
        d = ndi.map_coordinates(dist, [np.clip(uv[:, 1], 0, h - 1), np.clip(uv[:, 0], 0, w - 1)], order=1)
        # Outside the photo counts as far off.
        off = np.maximum(0, -uv).sum(axis=1) + np.maximum(0, uv - [w - 1, h - 1]).sum(axis=1)
        # The top of the head level with the silhouette's top, and the priors.
        f = 0.02 * x[0] * ipd_front
        extra = [0.5 * (fit.apply([[z_top, front_top]])[0, 1] - top),
                 f * (x[0] / scale_guess - 1) / SCALE_SPREAD, f * x[1] / ROLL_SPREAD]
        held = ANCHOR_WEIGHT * (fit.apply(a_zy)[:, 1] - a_row) if len(a_row) else []
        return np.r_[d + off, held, extra]

    def solve(x0):
        s = x0[0]
        lo = np.array([0.3 * s, -MAX_ANGLE, -np.inf, -np.inf])
        hi = np.array([3.0 * s, MAX_ANGLE, np.inf, np.inf])
        sol = least_squares(residuals, x0, bounds=(lo, hi), loss="soft_l1", f_scale=0.02 * s * ipd_front,
                            x_scale=np.array([0.05 * s, 0.02, 2.0, 2.0]), max_nfev=200)
        # With anchors the best start is the one that lays the mesh on the outline with
        # the parts where they were seen: the anchors' misfit, in pixels, counts with it.
        misfit = float(np.mean(np.abs(sol.fun[len(zy):len(zy) + len(a_row)]))) / ANCHOR_WEIGHT if len(a_row) else 0.0
        return ProfileFit(float(sol.x[0]), float(sol.x[1]), sol.x[2:4].copy(),
                          float(np.median(np.abs(sol.fun[:len(zy)])))), misfit

    # Scales to start from: the photos' own ratio, and the one that puts the nose tip at
    # the height of the silhouette's most forward point in the upper part of the head.
    # (None when that point is on the photo's edge: a profile cut by it has no nose tip to
    # measure, and the edge's first row would start a face a fraction of the size.)
    band = rows[: max(3, int(0.6 * len(rows)))]
    k = int(np.nanargmin(prof[band]))
    starts = [scale_guess]
    if tip_y - front_top > 0.2 * ipd_front and not on_left_edge(prof[band[k]]):
        starts.append((float(band[k]) - top) / (tip_y - front_top))
    best, best_cost = None, np.inf
    for s0 in starts:
        if not np.isfinite(s0) or s0 <= 0:
            continue
        for f in (0.92, 1.0, 1.08):
            s = s0 * f
            shifts = [top - s * front_top]
            # And the shift that puts the anchors at their rows, with the top left to follow.
            shifts += [float(np.mean(a_row - s * a_zy[:, 1]))] if len(a_row) else []
            for ty in shifts:
                r = int(np.clip(round(s * tip_y + ty), rows[0], rows[-1]))
                win = np.arange(max(rows[0], r - int(0.25 * s * ipd_front)),
                                min(rows[-1], r + int(0.25 * s * ipd_front)) + 1)
                if not np.isfinite(prof[win]).any():
                    continue
                fit, misfit = solve(np.array([s, 0.0, float(np.nanmin(prof[win])) - s * tip_z, ty]))
                # With anchors, compared in the front photo's pixels: the anchors' start may
                # find a much smaller face, which lies closer to any outline. (Without, the
                # side photo's pixels, as measured best on the synthetic photos.)
                cost = (fit.cost + misfit) / fit.scale if len(a_row) else fit.cost
                if cost < best_cost:
                    best, best_cost = fit, cost
    if best is None:
        raise ValueError("no profile to fit")
    return best
