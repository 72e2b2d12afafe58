"""Feature points on a front photo.

Three sources, each point keeping the name of its own (:data:`SOURCES`):

- ``model``: the face mesh's landmarks mapped by the table (:mod:`recon.landmarks.mapping`),
  the pupils at the iris centres;
- ``silhouette``: what the mesh does not cover, read off the head's silhouette and colours —
  the top of the hair (11.5) where the face's midline leaves the silhouette, the hairline
  (11.1, and 11.2/11.3 above the outer ends of the eyebrows) where skin colour gives way
  going up the forehead, the ears where they stand out of the head's outline;
- ``rule``: proportions of the face when the photo shows nothing better (the top of the
  skull 11.4 under the hair, a hairline that is not there, ears hidden by hair).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mpeg4.errors import InputError

from .mapping import apply_mapping, load_mapping
from .models import face_landmarks
from .silhouette import head_mask, row_extents

__all__ = ["SOURCES", "ViewPoints", "detect_front", "skin_model", "hairline_along"]

#: How a point was found, from best to worst supported.
SOURCES = ("model", "silhouette", "rule")

# Face mesh landmarks used below by name (the surface mesh's own numbering).
_FOREHEAD = (151, 108, 337, 109, 338)  # skin patches for the colour model, with the cheeks
_CHEEKS = (50, 280, 205, 425, 118, 347)
_FOREHEAD_TOP, _NASION, _CHIN = 10, 168, 152
_OVAL_LEFT = (10, 338, 297, 332, 284, 251, 389, 356, 454, 323, 361, 288, 397, 365, 379, 378, 400, 377, 152)
_OVAL_RIGHT = (10, 109, 67, 103, 54, 21, 162, 127, 234, 93, 132, 58, 172, 136, 150, 149, 176, 148, 152)


@dataclass
class ViewPoints:
    """Feature points found on one photo.

    Attributes
    ----------
    points : dict of str to (2,) float64
        FP id → pixel.
    confidence : dict of str to float
        FP id → [0, 1].
    source : dict of str to str
        FP id → one of :data:`SOURCES`.
    mask : (H, W) bool
        The head's silhouette.
    ipd_px : float
        Distance between the pupils, pixels (the scale of the face in this photo).
    extras : dict
        What later steps reuse (landmarks, the midline, ear rows...).
    """

    points: dict[str, np.ndarray] = field(default_factory=dict)
    confidence: dict[str, float] = field(default_factory=dict)
    source: dict[str, str] = field(default_factory=dict)
    mask: np.ndarray | None = None
    ipd_px: float = float("nan")
    extras: dict = field(default_factory=dict)

    def put(self, fp: str, xy, confidence: float, source: str) -> None:
        self.points[fp] = np.asarray(xy, dtype=np.float64)
        self.confidence[fp] = float(np.clip(confidence, 0.0, 1.0))
        self.source[fp] = source


def skin_model(image: np.ndarray, centres: np.ndarray, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and inverse covariance of the skin's CIELAB colour in square patches.

    Parameters
    ----------
    image : (H, W, 3) uint8
    centres : (K, 2) float
        Patch centres, pixels.
    radius : int
        Half the patch side, pixels.
    """
    from skimage.color import rgb2lab

    h, w = image.shape[:2]
    samples = []
    for x, y in np.round(centres).astype(int):
        x0, x1, y0, y1 = max(0, x - radius), min(w, x + radius + 1), max(0, y - radius), min(h, y + radius + 1)
        if x1 > x0 and y1 > y0:
            samples.append(rgb2lab(image[y0:y1, x0:x1]).reshape(-1, 3))
    lab = np.concatenate(samples)
    mean = lab.mean(axis=0)
    # A floor on the spread: a flat-lit forehead would otherwise call every shadow hair.
    cov = np.cov(lab.T) + np.diag([9.0, 4.0, 4.0])
    return mean, np.linalg.inv(cov)


def _not_skin(image, pts: np.ndarray, mean, icov, limit: float = 16.0) -> np.ndarray:
    from skimage.color import rgb2lab

    h, w = image.shape[:2]
    xy = np.clip(np.round(pts).astype(int), 0, [w - 1, h - 1])
    lab = rgb2lab(image[xy[:, 1], xy[:, 0]][None])[0]
    d = lab - mean
    return np.einsum("ki,ij,kj->k", d, icov, d) > limit


