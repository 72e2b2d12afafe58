"""Feature points on a side (profile) photo, with the front photo's help.

The head's silhouette (:func:`recon.landmarks.silhouette.head_mask`) is read as two
curves, the face's profile and the back of the head. The photo is turned, if need be, so
that the nose points to the image's left (the face's nose is the sharpest bump either
curve has). Then:

- the front photo's face mesh is laid onto the profile (:func:`recon.landmarks.profile.fit_profile`):
  its midline landmarks drawn onto the silhouette's outline by a similarity. The fit
  carries the landmarks' depth and height (the height the front photo gives) into the side
  photo, and with them every feature point, by the side table
  (:mod:`recon.landmarks.mapping`, ``recon/data/facemesh_side.csv``), for either side;
- where the lips the photo shows lie further from the fit's mouth than the two photos'
  heights may disagree, the outline was ambiguous (glasses before the eyes read as a
  second nose): the fit is made again with the mouth's corner held at the lips' height,
  and kept when the lips are found there again; lips that cannot hold it, and an eye's
  white that far off, are not taken. A face whose profile runs off the photo's edge is
  refused;
- the face mesh's depth is its weakest part, off by a few millimetres for a whole eye, a
  mouth or an ear at a time: where the photo shows them (:mod:`recon.landmarks.side_parts`:
  the white of the eye, the lips, the ear's outline), their points move onto them, and the
  points around them by the share of their depth behind the profile;
- the points on the profile (``P`` in the catalogue) go onto the silhouette's outline,
  the nearest place of it; the hairline is where the forehead, just inside the outline,
  turns from skin to hair; the top of the head is the silhouette's top, the back of the
  skull on the back curve as far down as the generic head has it.
"""

from __future__ import annotations

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError

from .front import ViewPoints
from .mapping import SIDE_MAP_FILE, apply_mapping, load_mapping
from .profile import ProfileFit, fit_profile, outline_distance
from .silhouette import bumpiness, head_mask, on_left_edge, row_extents

__all__ = ["ProfileCutOff", "facing_of", "detect_side", "register_profile"]


class ProfileCutOff(InputError):
    """The side photo's edge cuts the face's profile off: there is no profile to read
    (``recon build`` then builds from the front photo alone, with a warning)."""


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
    lb = bumpiness(left[head], scale)
    rb = bumpiness(-right[head], scale)
    return "left" if lb >= rb else "right"


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


def _checked(image: np.ndarray, where: str, mask: np.ndarray | None = None) -> np.ndarray:
    """The side photo's head silhouette, once the photo is seen to be a profile with a head."""
    from .roles import FRONTAL, turn

    h, w = image.shape[:2]
    a = turn(image)
    if a is not None and abs(a) < FRONTAL:
        raise InputError("the side photo shows the face from the front", where=where,
                         fix="give a profile photo (the head turned 90 degrees, one ear towards the camera); "
                             "if the two photos were given the other way round, swap them")
    mask = head_mask(image) if mask is None else np.asarray(mask, bool)
    if mask.sum() < 0.01 * h * w:
        raise InputError("no head found in the side photo (the person could not be told from the background)",
                         where=where, fix="photograph the profile against a plain, contrasting background")
    return mask


