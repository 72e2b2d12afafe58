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

from dataclasses import dataclass

import numpy as np

__all__ = ["MIDLINE", "FEATURES", "ProfileFit", "fit_profile", "profile_features", "outline_distance"]

#: The largest roll :func:`fit_profile` considers, radians (20 degrees).
MAX_ANGLE = 0.35
PRIOR = (1.0, 4.0)
ANCHORS = False
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


def _extreme(curve: np.ndarray, lo: float, hi: float, kind: str) -> int | None:
    """Row of a profile curve's most forward (``"out"``, smallest x) or most backward
    (``"in"``) point between two rows, the middle of it where it runs level."""
    a, b = int(max(0, np.floor(min(lo, hi)))), int(min(len(curve) - 1, np.ceil(max(lo, hi))))
    seg = curve[a:b + 1]
    if b <= a or not np.isfinite(seg).any():
        return None
    seg = seg if kind == "out" else -seg
    best = np.nanmin(seg)
    level = np.flatnonzero(seg <= best + 1.0)
    # The run of level rows around the first extreme, and its middle.
    k = level[0]
    run = [k]
    for j in level[1:]:
        if j != run[-1] + 1:
            break
        run.append(j)
    return a + int(round(0.5 * (run[0] + run[-1])))


#: Face mesh landmarks near the profile's own landmarks, to look for them near: the nose
#: tip, under the nose, the upper lip, the mouth (between the inner lips), the lower lip,
#: the fold under it and the chin; and whether each is a forward bump or a hollow.
FEATURES = {"tip": ((1,), "out"), "subnasale": ((2,), "in"), "upper_lip": ((0,), "out"), "mouth": ((13, 14), "in"),
            "lower_lip": ((17,), "out"), "fold": ((18,), "in"), "chin": ((175,), "out")}


def profile_features(prof: np.ndarray, guesses: dict[str, float], ipd: float) -> dict[str, int]:
    """Rows of the profile's own landmarks (:data:`FEATURES`), each the curve's most forward
    point (a bump) or most backward point (a hollow) within 0.15 IPD of where it is expected,
    kept only when it is that window's extreme inside it, standing out of the window's ends
    by at least 2 % of the IPD (a lip that does not stand out is no landmark).

    Parameters
    ----------
    prof : (H,) float
        Column of the profile in each row (the nose towards the image's left), NaN where none.
    guesses : dict of str to float
        Expected rows, by :data:`FEATURES` name.
    ipd : float
        Distance between the pupils in the side photo's scale, pixels.

    Returns
    -------
    dict of str to int
        Rows of those found.
    """
    out = {}
    half = 0.15 * ipd
    for name, row in guesses.items():
        kind = FEATURES[name][1]
        k = _extreme(prof, row - half, row + half, kind)
        if k is None:
            continue
        a, b = int(max(0, row - half)), int(min(len(prof) - 1, row + half))
        ends = prof[[a, b]]
        if not np.isfinite(ends).all() or not a < k < b:
            continue
        stand = (np.min(ends) - prof[k]) if kind == "out" else (prof[k] - np.max(ends))
        if stand >= 0.02 * ipd:
            out[name] = k
    return out


#: The profile's landmarks whose heights hold the fit: under the nose and the mouth, the
#: sharpest hollows of the profile (a bump's most forward point runs level over rows).
_HEIGHT_ANCHORS = ("subnasale", "mouth")


def fit_profile(mask: np.ndarray, landmarks: np.ndarray, front_top: float, ipd_front: float,
                scale_guess: float = 1.0, distance: np.ndarray | None = None) -> ProfileFit:
    """Lay the face mesh's midline onto a profile silhouette facing left.

    Two stages. First a chamfer fit from several starts: the midline landmarks drawn to the
    outline, the top of the head kept level with the silhouette's top. Then, with the
    profile's own landmarks found near where that fit puts them (:func:`profile_features`),
    again with the heights of the point under the nose and of the mouth held to theirs: the
    face mesh's depth is its weakest part, and it must not tilt or shrink the heights the
    front photo gives.

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

    from .silhouette import row_extents

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
    anchors = {}

    def residuals(x):
        fit = ProfileFit(x[0], x[1], x[2:4], 0.0)
        uv = fit.apply(zy)
        d = ndi.map_coordinates(dist, [np.clip(uv[:, 1], 0, h - 1), np.clip(uv[:, 0], 0, w - 1)], order=1)
        # Outside the photo counts as far off.
        off = np.maximum(0, -uv).sum(axis=1) + np.maximum(0, uv - [w - 1, h - 1]).sum(axis=1)
        extra = [(3.0 if anchors else 0.5) * (fit.apply([[z_top, front_top]])[0, 1] - top)]
        for name, (zy_a, row) in anchors.items():
            extra.append(3.0 * (fit.apply(zy_a[None])[0, 1] - row))
        # Priors: photos taken alike (the same scale), the head held alike (no roll).
        f = 0.02 * x[0] * ipd_front
        extra += [PRIOR[0] * f * (x[0] / scale_guess - 1) / 0.04, PRIOR[1] * f * x[1] / np.radians(4)]
        return np.r_[d + off, extra]

    def solve(x0):
        s = x0[0]
        lo = np.array([0.3 * s, -MAX_ANGLE, -np.inf, -np.inf])
        hi = np.array([3.0 * s, MAX_ANGLE, np.inf, np.inf])
        sol = least_squares(residuals, x0, bounds=(lo, hi), loss="soft_l1", f_scale=0.02 * s * ipd_front,
                            x_scale=np.array([0.05 * s, 0.02, 2.0, 2.0]), max_nfev=200)
        return ProfileFit(float(sol.x[0]), float(sol.x[1]), sol.x[2:4].copy(),
                          float(np.median(np.abs(sol.fun[:len(zy)]))))

    # Scales to start from: the photos' own ratio, and the one that puts the nose tip at
    # the height of the silhouette's most forward point in the upper part of the head.
    band = rows[: max(3, int(0.6 * len(rows)))]
    forward = float(band[np.nanargmin(prof[band])])
    starts = [scale_guess]
    if tip_y - front_top > 0.2 * ipd_front:
        starts.append((forward - top) / (tip_y - front_top))
    best = None
    for s0 in starts:
        if not np.isfinite(s0) or s0 <= 0:
            continue
        for f in (0.92, 1.0, 1.08):
            s = s0 * f
            ty = top - s * front_top
            r = int(np.clip(round(s * tip_y + ty), rows[0], rows[-1]))
            win = np.arange(max(rows[0], r - int(0.25 * s * ipd_front)), min(rows[-1], r + int(0.25 * s * ipd_front)) + 1)
            if not np.isfinite(prof[win]).any():
                continue
            fit = solve(np.array([s, 0.0, float(np.nanmin(prof[win])) - s * tip_z, ty]))
            if best is None or fit.cost < best.cost:
                best = fit
    if best is None:
        raise ValueError("no profile to fit")
    ipd_s = best.scale * ipd_front
    guesses = {name: float(best.apply(landmarks[list(ids)][:, [2, 1]].mean(axis=0)[None])[0, 1])
               for name, (ids, _) in FEATURES.items()}
    found = profile_features(prof, guesses, ipd_s)
    for name in _HEIGHT_ANCHORS:
        if name in found:
            anchors[name] = (landmarks[list(FEATURES[name][0])][:, [2, 1]].mean(axis=0), float(found[name]))
    if not anchors or not ANCHORS:
        return best
    return solve(np.r_[best.scale, best.angle, best.offset])
