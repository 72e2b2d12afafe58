"""Feature points on a front photo.

Three sources, each point keeping the name of its own (:data:`SOURCES`):

- ``model``: the face mesh's landmarks mapped by the table (:mod:`recon.landmarks.mapping`),
  the pupils at the iris centres;
- ``silhouette``: what the mesh does not cover, read off the head's silhouette and colours —
  the top of the hair (11.5) where the face's midline leaves the silhouette; the hairline
  (11.1 up the midline from between the brows, 11.2/11.3 above the outer ends of the
  eyebrows) at the first sharp change from skin to hair colour
  (:func:`recon.landmarks.colour.hairline_on`), or at the brows when a fringe comes down
  to them; the ears where the head's outline steps out and back in beside the face, and
  the bump is skin-coloured (:func:`ear_from_outline`);
- ``rule``: proportions of the face when the photo shows nothing better (the top of the
  skull 11.4 under the hair, a hairline that is not there, ears hidden by hair).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mpeg4.errors import InputError

from .colour import FAR, ColourModel, hair_share, hairline_on, lab_at, sample_patches, to_lab
from .mapping import apply_mapping, load_mapping
from .models import face_landmarks
from .silhouette import head_mask, row_extents

__all__ = ["SOURCES", "ViewPoints", "detect_front", "skin_and_hair", "hairline_along", "ear_from_outline"]

#: How a point was found, from best to worst supported.
SOURCES = ("model", "silhouette", "rule")

# Face mesh landmarks used below by name (the surface mesh's own numbering).
# Skin patches for the colour model: the cheeks and the nose's bridge, which no fringe
# hides, and the forehead where it looks like them.
_SKIN = (50, 280, 205, 425, 118, 347, 168, 6, 197)
_FOREHEAD = (151, 108, 337, 109, 338)
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


def skin_and_hair(lab: np.ndarray, mask: np.ndarray, lm: np.ndarray, top: np.ndarray, up: np.ndarray,
                  ipd: float) -> tuple[ColourModel, ColourModel | None]:
    """The skin's colour model (the face mesh's cheeks and nose bridge, and the forehead
    where it matches them) and the hair's (the crown just below the top of the silhouette),
    None when the crown is skin-coloured (no hair)."""
    r = max(2, int(0.03 * ipd))
    skin = ColourModel.fit(sample_patches(lab, lm[list(_SKIN), :2], r))
    # The forehead too, where it is skin (not under a fringe): its light differs.
    forehead = sample_patches(lab, lm[list(_FOREHEAD), :2], r)
    forehead = forehead[skin.distance2(forehead) < FAR]
    if len(forehead) > 10:
        skin = ColourModel.fit(np.concatenate([sample_patches(lab, lm[list(_SKIN), :2], r), forehead]))
    across = np.array([-up[1], up[0]])
    crown = [top - d * ipd * up + a * ipd * across for d in (0.08, 0.16, 0.24) for a in (-0.2, 0.0, 0.2)]
    crown = sample_patches(lab, np.array(crown), r, mask)
    if len(crown) < 10 or np.median(skin.distance2(crown)) < 0.4 * FAR:
        return skin, None
    return skin, ColourModel.fit(crown)


def hairline_along(lab: np.ndarray, mask: np.ndarray, start: np.ndarray, up: np.ndarray, half_width: float,
                   skin: ColourModel, hair: ColourModel | None, scale: float) -> tuple[np.ndarray | None, float]:
    """Where the skin gives way to hair going ``up`` from ``start`` in a straight line
    (:func:`recon.landmarks.colour.hairline_on` along it).

    Parameters
    ----------
    lab : (H, W, 3) float
        The photo's colours (:func:`recon.landmarks.colour.to_lab`).
    mask : (H, W) bool
        The head's silhouette.
    start, up : (2,) float
        Where to start, and the direction up the head (pixels).
    half_width : float
        Half the band's width, pixels.
    skin, hair : ColourModel
        The skin's colours, and the hair's (None: no hair sampled).
    scale : float
        How far above and below a place the colours are compared, pixels.

    Returns
    -------
    point : (2,) float or None
        None when the line leaves the silhouette first (no hair there).
    strength : float
        Share of the band that is hair just above the hairline, in [0, 1].
    """
    up = np.asarray(up, float) / np.linalg.norm(up)
    across = np.array([-up[1], up[0]])
    h, w = mask.shape
    centres = []
    for k in range(2 * h):
        c = start + k * up
        if not (0 <= c[0] < w and 0 <= c[1] < h) or not mask[int(c[1]), int(c[0])]:
            break
        centres.append(c)
    if not centres:
        return None, 0.0
    k, share = hairline_on(lab, np.array(centres), across, half_width, skin, hair, scale)
    return (None, 0.0) if k is None else (centres[k], share)


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


def _largest_step(reach: np.ndarray, lo: int, hi: int, m: int, least: float) -> int | None:
    """The row in [lo, hi) where ``reach`` (per row) grows the most from ``m`` rows above
    to ``m`` rows below, or None when nowhere by ``least``."""
    step = reach[lo + m:hi + m] - reach[lo - m:hi - m]
    if not np.isfinite(step).any():
        return None
    k = int(np.nanargmax(step))
    return lo + k if step[k] >= least else None


def ear_from_outline(mask: np.ndarray, sign: float, centre_x: float, top_band: tuple[float, float],
                     lowest: float, ipd: float) -> dict | None:
    """An ear standing out of a front silhouette's outline, or None.

    Seen from the front an ear is a bump on the head's outline: the outline steps out at
    the top of the ear (the rim leaves the head), bulges, and steps back in under the lobe.
    The steepest step out within ``top_band`` rows and the steepest step back in below it
    (0.45–1.5 IPD lower, above ``lowest``) bound the ear; the head's own outline runs
    straight from above the one to below the other, and the ear is what lies outside it.

    Parameters
    ----------
    mask : (H, W) bool
        The head's silhouette.
    sign : {+1, -1}
        +1 for the ear on the image's right (the face's left), -1 for the other.
    centre_x : float
        Column of the face's midline.
    top_band : (float, float)
        Rows where the top of the ear may be.
    lowest : float
        Lowest row the lobe may reach.
    ipd : float
        Distance between the pupils, pixels.

    Returns
    -------
    dict or None
        ``top``, ``lobe`` (the highest and lowest pixel of the ear), ``upper_join``,
        ``lower_join`` (where the ear meets the head's line near them), each (2,) x, y;
        ``region`` (H, W) bool, the ear's pixels; ``bulge``, how far it stands out, pixels.
    """
    from scipy import ndimage as ndi

    h, w = mask.shape
    left, right = row_extents(mask)
    out = sign * ((right if sign > 0 else left) - centre_x)  # outward reach per row
    m = max(2, int(round(0.04 * ipd)))
    a, b = int(max(m, top_band[0])), int(min(h - 2 * m - 1, top_band[1]))
    if b <= a:
        return None
    y_top = _largest_step(out, a, b, m, 0.05 * ipd)
    if y_top is None:
        return None
    lo, hi = int(y_top + 0.45 * ipd), int(min(h - m - 1, y_top + 1.5 * ipd, lowest))
    if hi <= lo:
        return None
    y_bottom = _largest_step(-out, lo, hi, m, 0.04 * ipd)
    if y_bottom is None:
        return None
    # The head's line: the outline just above the ear and just below the lobe.
    ya, yb = y_top - m, y_bottom + m
    xa, xb = out[ya], out[yb]
    if not (np.isfinite(xa) and np.isfinite(xb)):
        return None
    yy, xx = np.mgrid[ya:yb + 1, 0:w]
    reach = sign * (xx - centre_x)
    line = xa + (yy - ya) / max(yb - ya, 1) * (xb - xa)
    region = np.zeros((h, w), bool)
    region[ya:yb + 1] = mask[ya:yb + 1] & (reach > line + 0.02 * ipd)
    lab, n = ndi.label(region)
    if n == 0:
        return None
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    region = lab == np.argmax(sizes)
    ys, xs = np.nonzero(region)
    bulge = float(np.max(sign * (xs - centre_x) - (xa + (ys - ya) / max(yb - ya, 1) * (xb - xa))))
    if bulge < 0.06 * ipd or np.ptp(ys) < 0.4 * ipd:
        return None
    t, bot = ys.min(), ys.max()
    band = max(1, int(0.03 * ipd))

    def outer(sel):  # the ear's pixel furthest out among those selected
        j = np.flatnonzero(sel)
        j = j[np.argmax(sign * xs[j])]
        return np.array([xs[j], ys[j]], float)

    def join(y):  # the ear's innermost pixel in row y: where it meets the head
        y = int(np.clip(round(y), t, bot))
        row = xs[ys == y]
        if len(row) == 0:
            return np.array([centre_x + sign * (xa + (y - ya) / max(yb - ya, 1) * (xb - xa)), y], float)
        return np.array([row[np.argmin(sign * row)], y], float)

    top_pt = outer(ys <= t + band)
    lobe = np.array([np.median(xs[ys >= bot - band]), bot], float)
    # The joins: the ear's front edge just below its top, and about 5 mm above the lobe's
    # bottom (where the lobe hangs free of the cheek).
    return {"top": top_pt, "lobe": lobe, "upper_join": join(t + band), "lower_join": join(bot - 0.085 * ipd),
            "region": region, "bulge": bulge}


#: The least share of an ear's pixels (in a front photo's outline) that have the skin's colour.
EAR_SKIN = 1.0 / 3.0


def _ears(front: ViewPoints, lab: np.ndarray, lm: np.ndarray, pts: dict, skin: ColourModel,
          hair: ColourModel | None) -> None:
    """10.x on a front photo: the ears where they stand out of the head's outline
    (:func:`ear_from_outline`) and are skin-coloured (not a tuft of hair); where they do
    not, the classic proportions (the ear from the brows' height to the nose's base)."""
    mask, ipd = front.mask, front.ipd_px
    centre_x = float(lm[_NASION, 0])
    y_brow = min(pts["4.3"][1], pts["4.4"][1])
    y_eye = 0.5 * (pts["3.5"][1] + pts["3.6"][1])
    y_mouth = 0.5 * (pts["8.1"][1] + pts["8.2"][1])
    front.extras["ears"] = {}
    for side, sign in (("L", 1.0), ("R", -1.0)):
        ids = {"L": ("10.1", "10.9", "10.5", "10.7"), "R": ("10.2", "10.10", "10.6", "10.8")}[side]
        ear = ear_from_outline(mask, sign, centre_x, (y_brow - 0.4 * ipd, y_eye + 0.4 * ipd),
                               y_mouth + 0.6 * ipd, ipd)
        if ear is not None:
            ys, xs = np.nonzero(ear["region"])
            pick = np.linspace(0, len(ys) - 1, min(len(ys), 400)).astype(int)
            colours = lab_at(lab, np.c_[xs[pick], ys[pick]])
            # An ear is skin: at least a third of it the skin's colour (its folds' shade and
            # hair over its rim are the rest). Loose strands over the backdrop are neither
            # hair nor skin by colour, and bulge out of the outline as an ear would.
            if hair_share(colours, skin, hair) > 0.5 or np.mean(skin.distance2(colours) < FAR) < EAR_SKIN:
                ear = None
        if ear is not None:
            conf = float(np.clip(0.4 + ear["bulge"] / ipd, 0.4, 0.7))
            for fp, key in zip(ids, ("top", "upper_join", "lobe", "lower_join")):
                front.put(fp, ear[key], conf, "silhouette")
            front.extras["ears"][side] = (float(ear["top"][1]), float(ear["lobe"][1]), "silhouette")
            continue
        # Hidden by hair or flat to the head: from the height of the brows to the nose's base,
        # on the head's outline (the face mesh's edge at those heights, a little outside it).
        top = 0.5 * (pts["4.3" if side == "L" else "4.4"][1] + y_eye)
        bottom = pts["9.15"][1]
        left_x, right_x = row_extents(mask)
        extent = right_x if sign > 0 else left_x
        for fp, y in zip(ids, (top, top + 0.1 * ipd, bottom, bottom - 0.1 * ipd)):
            r = int(np.clip(round(y), 0, mask.shape[0] - 1))
            x = extent[r] if np.isfinite(extent[r]) else centre_x + sign * 1.1 * ipd
            inset = 0.0 if fp in ("10.1", "10.2", "10.5", "10.6") else 0.08 * ipd
            front.put(fp, (x - sign * inset, y), 0.2, "rule")
        front.extras["ears"][side] = (float(top), float(bottom), "rule")


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.r_[0, flags.astype(int), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def detect_front(image: np.ndarray, where: str = "front photo", mask: np.ndarray | None = None) -> ViewPoints:
    """Feature points on a front photo (see the module docstring).

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo of the face looking at the camera.
    where : str
        The photo's name, for messages.
    mask : (H, W) bool, optional
        The head's silhouette, :func:`recon.landmarks.silhouette.head_mask` of the photo
        when omitted.

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
    front.mask = head_mask(image) if mask is None else np.asarray(mask, bool)
    if not front.mask.any():
        raise InputError("no head found in the front photo (the person could not be told from the background)",
                         where=where, fix="photograph the person against a plain, contrasting background")
    base, up = _midline(lm)
    front.extras["midline"] = (base, up)
    # Top of the hair: where the midline leaves the silhouette.
    top = _leave(front.mask, base, up)
    front.put("11.5", top, 0.8, "silhouette")
    # Hairline: skin colour up the forehead's midline and above the eyebrows' outer ends.
    lab = to_lab(image)
    skin, hair_model = skin_and_hair(lab, front.mask, lm, top, up, ipd)
    # From between the eyebrows up the midline (a fringe may hide the forehead's middle).
    hair, strength = hairline_along(lab, front.mask, lm[9, :2], up, 0.08 * ipd, skin, hair_model, 0.08 * ipd)
    if hair is not None:
        front.put("11.1", hair, 0.45 + 0.4 * strength, "silhouette")
    else:  # no hair on the forehead: as high above the brows as the nose base is below them
        glabella = 0.5 * (pts["4.1"] + pts["4.2"])
        front.put("11.1", glabella + (glabella - pts["9.15"]), 0.25, "rule")
    across = np.array([-up[1], up[0]])
    for fp, brow in (("11.3", "4.5"), ("11.2", "4.6")):
        # From just above the eyebrow's top (4.3/4.4, higher than its outer end 4.5/4.6).
        above = pts[brow] + ((pts[{"4.5": "4.3", "4.6": "4.4"}[brow]] - pts[brow]) @ up + 0.12 * ipd) * up
        band = above + np.linspace(-0.05, 0.05, 9)[:, None] * ipd * across
        colours = lab_at(lab, band)
        fringe = hair_share(colours, skin, hair_model) > 0.6 and (
            hair_model is None or np.median(hair_model.distance2(colours)) < 0.5 * FAR)
        if fringe:  # hair down to the brows
            front.put(fp, above, 0.35, "silhouette")
            continue
        found, strength = hairline_along(lab, front.mask, above, up, 0.05 * ipd, skin, hair_model, 0.08 * ipd)
        if found is not None:
            front.put(fp, found, 0.4 + 0.4 * strength, "silhouette")
        else:
            front.put(fp, pts[brow] + (front.points["11.1"] - glabella_of(pts)) @ up * up, 0.2, "rule")
    # Top of the skull: under the hair, whose thickness a photo does not show.
    front.put("11.4", top, 0.35, "rule")
    front.extras["colours"] = (skin, hair_model)
    # Where the crown is hair the outline there is the hair's (recon.shape.hair).
    front.extras["under_hair"] = ["11.4"] if hair_model is not None else []
    _ears(front, lab, lm, pts, skin, hair_model)
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