def register_profile(image: np.ndarray, front: ViewPoints, front_height: int,
                     where: str = "side photo", mask: np.ndarray | None = None,
                     facing: str | None = None) -> tuple[ProfileFit, dict]:
    """The front photo's face mesh laid onto a side photo's profile.

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
    mask : (H, W) bool, optional
        The head's silhouette in the photo as given (:func:`head_mask` when omitted).
    facing : {"left", "right"}, optional
        Where the nose points, when the user knows; found by
        :func:`recon.landmarks.facing.profile_facing` otherwise, and refused when unsure.

    Returns
    -------
    fit : ProfileFit
        Face mesh (depth, height) → pixels of the photo turned nose-left.
    context : dict
        ``image`` and ``mask`` turned nose-left, ``flipped`` (bool), ``distance`` (the
        outline's distance map), ``facing`` (:class:`~recon.landmarks.facing.Facing`).
    """
    from .facing import SURE, UnsureFacing, profile_facing

    mask = _checked(image, where, mask)

    def fitted(m: np.ndarray, dist: np.ndarray | None = None) -> ProfileFit:
        try:
            return _fit_midline(m, front, front_height, outline_distance(m) if dist is None else dist)
        except ValueError:
            raise InputError("the side photo's silhouette has no profile", where=where,
                             fix="give a profile photo showing the whole head, from the top of the hair to the "
                                 "chin") from None

    costs = None
    if facing is None:
        both = [fitted(m) for m in (mask, mask[:, ::-1])]
        costs = tuple(f.cost / max(f.scale * front.ipd_px, 1e-9) for f in both)
    colours = front.extras.get("colours")
    found = profile_facing(image, mask, costs, skin=colours[0] if colours else None, given=facing)
    if found.confidence < SURE:
        raise UnsureFacing(found, where=where)
    flip = found.facing == "right"
    if flip:
        # Everything below works on the photo turned nose-left; segmenting it again there
        # (rather than mirroring this mask) makes a mirrored photo give exactly mirrored points.
        image = np.ascontiguousarray(image[:, ::-1])
        mask = head_mask(image)
    dist = outline_distance(mask)
    fit = fitted(mask, dist)
    return fit, {"image": image, "mask": mask, "flipped": flip, "distance": dist, "facing": found}


#: An ear is taken as found when the gradient along its outline is this many times the
#: window's median.
EAR_CONTRAST = 1.5
#: A part found in the side photo whose height is further than this, as a share of the
#: IPD, from where the fitted face mesh puts it disagrees with the fit: the lips then hold
#: the fit, the eye's white is not taken. The calibration's default tolerance between the
#: two photos' heights (8 mm of 63).
PART_HEIGHT_TOL = 8.0 / 63.0
#: The least area of a red patch, in IPD², that may hold the fit as the lips: a quarter of
#: the lips' side view (about 0.24 IPD high, 0.3 IPD from the front to the corner, half of
#: that box red). A smaller patch may be the lower lip alone or a red spot on the cheek.
LIPS_AREA = 0.25 * 0.5 * 0.24 * 0.3
#: Points on the profile (the catalogue's ``P`` in the side view) that the face mesh's
#: table puts near it.
_ON_PROFILE = ("9.12", "9.3", "9.15", "8.1", "8.2", "2.10", "2.1", "11.1")
#: Points off the profile that move with the eye, and with the mouth, when either is seen
#: (the left side's ids).
_EYE = ("3.1", "3.3", "3.5", "3.7", "3.9", "4.5")
_AROUND_EYE = ("3.13", "4.3", "5.3")
_MOUTH = ("8.3", "8.5", "8.7", "2.4")
_JAW = ("2.13",)


def _back_share() -> float:
    """How far down the back of the skull (11.6) is on the generic head, as a share of the
    height from the top of the head (11.4) to under the nose (9.15)."""
    from .layout import generic_layout

    side = generic_layout()["side"]
    return float((side["11.6"][1] - side["11.4"][1]) / (side["9.15"][1] - side["11.4"][1]))


def _own(fp: str, side: str) -> str:
    """The id of a left-side point on the side a photo shows."""
    f = FEATURE_POINTS[fp]
    return f.mirror if side == "R" and f.side == "L" else fp


