"""Feature points on a side (profile) photo, with the front photo's help.

The head's silhouette (:func:`recon.landmarks.silhouette.head_mask`) is read as two
curves, the face's profile and the back of the head. The photo is turned, if need be, so
that the nose points to the image's left (the face's nose is the sharpest bump either
curve has). Then:

- heights: a point both photos show is at the same height in both, up to the photos'
  scales and framing; the top of the head and the tip of the nose, found in both,
  give that map (``y_side = s * y_front + t``) and every height the front photo has is
  carried across;
- on the profile (``P`` in the catalogue): the curve at the point's height, the nose tip,
  the point under the nose and the lips refined to the curve's own extremes, the back of
  the skull where the back curve reaches furthest, the top where the silhouette begins;
- off the profile (eye and mouth corners, nose wing, jaw angle, ear): the generic head's
  side layout, fitted to the points found on the profile (a similarity for the face, a
  stretch in depth and height for the ear and jaw), at the heights from the front.
"""

from __future__ import annotations

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError

from .front import ViewPoints
from .models import face_landmarks
from .silhouette import head_mask, row_extents

__all__ = ["facing_of", "detect_side"]

#: Points on the profile whose height the front photo gives and whose depth is the curve's.
_ON_PROFILE = ("11.1", "9.12", "9.15", "8.1", "2.2", "2.3", "8.2", "2.10", "2.1")
#: Anchors of the face's layout fit, and of the head's (ear, jaw, back).
_FACE_ANCHORS = ("9.12", "9.3", "9.15", "8.1", "8.2", "2.10", "2.1")
_HEAD_ANCHORS = ("11.4", "11.6", "9.3", "2.1")


def _bumpiness(curve: np.ndarray, scale: int) -> float:
    """Largest outward bump of a silhouette curve (x per row, outward = smaller x) at ``scale``
    rows: how far a row stands out of the chord between the rows ``scale`` above and below."""
    ok = np.isfinite(curve)
    y = np.flatnonzero(ok)
    if len(y) < 3 * scale:
        return 0.0
    c = np.interp(np.arange(y[0], y[-1] + 1), y, curve[ok])
    out = 0.5 * (c[:-2 * scale] + c[2 * scale:]) - c[scale:-scale]
    return float(out.max())


def facing_of(mask: np.ndarray) -> str:
    """``"left"`` or ``"right"``: where the nose points in a profile silhouette.

    The nose is a sharper bump than anything on the back of the head (which is a smooth
    arc) or on the neck, so the side whose curve has the larger bump is the face.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[:200, :200]
    >>> head = (xx - 110) ** 2 + (yy - 100) ** 2 < 60 ** 2
    >>> head |= (np.abs(yy - 110) < 8) & (xx > 40) & (xx < 120)  # a nose on the left
    >>> facing_of(head)
    'left'
    >>> facing_of(head[:, ::-1])
    'right'
    """
    left, right = row_extents(mask)
    rows = np.flatnonzero(np.isfinite(left))
    if len(rows) == 0:
        raise ValueError("empty silhouette")
    n = len(rows)
    scale = max(2, int(0.03 * n))
    # Between the crown (whose edge runs level, a "bump" at any scale) and the neck and
    # shoulders: the rows of the face.
    head = slice(rows[0] + int(0.15 * n), rows[0] + int(0.6 * n))
    lb = _bumpiness(left[head], scale)
    rb = _bumpiness(-right[head], scale)
    return "left" if lb >= rb else "right"


def _extreme(curve: np.ndarray, lo: float, hi: float, kind: str) -> int | None:
    """Row of the curve's min (``"out"``, most forward) or max (``"in"``) between rows."""
    a, b = int(max(0, np.floor(min(lo, hi)))), int(min(len(curve) - 1, np.ceil(max(lo, hi))))
    seg = curve[a:b + 1]
    if not np.isfinite(seg).any():
        return None
    k = np.nanargmin(seg) if kind == "out" else np.nanargmax(seg)
    return a + int(k)


def _profile_hairline(image: np.ndarray, prof: np.ndarray, start: int, stop: int, ipd: float):
    """First row above ``start`` (the nose bridge) where the pixels just inside the profile
    are no longer the colour of the skin below; None when they stay skin to ``stop``."""
    from .front import _not_skin, skin_model

    inset = 0.06 * ipd
    rows = np.arange(start - int(0.5 * ipd), stop, -1)
    rows = rows[np.isfinite(prof[rows])]
    if len(rows) < 10:
        return None
    # Skin: the forehead between the bridge and a little above the brows.
    seed = rows[: max(3, int(0.3 * ipd))]
    skin = skin_model(image, np.c_[prof[seed] + inset, seed], max(1, int(0.02 * ipd)))
    need = max(3, int(0.04 * ipd))
    run = 0
    for r in rows:
        band = np.c_[prof[r] + inset * np.array([0.6, 1.0, 1.4, 1.8]), np.full(4, r)]
        if np.mean(_not_skin(image, band, *skin)) >= 0.75:
            run += 1
            if run >= need:
                r0 = r + need - 1
                return np.array([prof[r0], float(r0)])
        else:
            run = 0
    return None