def hairline_along(image: np.ndarray, mask: np.ndarray, start: np.ndarray, up: np.ndarray, half_width: float,
                   skin: tuple, step: float = 1.0) -> tuple[np.ndarray | None, float]:
    """First place going ``up`` from ``start`` where the head stops being skin-coloured.

    A band ``half_width`` pixels either side of the line is tested at each step; the
    hairline is where most of it is not skin and stays so for the next few steps.

    Returns
    -------
    point : (2,) float or None
        None when the line leaves the silhouette first (no hair there).
    strength : float
        Share of the band that is not skin just past the hairline, in [0, 1].
    """
    up = np.asarray(up, float) / np.linalg.norm(up)
    across = np.array([-up[1], up[0]])
    offsets = np.linspace(-half_width, half_width, 9)
    h, w = mask.shape
    run, first = 0, None
    need = max(3, int(0.25 * half_width / step))
    share = 0.0
    for k in range(int(2 * h / step)):
        c = start + k * step * up
        if not (0 <= c[0] < w and 0 <= c[1] < h) or not mask[int(c[1]), int(c[0])]:
            return None, 0.0
        band = c + offsets[:, None] * across
        share = float(np.mean(_not_skin(image, band, *skin)))
        if share >= 0.6:
            if run == 0:
                first = c
            run += 1
            if run >= need:
                return first, share
        else:
            run = 0
    return None, 0.0