def _side_colours(lab: np.ndarray, mask: np.ndarray, cheek: np.ndarray, y_top: float, ipd: float):
    """Skin (the cheek) and hair (the crown) colour models of a side photo."""
    from .colour import FAR, ColourModel, sample_patches

    r = max(2, int(0.03 * ipd))
    skin = ColourModel.fit(sample_patches(lab, cheek, r, mask))
    row = int(min(mask.shape[0] - 1, y_top + 0.15 * ipd))
    cols = np.flatnonzero(mask[row])
    if len(cols) == 0:
        return skin, None
    crown = [(cols.mean() + dx * ipd, y_top + dy * ipd) for dx in (-0.3, 0.0, 0.3) for dy in (0.1, 0.2)]
    lab_c = sample_patches(lab, np.array(crown), r, mask)
    if len(lab_c) < 10 or np.median(skin.distance2(lab_c)) < 0.4 * FAR:
        return skin, None
    return skin, ColourModel.fit(lab_c)


def _is_hair(lab: np.ndarray, mask: np.ndarray, at, ipd: float, skin, hair) -> bool:
    """Whether the head is mostly hair-coloured in a patch at ``at`` (pixels)."""
    from .colour import hair_share, sample_patches

    colours = sample_patches(lab, np.array([at], float), max(2, int(0.03 * ipd)), mask)
    return len(colours) >= 5 and hair_share(colours, skin, hair) > 0.5


def _generic_ear(where: dict[str, np.ndarray], ipd: float) -> dict[str, np.ndarray]:
    """The generic head's ear outline (:data:`~recon.landmarks.side_parts.EAR_OUTLINE`)
    as a side photo nose-left shows it, ``ipd`` pixels between the pupils, centred where
    ``where``'s points are."""
    from .layout import generic_layout

    layout = generic_layout()
    g_ipd = float(np.linalg.norm(layout["front"]["3.5"] - layout["front"]["3.6"]))
    ids = list(where)
    g = np.array([layout["side"][i] for i in ids]) * (ipd / g_ipd)
    g += np.mean([where[i] for i in ids], axis=0) - g.mean(axis=0)
    return dict(zip(ids, g))


def _shift(points: dict, ids, anchor_pred: np.ndarray, anchor_found: np.ndarray) -> None:
    """Move ``ids`` in depth by what the anchor moved."""
    dx = anchor_found[0] - anchor_pred[0]
    for fp in ids:
        if fp in points:
            points[fp] = points[fp] + [dx, 0.0]


def _stretch(points: dict, ids, prof: np.ndarray, anchor_pred: np.ndarray, anchor_found: np.ndarray) -> float:
    """Stretch the depth behind the profile of ``ids`` so that the anchor lands where it was
    found; returns the factor (1 when it cannot be told)."""
    r = int(np.clip(round(anchor_pred[1]), 0, len(prof) - 1))
    ref = prof[r]
    if not np.isfinite(ref) or abs(anchor_pred[0] - ref) < 1.0:
        return 1.0
    k = float(np.clip((anchor_found[0] - ref) / (anchor_pred[0] - ref), 0.5, 2.0))
    for fp in ids:
        if fp in points:
            p = points[fp]
            points[fp] = np.array([ref + k * (p[0] - ref), p[1]])
    return k


def _fit_midline(mask: np.ndarray, front: ViewPoints, front_height: int, distance: np.ndarray,
                 anchors=()) -> ProfileFit:
    """:func:`recon.landmarks.profile.fit_profile` of the front photo's face mesh onto a
    nose-left side ``mask`` (with its outline ``distance``), at the photos' height ratio."""
    return fit_profile(mask, front.extras["landmarks"], front.points["11.5"][1], front.ipd_px,
                       mask.shape[0] / front_height, distance, anchors=anchors)


def _placed(fit: ProfileFit, depth_height: dict) -> dict:
    """Every feature point where ``fit`` carries its face mesh (depth, height)."""
    return {fp: fit.apply(zy[None])[0] for fp, zy in depth_height.items()}


def _seen_parts(lab: np.ndarray, mask: np.ndarray, pts: dict, own: dict, ipd: float):
    """The eye's white and the lips (:mod:`recon.landmarks.side_parts`) looked for where
    the points ``pts`` put them; each None when not seen."""
    from .side_parts import eye_white, lip_region

    eye = eye_white(lab, mask, 0.5 * (pts[own["3.5"]] + pts[own["3.7"]]), ipd)
    return eye, lip_region(lab, mask, pts[own["8.3"]], ipd)


