"""From feature points marked on a front and a side photo to 3D feature points.

The front photo gives x and y, the side photo z and y. The two views are brought to a
common height scale by the points marked in both (their heights must agree: a straight
line maps side-photo rows to front-photo heights), a small head roll in the front photo is
removed using the pupils, a turn of the head in the front photo (booking photos and
selfies are often turned 5-20 degrees) is taken out using the side photo's depths
(:mod:`recon.shape.turn`), and the absolute size comes from the user's interpupillary
distance (photos carry none). The side photo may face either way; which side of the face
it shows is read from its labels and mirrored to the other side. Points one view cannot
show take their missing coordinate from the generic head carried by the same free-form
deformation that shapes the head, driven by the points known in 3D; points neither view
shows (tongue, teeth, 7.1) come wholly from it.

Cameras are orthographic by default. With a focal length (pixels, both photos) each view
is a pinhole camera on its axis through the image centre, and the points are found by a
few rounds of alternating between the views (each view's depths come from the other).

Coordinates out: metres, the generic head's MPEG-4 neutral frame (+x the face's left,
+y up, +z towards the viewer), the midline at x = 0.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS, check_fp_id
from mpeg4.errors import InputError
from mpeg4.head import Head

from .core_points import CORE_GROUPS, is_core
from .deform import bounding_controls, dffd, fit_similarity
from .hair import skull_normals, skull_under
from .turn import front_turn, generic_depths

__all__ = ["DEFAULT_IPD_MM", "CORE_GROUPS", "is_core", "Calibration", "HeightsDisagree", "calibrate"]

#: Adult mean interpupillary distance (mm) used when the user gives none.
DEFAULT_IPD_MM = 63.0

#: Largest nod of the head between the two photos the orthographic calibration takes out,
#: degrees (people nod a few degrees between a front and a profile photo).
MAX_NOD_DEG = 20.0

# Rounds of the alternating perspective solution (converges to ~1e-9 m in 5).
_PERSPECTIVE_ROUNDS = 8


@dataclass
class Calibration:
    """3D feature points and how they were obtained.

    Attributes
    ----------
    points : dict of str to (3,) float64
        FP id → position, metres, for all 84 points.
    source : dict of str to str
        FP id → ``"front+side"``, ``"front"``, ``"side"`` (with the missing coordinate from
        the generic head), ``"mirror"`` (its partner's side-view depth) or ``"generic"``.
    roll_deg : float
        Head roll removed from the front photo (positive: the face's left eye was higher).
    yaw_deg : float
        Head turn removed from the front photo (positive: the face turned towards its own
        left, the image's right), see :func:`recon.shape.turn.front_turn`.
    metres_per_px : dict
        ``front`` and ``side`` scales (orthographic; at the pupils' depth in perspective).
    side_facing : {"left", "right"}
        Which way the nose points in the side photo.
    visible_side : {"L", "R"}
        Which side of the face the side photo shows (by its labels).
    height_residual_mm : dict of str to float
        For points marked in both views, side-photo height minus front-photo height.
    dropped : dict of str to dict
        Points left out because their heights disagreed (``drop_outliers``): FP id →
        ``{"view": "front" | "side" | "both", "disagreement_mm": float}``, in the order
        they were dropped.
    assumptions : dict
        What the numbers rest on (IPD, camera model), for the output's provenance.
    """

    points: dict[str, np.ndarray]
    source: dict[str, str]
    roll_deg: float
    metres_per_px: dict[str, float]
    side_facing: str
    visible_side: str
    height_residual_mm: dict[str, float]
    assumptions: dict = field(default_factory=dict)
    dropped: dict[str, dict] = field(default_factory=dict)
    yaw_deg: float = 0.0


class HeightsDisagree(InputError):
    """The heights of points marked in both photos disagree beyond the tolerance.

    ``residual_mm`` holds each shared point's disagreement (side minus front, mm).
    """

    def __init__(self, residual_mm: dict[str, float], *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.residual_mm = residual_mm


def _as_points(view: Mapping, name: str) -> dict[str, np.ndarray]:
    out = {}
    for fp_id, xy in view.items():
        check_fp_id(fp_id, where=f"{name} view")
        p = np.asarray(xy, dtype=np.float64).reshape(-1)
        if p.shape != (2,) or not np.isfinite(p).all():
            raise InputError(f"feature point {fp_id} is {xy!r}, expected two finite pixel numbers",
                             where=f"{name} view", fix="give [x, y] in pixels")
        out[fp_id] = p
    return out


def _check_inside(points: dict[str, np.ndarray], size, name: str) -> None:
    if size is None:
        return
    w, h = size
    for fp_id, (x, y) in points.items():
        if not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
            raise InputError(f"feature point {fp_id} at ({x:.1f}, {y:.1f}) lies outside the {w}x{h} image",
                             where=f"{name} view", fix="drag it onto the photo or remove it")


def _side_depths(side: dict[str, np.ndarray]) -> float:
    """+1 if the nose points to the image's right in the side photo, else -1."""
    if "9.3" not in side:
        raise InputError("the tip of the nose (9.3) is not marked", where="side view",
                         fix="mark 9.3; the side photo's facing direction is read from it")
    back = [i for i in ("11.6", "10.3", "10.4", "10.1", "10.2", "10.5", "10.6", "7.1") if i in side]
    ref = side[back[0]][0] if back else np.median([p[0] for p in side.values()])
    if side["9.3"][0] == ref:
        raise InputError("cannot tell which way the side photo faces", where="side view",
                         fix="mark the tip of the nose (9.3) and an ear point (10.x) or the back of the skull (11.6)")
    return 1.0 if side["9.3"][0] > ref else -1.0


def calibrate(front: Mapping[str, np.ndarray], side: Mapping[str, np.ndarray], generic: Head,
              ipd_mm: float = DEFAULT_IPD_MM, focal_px: float | None = None,
              front_size: tuple[int, int] | None = None, side_size: tuple[int, int] | None = None,
              height_tol_mm: float = 8.0, confidence: Mapping[str, Mapping[str, float]] | None = None,
              drop_outliers: bool = False, under_hair: Collection[str] = ()) -> Calibration:
    """3D feature points from 2D points marked on a front and a side photo.

    With ``drop_outliers`` (points found automatically, not reviewed), a point whose
    heights disagree beyond ``height_tol_mm`` is left out of the view it is less sure of
    and the rest fitted again, the worst first, until all agree; the dropped points are
    listed in :attr:`Calibration.dropped` and take their missing coordinates as unmarked
    points do. Only a disagreement of the face's core (:data:`CORE_GROUPS`) stays an error:
    there the photos, not a point, are wrong. A core point past the tolerance is judged
    again with the heights fitted to the core alone (stray points elsewhere pull the fit of
    every height): if the core agrees with itself, the worst point off it is dropped, or,
    with none past the tolerance, the core's fit is kept. Without it (marked points) any disagreement
    is an error naming the worst points.

    Parameters
    ----------
    front, side : mapping of str to (2,) array
        FP id → pixel (x right, y down) in each photo. The front view needs both pupils
        (3.5, 3.6); the side view needs the tip of the nose (9.3) and at least three
        points also marked in the front view (either side's id: heights are mirrored).
    generic : Head
        The generic head, for coordinates the photos cannot give.
    ipd_mm : float
        The person's interpupillary distance, which sets the absolute size.
    focal_px : float, optional
        Focal length in pixels of both photos; orthographic cameras when None.
    front_size, side_size : (width, height), optional
        Image sizes: points outside are errors; needed for the principal point with
        ``focal_px`` (the image centre).
    height_tol_mm : float
        Largest accepted disagreement between a point's height in the two views (``inf``:
        no check; recorded as None in the assumptions).
    confidence : dict, optional
        ``{"front": {id: c}, "side": {id: c}}`` with c in [0, 1]: weights of the height fit,
        and which view loses a disagreeing point (the less sure one; both when equal).
    drop_outliers : bool
        Drop disagreeing points instead of failing (see above); the unreviewed skull and
        ear points are then also brought within :data:`PRIOR_SLACK` of where the face's
        points put them (``"skull prior"`` in :attr:`Calibration.source`).
    under_hair : collection of str
        With ``drop_outliers``: the skull points (:data:`recon.shape.hair.UNDER_HAIR`)
        whose outline in either photo is hair, not skin; the skull is placed under it
        (:func:`recon.shape.hair.skull_offset`, ``"under hair"`` in the source).

    Returns
    -------
    Calibration
    """
    front = dict(front)
    side = dict(side)
    confidence = {v: dict((confidence or {}).get(v) or {}) for v in ("front", "side")}
    dropped: dict[str, dict] = {}
    while True:
        try:
            cal = _calibrate(front, side, generic, ipd_mm, focal_px, front_size, side_size, height_tol_mm, confidence)
        except HeightsDisagree as e:
            if not drop_outliers:
                raise
            res = e.residual_mm
            worst = max(res, key=lambda i: abs(res[i]))
            if is_core(worst):
                # Points off the core (an ear on the hair) pull the fit of every height and
                # can push a core point past the tolerance: the core is blamed only when it
                # disagrees with itself, the heights fitted to it alone.
                try:
                    cal = _calibrate(front, side, generic, ipd_mm, focal_px, front_size, side_size, height_tol_mm,
                                     confidence, core_fit=True)
                except HeightsDisagree as against_core:
                    e, res = against_core, against_core.residual_mm
                    worst = max(res, key=lambda i: abs(res[i]))
                except InputError:
                    pass  # too few core points to fit alone: the core point stays blamed
                else:
                    worst = None
            if worst is not None:
                if is_core(worst):
                    raise HeightsDisagree(e.residual_mm, e.what + f" (after dropping {', '.join(dropped) or 'nothing'})",
                                          where=e.where, fix="the face's core points (eyes, nose, mouth, chin) cannot "
                                                             "disagree by this much on the same face: check that the "
                                                             "two photos show the same person in the same pose, and "
                                                             "their points (recon annotate)") from None
                dropped[worst] = {"view": _drop(worst, front, side, confidence),
                                  "disagreement_mm": round(float(res[worst]), 1)}
                continue
        cal.dropped = dropped
        if drop_outliers:
            _skull_prior(cal, generic, under_hair)
        return cal


#: How far unreviewed points of the skull's outline and the ears may lie from where the
#: face's points put the generic head's, metres: the spread of skull and ear shapes about
#: a face of a given size. Hair lies on the skull 5-50 mm thick, and a photo's outline of
#: the top and back of the head is the hair's, so a point further out is hair (or an ear
#: found on the hair or the cheek) and is brought back to this bound.
PRIOR_SLACK = {**{i: 0.012 for i in ("11.4", "11.5", "11.6")},
               **{i: 0.015 for i in FP_IDS if FEATURE_POINTS[i].group == 10}}

#: An ear's points, each side: they move together (:data:`PRIOR_SLACK` bounds the ear's
#: shift), and each keeps within :data:`EAR_SHAPE_SLACK` of where that shift puts the
#: generic ear's. An ear's shape varies less than where it sits on the head; points pulled
#: apart by a turned head or a guess on the hair would make a spike of the ear.
EARS = (("10.1", "10.3", "10.5", "10.7", "10.9"), ("10.2", "10.4", "10.6", "10.8", "10.10"))

#: How far (metres) an unreviewed ear point may lie from the generic ear moved as a whole:
#: about the spread of how far ears stand out and how long they are.
EAR_SHAPE_SLACK = 0.006


def _skull_prior(cal: Calibration, generic: Head, under_hair: Collection[str] = ()) -> None:
    """Bring unreviewed skull and ear points (:data:`PRIOR_SLACK`) within their bound of the
    generic head carried by the face's points, recording those moved as ``"skull prior"``:
    each ear moved as a whole (the median of its points' offsets, bounded), its points
    within :data:`EAR_SHAPE_SLACK` of that; the skull points in ``under_hair`` go under the
    hair (:mod:`recon.shape.hair`)."""
    g = {i: generic.fp_position(i) for i in generic.feature_points}
    face = [i for i in FP_IDS if FEATURE_POINTS[i].group not in (10, 11) and i in g
            and cal.source.get(i) not in (None, "generic")]
    if len(face) < 4:
        return
    guess = _generic_guess(g, face, np.array([cal.points[i] for i in face]))
    normals = skull_normals(generic) if under_hair else {}
    ears = set()
    for ear in EARS:
        ids = [i for i in ear if i in guess and i in cal.points and cal.source.get(i) != "generic"]
        if not ids:
            continue
        ears.update(ids)
        d = np.array([cal.points[i] - guess[i] for i in ids])
        shift = np.median(d, axis=0)
        n = float(np.linalg.norm(shift))
        shift *= min(1.0, PRIOR_SLACK[ids[0]] / max(n, 1e-12))
        for i, di in zip(ids, d - shift):
            m = float(np.linalg.norm(di))
            p = guess[i] + shift + di * min(1.0, EAR_SHAPE_SLACK / max(m, 1e-12))
            if np.linalg.norm(p - cal.points[i]) > 1e-6:
                cal.points[i] = p
                cal.source[i] = "skull prior"
    for i, slack in PRIOR_SLACK.items():
        if i not in guess or cal.source.get(i) == "generic" or i in ears:
            continue
        d = cal.points[i] - guess[i]
        if i in under_hair and i in normals:
            # Along the normal the outline is hair over the skull; across it, as for any point.
            cal.points[i] = skull_under(guess[i], cal.points[i], normals[i], across_limit=slack)
            cal.source[i] = "under hair"
            continue
        n = float(np.linalg.norm(d))
        if n > slack:
            cal.points[i] = guess[i] + d * (slack / n)
            cal.source[i] = "skull prior"


def _drop(i: str, front: dict, side: dict, confidence: dict) -> str:
    """Remove point ``i`` (a front id; the side may hold it under its mirror label) from the
    view less sure of it, or from both; returns which."""
    side_id = i if i in side else FEATURE_POINTS[i].mirror
    cf = confidence["front"].get(i)
    cs = confidence["side"].get(side_id)
    if cf is not None and cs is not None and cf != cs:
        view = "front" if cf < cs else "side"
    else:
        view = "both"
    if view in ("front", "both"):
        front.pop(i, None)
    if view in ("side", "both"):
        side.pop(side_id, None)
    return view


def _weights(shared: list[str], side_any_label: dict[str, str], confidence: dict, core_only: bool = False
             ) -> np.ndarray:
    """(len(shared),) weights of the height fit: the less sure view's confidence, at least 0.1
    (with ``core_only``, 0 off the face's core)."""
    w = [min(confidence["front"].get(i, 1.0), confidence["side"].get(side_any_label[i], 1.0)) for i in shared]
    w = np.sqrt(np.clip(np.asarray(w, float), 0.1, 1.0))
    return w * np.array([is_core(i) for i in shared]) if core_only else w


def _calibrate(front, side, generic, ipd_mm, focal_px, front_size, side_size, height_tol_mm, confidence,
               core_fit: bool = False):
    """One calibration of the given points (see :func:`calibrate`); with ``core_fit`` the
    heights are fitted to the face's core points alone (the others are still placed, and
    judged against them)."""
    front = _as_points(front, "front")
    side = _as_points(side, "side")
    _check_inside(front, front_size, "front")
    _check_inside(side, side_size, "side")
    missing = [i for i in ("3.5", "3.6") if i not in front]
    if missing:
        raise InputError(f"the pupils {' and '.join(missing)} are not marked", where="front view",
                         fix="mark both pupils (3.5 left, 3.6 right); they set the scale and the roll")
    if not ipd_mm > 0:
        raise InputError(f"interpupillary distance {ipd_mm} mm is not positive", fix="give --ipd in millimetres, e.g. 63")
    if focal_px is not None and (front_size is None or side_size is None):
        raise InputError("a perspective calibration needs both image sizes", fix="give front_size and side_size")
    ipd = ipd_mm / 1000.0

    # Front: undo the roll (the face's left pupil 3.5 appears on the image's right).
    d = front["3.5"] - front["3.6"]
    if d[0] <= 0:
        raise InputError("the left pupil 3.5 is not to the right of the right pupil 3.6 in the image",
                         where="front view", fix="3.5 is the face's own left pupil, on the viewer's right; "
                                                 "swap 3.5 and 3.6 if they were placed the other way")
    roll = float(np.arctan2(-d[1], d[0]))  # image y grows downwards
    mid = 0.5 * (front["3.5"] + front["3.6"])
    c, s = np.cos(roll), np.sin(roll)
    rot = np.array([[c, -s], [s, c]])  # turns the eye line horizontal (image coordinates, y down)
    fu = {i: rot @ (p - mid) for i, p in front.items()}  # pixels, pupils' midpoint at 0, y down
    ipd_px = float(np.linalg.norm(d))

    facing = _side_depths(side)
    labelled = [FEATURE_POINTS[i].side for i in side]
    visible = "R" if labelled.count("R") > labelled.count("L") else "L"
    # Side heights for every id the side view gives, its own or its mirror partner's.
    side_any: dict[str, np.ndarray] = {}
    label: dict[str, str] = {}
    for i, p in side.items():
        side_any[i], label[i] = p, i
    for i, p in side.items():
        m = FEATURE_POINTS[i].mirror
        if m and m not in side_any:
            side_any[m], label[m] = p, i
    shared = [i for i in FP_IDS if i in fu and i in side_any]
    if len(shared) < 3:
        raise InputError(f"only {len(shared)} points are marked in both views ({', '.join(shared) or 'none'})",
                         where="side view", fix="mark at least three points seen in both photos, e.g. 9.3, 2.1, "
                                                "3.7, 8.3, 9.15")

    # Midline in the front photo: mean of the pair midpoints and midline points.
    xs = [fu[i][0] for i in fu if FEATURE_POINTS[i].side == "C"]
    xs += [0.5 * (fu[i][0] + fu[FEATURE_POINTS[i].mirror][0]) for i in fu
           if FEATURE_POINTS[i].side == "L" and FEATURE_POINTS[i].mirror in fu]
    x_mid = float(np.mean(xs))

    if focal_px is None:
        sf = ipd / ipd_px
        X = {i: (p[0] - x_mid) * sf for i, p in fu.items()}
        Yf = {i: -p[1] * sf for i, p in fu.items()}
        a, c, b, resid = _fit_heights(shared, Yf, side_any, _weights(shared, label, confidence, core_fit))
        ss = float(np.hypot(a, c))
        # The side photo's plane by a similarity: heights a v + c u + b, depths at right
        # angles (c = 0 when the head did not nod between the photos).
        Z = {i: facing * (c * p[1] - a * p[0]) for i, p in side_any.items()}
        Ys = {i: a * p[1] + c * p[0] + b for i, p in side_any.items()}
        scales = {"front": sf, "side": ss}
    else:
        X, Yf, Z, Ys, resid, scales, sin_yaw = _perspective(
            front, side_any, generic, ipd, focal_px, front_size, side_size, roll, facing, visible, shared,
            _weights(shared, label, confidence, core_fit))
    # The front photo's turn: x seen there is x + z sin(yaw) + c, and every length is too
    # long by 1 / cos(yaw) (the pupils look closer together than the IPD given).
    # (The perspective branch takes the turn out as it goes.)
    if focal_px is None:
        # Unweighted by the points' confidences: they speak of where a point lies, not of
        # the midline; a point placed by hand (confidence 1) among the generic head's
        # guesses (0) held a turn of 64 degrees alone.
        sin_yaw, x0 = front_turn(X, Z)
        z_of = generic_depths(X, Z, generic)
        X = {i: v - x0 - sin_yaw * z_of[i] for i, v in X.items()}
        cos_yaw = float(np.sqrt(1.0 - sin_yaw ** 2))
        Yf, Z, Ys = ({i: v * cos_yaw for i, v in d.items()} for d in (Yf, Z, Ys))
        resid = {i: v * cos_yaw for i, v in resid.items()}
        scales = {k: v * cos_yaw for k, v in scales.items()}
    worst = max(shared, key=lambda i: abs(resid[i]))
    if abs(resid[worst]) * 1000 > height_tol_mm:
        top = sorted(shared, key=lambda i: -abs(resid[i]))[:3]
        raise HeightsDisagree({i: resid[i] * 1000 for i in shared}, "the heights of the points marked in both photos disagree: "
                         + ", ".join(f"{i} by {resid[i] * 1000:+.1f} mm" for i in top),
                         where="side view", fix=f"check those points (tolerance {height_tol_mm:g} mm); the two "
                                                "photos must show the same neutral pose"
                                                + ("; photos taken from nearer than a few metres need the lens's "
                                                   "focal length (--focal, pixels): without it the heights of "
                                                   "points far from the middle disagree by a few mm"
                                                   if focal_px is None else ""))

    # Assemble: x from the front (0 on the midline), y from both, z from the side.
    pts: dict[str, list] = {}
    source: dict[str, str] = {}
    for i in FP_IDS:
        fp = FEATURE_POINTS[i]
        x = X.get(i)
        if x is None and fp.mirror in X:
            x = -X[fp.mirror]
        if fp.side == "C" and (i in X or i in side_any):
            x = 0.0
        ys = [v for v in (Yf.get(i), Ys.get(i) if i in side else None) if v is not None]
        if not ys and fp.mirror and fp.mirror in Yf:
            ys = [Yf[fp.mirror]]
        if not ys and i in Ys:
            ys = [Ys[i]]
        z = Z.get(i)
        pts[i] = [x, float(np.mean(ys)) if ys else None, z]
        known = [v is not None for v in pts[i]]
        if all(known):
            source[i] = "front+side" if i in side else ("mirror" if i in fu else "side")
        elif any(known):
            source[i] = "front" if i in fu else "side"
        else:
            source[i] = "generic"

    # Bring the free y/z origin to the generic head's, then fill what is missing from the
    # generic head similarity-fitted to the complete points.
    full = [i for i in FP_IDS if None not in pts[i] and i in generic.feature_points]
    if len(full) < 4:
        raise InputError(f"only {len(full)} points are known in 3D", fix="mark more points in both views")
    g = {i: generic.fp_position(i) for i in generic.feature_points}
    p_full = np.array([pts[i] for i in full], dtype=np.float64)
    g_full = np.array([g[i] for i in full])
    shift = np.r_[0.0, (g_full - p_full).mean(axis=0)[1:]]
    for i in FP_IDS:
        pts[i] = [None if v is None else v + shift[k] for k, v in enumerate(pts[i])]
    guess = _generic_guess(g, full, p_full + shift)
    out = {}
    for i in FP_IDS:
        if None in pts[i]:
            if i not in g:
                raise InputError(f"feature point {i} is marked in neither view and the generic head lacks it")
            guess_i = guess[i]
            pts[i] = [guess_i[k] if v is None else v for k, v in enumerate(pts[i])]
        if FEATURE_POINTS[i].side == "C":
            pts[i][0] = 0.0
        out[i] = np.array(pts[i], dtype=np.float64)
    return Calibration(
        points=out, source=source, roll_deg=float(np.degrees(roll)), yaw_deg=float(np.degrees(np.arcsin(sin_yaw))),
        metres_per_px=scales,
        side_facing="right" if facing > 0 else "left", visible_side=visible,
        height_residual_mm={i: float(resid[i] * 1000) for i in shared},
        assumptions=dict(ipd_mm=float(ipd_mm), camera="orthographic" if focal_px is None
                         else f"perspective, focal length {focal_px:g} px",
                         height_tol_mm=float(height_tol_mm) if np.isfinite(height_tol_mm) else None))


def _generic_guess(g: dict, full: list, known: np.ndarray) -> dict:
    """Where the generic head's points go when its complete points move to ``known``.

    The generic feature points are carried by the same Dirichlet free-form deformation
    that will shape the head (complete points as controls, a similarity fit for the far
    field), so a point seen in one view gets its missing coordinate from its neighbours'
    motion rather than from one global transform.
    """
    ids = list(g)
    rest = np.array([g[i] for i in ids])
    g_full = np.array([g[i] for i in full])
    _, first = np.unique(g_full.round(9), axis=0, return_index=True)  # one control per place
    g_full, known = g_full[np.sort(first)], known[np.sort(first)]
    box = bounding_controls(rest)
    controls = np.vstack([g_full, box])
    displaced = np.vstack([known, fit_similarity(g_full, known)(box)])
    # Generic points that coincide with a control (or each other) keep their control's motion.
    uniq, inv = np.unique(rest.round(9), axis=0, return_inverse=True)
    moved = dffd(uniq, controls, displaced)[inv.reshape(-1)]
    return dict(zip(ids, moved))


def _fit_heights(shared, Yf, side_any, w):
    """The side photo's plane onto the front's heights (metres), weighted by ``w``: heights
    ``a v + c u + b`` of side pixels (u, v), a similarity whose angle is the head's nod
    between the two photos; returns a, c, b and the residuals.

    The nod is kept only when enough points spread in depth to measure it (three or more,
    spanning a fifth of their height range); otherwise c = 0.
    """
    v = np.array([side_any[i][1] for i in shared])
    u = np.array([side_any[i][0] for i in shared])
    y = np.array([Yf[i] for i in shared])
    c = 0.0
    if len(shared) >= 3 and np.ptp(u) > 0.2 * max(np.ptp(v), 1e-9):
        A = np.c_[v, u, np.ones_like(v)]
        (a, c, b), *_ = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)
        if abs(np.degrees(np.arctan2(c, -a))) > MAX_NOD_DEG:
            c = 0.0  # not a nod a person makes between two photos: fit without it
    if c == 0.0:
        A = np.c_[v, np.ones_like(v)]
        (a, b), *_ = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)
    if not a < 0:
        raise InputError("the side photo's heights run the wrong way against the front photo's",
                         where="side view", fix="check that the side photo is upright and its points are the "
                                                "same as the front photo's")
    return a, c, b, {i: float(a * side_any[i][1] + c * side_any[i][0] + b - Yf[i]) for i in shared}


def _perspective(front, side_any, generic, ipd, f, front_size, side_size, roll, facing, visible, shared, w):
    """Alternate between the views with pinhole cameras; returns the same pieces as the
    orthographic branch (X, Yf, Z, Ys, residuals, scales) and the front photo's turn
    (sine, :func:`recon.shape.turn.front_turn`), taken out of X at each round."""
    cf = (np.array(front_size, float) - 1) / 2
    cs = (np.array(side_size, float) - 1) / 2
    c, s = np.cos(roll), np.sin(roll)
    rot = np.array([[c, -s], [s, c]])
    # Normalised rays, roll removed about the principal point.
    rf = {i: rot @ (p - cf) / f for i, p in front.items()}
    rs = {i: (p - cs) / f for i, p in side_any.items()}
    sigma = 1.0 if visible == "L" else -1.0  # side camera on +x (sees the left) or on -x
    # Start with depth 0 everywhere; the front camera distance from the pupils' spread.
    z = {i: 0.0 for i in set(rf) | set(rs)}
    x = {i: 0.0 for i in set(rf) | set(rs)}
    spread = np.linalg.norm(rf["3.5"] - rf["3.6"])
    sin_yaw, cos_yaw = 0.0, 1.0
    for _ in range(_PERSPECTIVE_ROUNDS):
        # The head turned by yaw in the front camera's frame: x' = x cos + z sin (+ an
        # offset), depth z' = z cos - x sin; a point at depth z' is dist_f - z' away.
        seen = {i: v for i, v in z.items() if i in rs}  # depth 0 in the first round
        z_of = generic_depths(rf, seen, generic)
        zc = {i: z_of[i] * cos_yaw - x[i] * sin_yaw for i in rf}
        # The pupils are ipd apart: x'_L - x'_R = ipd cos + (z_L - z_R) sin.
        dist_f = (ipd * cos_yaw + (z_of["3.5"] - z_of["3.6"]) * sin_yaw
                  + rf["3.5"][0] * zc["3.5"] - rf["3.6"][0] * zc["3.6"]) / (rf["3.5"][0] - rf["3.6"][0])
        turned = {i: r[0] * (dist_f - zc[i]) for i, r in rf.items()}
        Yf = {i: -r[1] * (dist_f - zc[i]) for i, r in rf.items()}
        sin_yaw, x0 = front_turn(turned, seen)
        cos_yaw = np.sqrt(1.0 - sin_yaw ** 2)
        X = {i: (v - x0 - sin_yaw * z_of[i]) / cos_yaw for i, v in turned.items()}
        x.update(X)

        def x_seen(i):
            """x of the side-photo point labelled ``i`` (a mirror label stands for its partner)."""
            xi = x.get(i, 0.0)
            return xi if FEATURE_POINTS[i].side in ("C", visible) else -xi

        # Side heights: Yf = y0 - v (D - sigma x) with unknown y0 and D (linear least squares).
        v = np.array([rs[i][1] for i in shared])
        xv = np.array([sigma * x_seen(i) for i in shared])
        y = np.array([Yf[i] for i in shared])
        A = np.c_[np.ones_like(v), -v]
        (y0, dist_s), *_ = np.linalg.lstsq(A * w[:, None], (y - v * xv) * w, rcond=None)
        if not dist_s > 0:
            raise InputError("the side photo's heights run the wrong way against the front photo's", where="side view",
                             fix="check that the side photo is upright")
        Z = {i: facing * r[0] * (dist_s - sigma * x_seen(i)) for i, r in rs.items()}
        Ys = {i: y0 - r[1] * (dist_s - sigma * x_seen(i)) for i, r in rs.items()}
        z.update(Z)
    resid = {i: float(Ys[i] - Yf[i]) for i in shared}
    scales = {"front": float(ipd * cos_yaw / (spread * f)),
              "side": float((dist_s - sigma * x["3.5"]) / f)}
    return X, Yf, Z, Ys, resid, scales, sin_yaw