def _apex(mask: np.ndarray, y_top: float, depth: float) -> float:
    """Column of the top of a silhouette: the vertex of a parabola fitted to its upper edge
    over the top ``depth`` rows (a flat crown has no single highest pixel)."""
    cols = np.flatnonzero(mask.any(axis=0))
    first = np.argmax(mask[:, cols], axis=0).astype(float)
    near = first <= y_top + max(depth, 2.0)
    x, y = cols[near].astype(float), first[near]
    if len(x) < 5:
        return float(np.mean(x)) if len(x) else float(np.mean(cols))
    a, b, _ = np.polyfit(x, y, 2)
    if a <= 0:
        return float(np.mean(x))
    return float(np.clip(-b / (2 * a), x.min(), x.max()))


def _axis_fit(src: np.ndarray, dst: np.ndarray):
    """x' = a x + c, y' = b y + d by least squares (a stretch in depth and in height)."""
    ax = np.polyfit(src[:, 0], dst[:, 0], 1)
    ay = np.polyfit(src[:, 1], dst[:, 1], 1)
    return lambda p: np.c_[np.polyval(ax, p[:, 0]), np.polyval(ay, p[:, 1])]


def detect_side(image: np.ndarray, front: ViewPoints, front_height: int, where: str = "side photo",
                layout: dict | None = None) -> tuple[ViewPoints, str]:
    """Feature points on a profile photo (see the module docstring).

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB profile photo, facing either way.
    front : ViewPoints
        :func:`recon.landmarks.front.detect_front` of the same person's front photo.
    front_height : int
        The front photo's height in pixels.
    where : str
        The photo's name, for messages.
    layout : dict, optional
        :func:`recon.annotate.placement.generic_layout` (the generic head's by default).

    Returns
    -------
    points : ViewPoints
        The points of the side the photo shows, each with a confidence and a source.
    side : {"L", "R"}
        The face's side the photo shows (``"L"`` when the nose points to the image's left).
    """
    from recon.annotate.placement import fit_view, generic_layout, shown_in

    h, w = image.shape[:2]
    faces = face_landmarks(image)
    if faces:
        lm = faces[0]
        nose, left_edge, right_edge = lm[1, 0], lm[234, 0], lm[454, 0]
        a = ((right_edge - nose) - (nose - left_edge)) / max(right_edge - left_edge, 1e-9)
        if abs(a) < 0.3:
            raise InputError("the side photo shows the face from the front", where=where,
                             fix="give a profile photo (the head turned 90 degrees, one ear towards the camera); "
                                 "if the two photos were given the other way round, swap them")
    mask = head_mask(image)
    if mask.sum() < 0.01 * h * w:
        raise InputError("no head found in the side photo (the person could not be told from the background)",
                         where=where, fix="photograph the profile against a plain, contrasting background")
    facing = facing_of(mask)
    flip = facing == "right"
    if flip:
        # Everything below works on the photo turned nose-left; segmenting it again there
        # (rather than mirroring this mask) makes a mirrored photo give exactly mirrored points.
        image = np.ascontiguousarray(image[:, ::-1])
        mask = head_mask(image)
    side = "R" if flip else "L"
    out = ViewPoints(mask=mask)
    prof, back = row_extents(mask)
    rows = np.flatnonzero(np.isfinite(prof))
    y_top = float(rows[0])

    def fy(fp):  # the front's height of the point the side photo shows (its own side)
        f = FEATURE_POINTS[fp]
        key = f.mirror if (flip and f.side != "C") else fp
        return front.points[key][1] if key in front.points else None

    # Heights: the top of the head and the point under the nose, in both photos. The nose
    # tip (the curve's most forward point) leads to the latter: the deepest point of the
    # curve just below it.
    ipd_f = front.ipd_px
    s0 = h / front_height
    top_f = front.points["11.5"][1]
    guess = y_top + s0 * (fy("9.3") - top_f)
    k = _extreme(prof, guess - 0.6 * s0 * ipd_f, guess + 0.6 * s0 * ipd_f, "out")
    if k is None:
        raise InputError("the side photo's silhouette has no profile where the nose should be", where=where,
                         fix="give a profile photo showing the whole head, from the top of the hair to the chin")
    k2 = _extreme(prof, k + 1, k + 0.3 * s0 * ipd_f, "in")
    s = s0 if k2 is None else (k2 - y_top) / max(fy("9.15") - top_f, 1e-9)
    if not 0.5 * s0 < s < 2.0 * s0:  # what was found is not the nose: keep the photos' own scales
        s, k2 = s0, None
    t = y_top - s * top_f

    def to_side(y):
        return s * y + t

    ipd = s * ipd_f
    out.ipd_px = ipd
    out.extras.update(scale=s, offset=t, facing=facing)
    # The top: the apex of a parabola through the silhouette's upper edge.
    top_x = _apex(mask, y_top, 0.12 * ipd)
    out.put("11.5", (top_x, y_top - 0.5), 0.75, "silhouette")
    out.put("11.4", (top_x, y_top - 0.5), 0.45, "rule")
    # The profile at the front's heights.
    for fp in ("9.3",) + _ON_PROFILE:
        y = fy(fp)
        if y is None:
            continue
        r = int(np.clip(round(to_side(y)), rows[0], rows[-1]))
        if np.isfinite(prof[r]):
            out.put(fp, (prof[r], r), 0.6 * front.confidence.get(fp, 0.5) + 0.3, "silhouette")
    if k2 is not None:
        out.put("9.15", (prof[k2], k2), 0.75, "silhouette")
    # The chin's lowest point: where the chin turns under, the silhouette's furthest point
    # down and forward near the front's height (the curve is level there, so a height alone
    # does not fix it).
    if fy("2.1") is not None and "2.10" in out.points:
        y1 = to_side(fy("2.1"))
        x0 = out.points["2.10"][0]
        win = mask[int(max(0, y1 - 0.25 * ipd)):int(min(h, y1 + 0.25 * ipd)), int(max(0, x0 - 0.1 * ipd)):int(min(w, x0 + 0.6 * ipd))]
        yy, xx = np.nonzero(win)
        if len(yy):
            j = np.argmax(yy - xx)
            out.put("2.1", (xx[j] + int(max(0, x0 - 0.1 * ipd)), yy[j] + int(max(0, y1 - 0.25 * ipd))), 0.6, "silhouette")
    # The hairline on the profile: where the forehead stops being skin-coloured going up,
    # just inside the silhouette (the side photo's own skin, sampled on the forehead).
    if "9.12" in out.points:
        found = _profile_hairline(image, prof, int(out.points["9.12"][1]),
                                  int(y_top), ipd)
        if found is not None:
            out.put("11.1", found, 0.65, "silhouette")
    # Back of the skull: where the back curve is furthest back, above the base of the nose.
    y_base = out.points.get("9.15", out.points["9.3"])[1]
    kb = _extreme(-back, y_top, y_base, "out")
    if kb is not None:
        out.put("11.6", (back[kb], kb), 0.7, "silhouette")
    # Off the profile: the generic head's layout fitted to what was found.
    layout = generic_layout() if layout is None else layout
    lay = {i: np.asarray(p, float) for i, p in layout["side"].items()}
    want = [i for i in shown_in("side", "L") if i not in out.points]
    face_fit = fit_view(lay, {i: out.points[i] for i in _FACE_ANCHORS if i in out.points}, (w, h))
    anchors = [i for i in _HEAD_ANCHORS if i in out.points]
    head_fit = _axis_fit(np.array([lay[i] for i in anchors]), np.array([out.points[i] for i in anchors]))
    for fp in want:
        if fp not in lay:
            continue
        far = FEATURE_POINTS[fp].group == 10 or fp in ("2.13",)
        p = (head_fit if far else face_fit)(lay[fp][None])[0]
        y = fy(fp)
        if y is not None and front.source.get(fp if not flip else FEATURE_POINTS[fp].mirror or fp) != "rule":
            p[1] = to_side(y)
            conf = 0.35 if far else 0.45
        else:
            conf = 0.25
        out.put(fp, p, conf, "rule")
    # Back to the photo's own orientation and the ids of the side it shows.
    if flip:
        flipped = ViewPoints(mask=mask[:, ::-1], ipd_px=out.ipd_px, extras=out.extras)
        for fp, p in out.points.items():
            f = FEATURE_POINTS[fp]
            key = f.mirror if f.side != "C" else fp
            flipped.put(key, (w - 1 - p[0], p[1]), out.confidence[fp], out.source[fp])
        out = flipped
    keep = set(shown_in("side", side))
    for fp in list(out.points):
        x, y = out.points[fp]
        if fp not in keep or not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
            del out.points[fp], out.confidence[fp], out.source[fp]
    return out, side