def _held_by_lips(lips: dict, ipd: float, lab: np.ndarray, ctx: dict, front: ViewPoints, front_height: int,
                  depth_height: dict, own: dict):
    """The profile fitted again with the mouth's corner held at the lips' height, when the
    first fit put it further from them than the photos' heights may disagree: the outline
    alone was ambiguous (glasses before the eyes make a second nose, and the fit slides a
    feature up). Returns ``(fit, points, eye, lips)`` with the parts looked for again
    where the new fit puts them, or None: the patch is too small to be the lips
    (:data:`LIPS_AREA`), or is not found again where it held the fit (a red patch that is
    not the lips drags the fit where no lips are). Not the eye: behind glasses its white is
    confused with the lenses' glare."""
    mask = ctx["mask"]
    if lips["area"] < LIPS_AREA * ipd ** 2:
        return None
    fit = _fit_midline(mask, front, front_height, ctx["distance"],
                       anchors=[(depth_height[own["8.3"]], lips["corner"][1])])
    pts = _placed(fit, depth_height)
    eye, found = _seen_parts(lab, mask, pts, own, fit.scale * front.ipd_px)
    if found is None or abs(found["corner"][1] - lips["corner"][1]) > PART_HEIGHT_TOL * fit.scale * front.ipd_px:
        return None
    return fit, pts, eye, found


def _check_not_cut(prof: np.ndarray, y_top: float, pts: dict, scale: float, scale_guess: float,
                   front: ViewPoints, ipd: float, flip: bool, where: str) -> None:
    """Refuse a side photo whose edge cuts the face's profile off: the silhouette's front
    runs along the photo's edge in the head's rows (down to the chin, by the front photo's
    proportions at the larger of the fit's scale and the photos': a fit drawn to a cut
    profile can shrink onto the forehead), and the fitted profile reaches that edge (a
    background the silhouette took in, whose edge the face does not reach, is no cut)."""
    chin = y_top + max(scale, scale_guess) * (front.points["2.1"][1] - front.points["11.5"][1])
    face_rows = np.arange(int(y_top), int(np.clip(chin, y_top, len(prof) - 1)) + 1)
    cut = face_rows[on_left_edge(prof[face_rows])]
    if len(cut) > 0.1 * ipd and any(pts[fp][0] < 0.05 * ipd for fp in _ON_PROFILE if fp in pts):
        raise ProfileCutOff(f"the face runs off the photo's {'right' if flip else 'left'} edge (rows "
                         f"{cut[0]}-{cut[-1]}): the profile of the nose, lips or chin is cut off",
                         where=where, fix="give a profile photo with some background in front of the face")