def _midline(lm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A point on the face's midline (the nasion) and the unit vector up it."""
    base = lm[_NASION, :2]
    up = lm[_FOREHEAD_TOP, :2] - lm[_CHIN, :2]
    return base, up / np.linalg.norm(up)


def _yaw_asymmetry(lm: np.ndarray) -> float:
    """(left − right) / (left + right) of the nose tip's distances to the two face edges:
    0 for a face looking at the camera, ±1 for a profile."""
    nose = lm[1, 0]
    left, right = lm[454, 0] - nose, nose - lm[234, 0]
    return float((left - right) / max(left + right, 1e-9))


def _ears(front: ViewPoints, image_w: int, lm: np.ndarray, up: np.ndarray) -> None:
    """10.x on a front photo: the rows where each ear stands out of the head's outline.

    In a front photo the ears show as two bumps on the outline between the brows and the
    mouth. The top and bottom rows of a bump give the heights of the ear's top (10.1, 10.9)
    and of its lobe (10.5, 10.7); the points themselves sit on the head's outline where the
    ear meets it (the outline above and below the bump, joined straight across).
    """
    mask, ipd = front.mask, front.ipd_px
    left_x, right_x = row_extents(mask)
    y_brow = min(lm[105, 1], lm[334, 1])
    y_mouth = 0.5 * (lm[0, 1] + lm[17, 1])
    rows = np.arange(max(0, int(y_brow - 0.4 * ipd)), min(mask.shape[0], int(y_mouth + 0.2 * ipd)))
    front.extras["ears"] = {}
    for side, extent, oval, sign in (("L", right_x, _OVAL_LEFT, 1.0), ("R", left_x, _OVAL_RIGHT, -1.0)):
        ov = lm[list(oval), :2]
        order = np.argsort(ov[:, 1])
        face_edge = np.interp(rows, ov[order, 1], ov[order, 0])
        stick_out = sign * (extent[rows] - face_edge)
        ear = np.nan_to_num(stick_out, nan=0.0) > 0.06 * ipd
        ids = {"L": ("10.1", "10.9", "10.5", "10.7"), "R": ("10.2", "10.10", "10.6", "10.8")}[side]
        runs = _runs(ear)
        if runs:
            a, b = max(runs, key=lambda r: r[1] - r[0])
        if runs and (b - a) > 0.25 * ipd:
            top, bottom = rows[a], rows[b - 1]
            conf, src = 0.55, "silhouette"
        else:  # hidden by hair or flat to the head: the classic proportions
            top = 0.5 * (lm[105 if side == "R" else 334, 1] + lm[33 if side == "R" else 263, 1])
            bottom = lm[2, 1]
            conf, src = 0.2, "rule"
        # The outline above and below the ear, joined straight across the ear's rows.
        above = int(np.clip(top - 0.08 * ipd, 0, mask.shape[0] - 1))
        below = int(np.clip(bottom + 0.08 * ipd, 0, mask.shape[0] - 1))
        xa, xb = extent[above], extent[below]
        if not (np.isfinite(xa) and np.isfinite(xb)):
            continue

        def edge(y):
            t = (y - above) / max(below - above, 1)
            return xa + t * (xb - xa) - sign * 0.02 * ipd

        join = 0.12 * (bottom - top)
        for fp, y in zip(ids, (top, top + join, bottom, bottom - join)):
            front.put(fp, (edge(y), y), conf, src)
        front.extras["ears"][side] = (float(top), float(bottom), src)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.r_[0, flags.astype(int), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def detect_front(image: np.ndarray, where: str = "front photo") -> ViewPoints:
    """Feature points on a front photo (see the module docstring).

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo of the face looking at the camera.
    where : str
        The photo's name, for messages.

    Returns
    -------
    ViewPoints
        Every point a front photo shows (``shown_in("front")``), each with a confidence
        and a source; ``extras`` holds the face mesh ``landmarks`` (478, 3) and the
        ``midline``.

    Raises
    ------
    InputError
        No face found, or the face is turned too far to one side to be a front photo.
    """
    faces = face_landmarks(image)
    if not faces:
        raise InputError("no face found in the front photo", where=where,
                         fix="give a photo of the face from the front, evenly lit, the whole face and both eyes "
                             "visible (if the two photos were given the other way round, swap them)")
    lm = faces[0]
    asym = _yaw_asymmetry(lm)
    if abs(asym) > 0.55:
        raise InputError(f"the face in the front photo is turned to one side (asymmetry {asym:+.2f})", where=where,
                         fix="take the front photo with the face looking straight into the camera (if this is the "
                             "side photo, swap the two)")
    front = ViewPoints()
    front.extras.update(landmarks=lm, asymmetry=asym, faces=len(faces))
    mapping = load_mapping()
    pts = apply_mapping(lm[:, :2], mapping)
    ipd = float(np.linalg.norm(pts["3.5"] - pts["3.6"]))
    front.ipd_px = ipd
    # Smaller faces and turned heads make the mesh less sure.
    quality = min(1.0, ipd / 60.0) * (1.0 - 0.8 * min(abs(asym) / 0.55, 1.0) ** 2)
    h, w = image.shape[:2]
    for fp, xy in pts.items():
        conf = quality * (0.95 - 0.05 * mapping[fp].fit_error_pct)
        if -0.5 <= xy[0] <= w - 0.5 and -0.5 <= xy[1] <= h - 0.5:
            front.put(fp, xy, max(conf, 0.3 * quality), "model")
    front.mask = head_mask(image)
    if not front.mask.any():
        raise InputError("no head found in the front photo (the person could not be told from the background)",
                         where=where, fix="photograph the person against a plain, contrasting background")
    base, up = _midline(lm)
    front.extras["midline"] = (base, up)
    # Top of the hair: where the midline leaves the silhouette.
    top = _leave(front.mask, base, up)
    front.put("11.5", top, 0.8, "silhouette")
    # Hairline: skin colour up the forehead's midline and above the eyebrows' outer ends.
    r = max(2, int(0.03 * ipd))
    skin = skin_model(image, lm[list(_FOREHEAD + _CHEEKS), :2], r)
    start = lm[151, :2]
    hair, strength = hairline_along(image, front.mask, start, up, 0.08 * ipd, skin)
    if hair is not None:
        front.put("11.1", hair, 0.45 + 0.4 * strength, "silhouette")
    else:  # no hair on the forehead: as high above the brows as the nose base is below them
        glabella = 0.5 * (pts["4.1"] + pts["4.2"])
        front.put("11.1", glabella + (glabella - pts["9.15"]), 0.25, "rule")
    for fp, brow in (("11.3", "4.5"), ("11.2", "4.6")):
        # From above the eyebrow (its top, 4.3/4.4, is higher than its outer end).
        above = pts[brow] + ((pts[{"4.5": "4.3", "4.6": "4.4"}[brow]] - pts[brow]) @ up + 0.15 * ipd) * up
        found, strength = hairline_along(image, front.mask, above, up, 0.05 * ipd, skin)
        if found is not None:
            front.put(fp, found, 0.4 + 0.4 * strength, "silhouette")
        else:
            front.put(fp, pts[brow] + (front.points["11.1"] - glabella_of(pts)) @ up * up, 0.2, "rule")
    # Top of the skull: under the hair, whose thickness a photo does not show.
    front.put("11.4", top, 0.35, "rule")
    _ears(front, w, lm, up)
    return front


def glabella_of(pts: dict) -> np.ndarray:
    """Between the inner ends of the eyebrows."""
    return 0.5 * (pts["4.1"] + pts["4.2"])


def _leave(mask: np.ndarray, start: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The last pixel of the mask going from ``start`` along ``direction`` (sub-pixel
    by the last step's half)."""
    h, w = mask.shape
    p = np.asarray(start, float)
    last = p.copy()
    for _ in range(2 * (h + w)):
        q = p + direction
        if not (0 <= q[0] < w and 0 <= q[1] < h) or not mask[int(round(q[1])), int(round(q[0]))]:
            return last + 0.5 * direction
        last = p = q
    return last