def detect_side(image: np.ndarray, front: ViewPoints, front_height: int,
                where: str = "side photo", mask: np.ndarray | None = None,
                facing: str | None = None) -> tuple[ViewPoints, str]:
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
    mask : (H, W) bool, optional
        The head's silhouette in the photo as given (:func:`head_mask` when omitted).
    facing : {"left", "right"}, optional
        Where the nose points (see :func:`register_profile`); the one found is in the
        points' ``extras["facing_found"]``.

    Returns
    -------
    points : ViewPoints
        The points of the side the photo shows, each with a confidence and a source.
    side : {"L", "R"}
        The face's side the photo shows (``"L"`` when the nose points to the image's left).
    """
    from .layout import shown_in

    from .colour import hairline_on, to_lab
    from .side_parts import EAR_OUTLINE, ear_box

    h, w = image.shape[:2]
    fit, ctx = register_profile(image, front, front_height, where, mask, facing)
    image, mask, flip = ctx["image"], ctx["mask"], ctx["flipped"]
    side = "R" if flip else "L"
    out = ViewPoints(mask=mask)
    out.extras["facing_found"] = ctx["facing"]
    lm = front.extras["landmarks"]
    table = load_mapping(SIDE_MAP_FILE)
    depth_height = apply_mapping(lm[:, [2, 1]], table)
    prof, back = row_extents(mask)
    rows = np.flatnonzero(np.isfinite(prof))
    y_top = float(rows[0])
    lab = to_lab(image)
    own = {fp: _own(fp, side) for fp in _EYE + _AROUND_EYE + _MOUTH + _JAW + EAR_OUTLINE + ("5.1",)}
    pts = _placed(fit, depth_height)
    ipd = fit.scale * front.ipd_px
    eye, lips = _seen_parts(lab, mask, pts, own, ipd)
    if lips is not None and abs(lips["corner"][1] - pts[own["8.3"]][1]) > PART_HEIGHT_TOL * ipd:
        # Lips that cannot hold the fit are further from it than the heights may disagree:
        # not taken.
        fit, pts, eye, lips = (_held_by_lips(lips, ipd, lab, ctx, front, front_height, depth_height, own)
                               or (fit, pts, eye, None))
    ipd = fit.scale * front.ipd_px
    _check_not_cut(prof, y_top, pts, fit.scale, h / front_height, front, ipd, flip, where)
    if eye is not None and abs(eye["back"][1] - pts[own["3.7"]][1]) > PART_HEIGHT_TOL * ipd:
        # Further from the fitted face's eye than the photos' heights may disagree: not the
        # eye (a lens's glare, a shadow); its points stay where the fit puts them.
        eye = None
    out.ipd_px = ipd
    out.extras.update(profile_fit=fit, facing="right" if flip else "left")
    # How well the mesh lies on the profile: a fit off by a tenth of the IPD is worth little.
    quality = float(np.clip(1.0 - fit.cost / (0.1 * ipd), 0.2, 1.0)) * min(1.0, front.ipd_px / 60.0)
    conf = {fp: quality * (0.75 - 0.04 * table[fp].fit_error_pct) for fp in pts}
    # The eye and the mouth, seen: their points move with them, the depth behind the profile
    # stretched (the face mesh's depth is off by a share, more for what lies deeper).
    if eye is not None:
        # The eye's own points move with it; those around it (lid fold, brow, cheekbone) by
        # the share of their depth behind the profile.
        anchor = pts[own["3.7"]].copy()
        _stretch(pts, [own[i] for i in _AROUND_EYE], prof, anchor, eye["back"])
        _shift(pts, [own[i] for i in _EYE], anchor, eye["back"])
        pts[own["3.7"]] = eye["back"]
        for fp in _EYE + _AROUND_EYE:
            conf[own[fp]] = min(0.8, conf[own[fp]] + 0.15)
    if lips is not None:
        _stretch(pts, [own[i] for i in _MOUTH], prof, pts[own["8.3"]], lips["corner"])
        pts[own["8.3"]] = lips["corner"]
        for fp in _MOUTH:
            conf[own[fp]] = min(0.8, conf[own[fp]] + 0.15)
    # The ear: its outline slid onto the strongest edges near where the mesh puts it.
    skin, hair = _side_colours(lab, mask, np.array([pts[own["5.3"]], pts[own["5.1"]]]), y_top, ipd)
    # The ear's shape is the generic head's, at the person's scale, where the table puts it
    # (the table's own ear, an average, comes out smaller than any one ear).
    expected = _generic_ear({i: pts[own[i]] for i in EAR_OUTLINE}, ipd)
    ear = ear_box(lab, mask, expected, ipd, skin, hair)
    if ear is not None and ear["contrast"] <= EAR_CONTRAST:
        ear = None
    if ear is not None:
        before = np.mean([pts[own[i]] for i in EAR_OUTLINE], axis=0)
        after = np.mean([ear[i] for i in EAR_OUTLINE], axis=0)
        # The jaw's angle (the gonion, below and in front of the ear) is as far off in depth
        # as the ear was (benchmarks/landmark_accuracy.py, clean set: its side error 7.0 %
        # IPD median, 8.2 without this).
        _stretch(pts, [own[i] for i in _JAW], prof, before, after)
        for i in EAR_OUTLINE:
            pts[own[i]] = ear[i]
            conf[own[i]] = 0.5
    # The hairline on the profile: where the forehead, just inside the silhouette, turns
    # from skin to hair going up from above the eyebrows.
    brow = _own("4.3", side)
    if brow in pts:
        r0 = int(np.clip(round(pts[brow][1] - 0.1 * ipd), rows[0], rows[-1]))
        path = np.arange(r0, int(y_top), -1)
        path = path[np.isfinite(prof[path])]
        if len(path) > 10:
            centres = np.c_[prof[path] + 0.05 * ipd, path]
            k, strength = hairline_on(lab, centres, (1.0, 0.0), 0.03 * ipd, skin, hair, 0.08 * ipd)
            if k is not None:
                pts["11.1"] = np.array([prof[path[k]], float(path[k])])
                conf["11.1"] = 0.4 + 0.3 * strength
    # Nothing lies in front of the face's outline: a point off the profile that the face
    # mesh's depth (or the lips moved with it) puts ahead of it is in the backdrop, and is
    # taken back onto the outline at its height, its confidence halved (meds_s001's upper
    # lip, 8.5, stood 7 mm ahead of the lip's midpoint: a trench down the built philtrum).
    ahead = []
    for fp, p in pts.items():
        r = int(round(p[1]))
        if fp not in _ON_PROFILE and 0 <= r < len(prof) and np.isfinite(prof[r]) and p[0] < prof[r]:
            pts[fp] = np.array([prof[r], p[1]])
            conf[fp] *= 0.5
            ahead.append(fp)
    # Points on the profile: onto the silhouette's outline, the nearest place of it.
    outline = np.argwhere(ctx["distance"] < 0.75)[:, ::-1].astype(float)
    if len(outline):
        from scipy.spatial import cKDTree

        tree = cKDTree(outline)
        for fp in _ON_PROFILE:
            if fp in pts:
                d, j = tree.query(pts[fp])
                if d < 0.15 * ipd:
                    pts[fp] = outline[j]
    for fp in shown_in("side", side):
        if fp in pts:
            out.put(fp, pts[fp], conf[fp], "silhouette")
    # The top: the apex of a parabola through the silhouette's upper edge.
    top_x = _apex(mask, y_top, 0.12 * ipd)
    out.put("11.5", (top_x, y_top - 0.5), 0.75, "silhouette")
    out.put("11.4", (top_x, y_top - 0.5), 0.45, "rule")
    # The back of the skull: on the back of the silhouette, as far down from the top as
    # the generic head has it between the top and under the nose.
    r = int(np.clip(round(y_top + _back_share() * (out.points["9.15"][1] - y_top)), rows[0], rows[-1]))
    under_hair = ["11.4"] if hair is not None else []
    if np.isfinite(back[r]):
        out.put("11.6", (back[r], r), 0.6, "silhouette")
        if _is_hair(lab, mask, (back[r] - 0.06 * ipd, r), ipd, skin, hair):
            under_hair.append("11.6")
    # Where the outline is hair the skull lies under it (recon.shape.hair).
    out.extras.update(eye=eye, lips=lips, ear=ear, under_hair=under_hair, ahead_of_profile=ahead)
    # Back to the photo's own orientation.
    if flip:
        flipped = ViewPoints(mask=mask[:, ::-1], ipd_px=out.ipd_px, extras=out.extras)
        for fp, p in out.points.items():
            flipped.put(fp, (w - 1 - p[0], p[1]), out.confidence[fp], out.source[fp])
        out = flipped
    keep = set(shown_in("side", side))
    for fp in list(out.points):
        x, y = out.points[fp]
        if fp not in keep or not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
            del out.points[fp], out.confidence[fp], out.source[fp]
    return out, side


