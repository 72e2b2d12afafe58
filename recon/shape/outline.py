"""The profile the side photo shows, between the feature points.

The feature points fix the forehead, the nose, the lips and the chin at a dozen places on
the face's midline; between them the head keeps the generic shape (Lee et al. name it:
too few points on the profile). The side photo's outline from the brow down to the chin is
the midline itself seen edge-on, and no hair hides it, so :func:`profile_controls` reads
it there: each of the head's midline vertices between the brow and the chin is projected
by the side photo's camera, and the photo's outline in its row against the head's own
outline there (the head rendered by the same camera) says how far forward (or back) the
face is at that height. Those moves, at midline vertices a few millimetres apart and away
from the feature points, are carried over the face as one smooth field along its depth
(:func:`follow_profile`: between their heights, and across the face with a Gaussian
fall-off from the midline), less the smoothest field that takes it back at the feature
points, which stay where they are; :func:`match_profile` does it twice, the second round
taking most of what the first left.

An outline row that disagrees with the head by far more than a profile can (a fringe over
the forehead, glasses on the nose, a hand) is left out, and so is a control whose
neighbours along the profile disagree with it (a median over a few controls).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mpeg4.camera import Camera
from mpeg4.head import Head

__all__ = ["PROFILE_SPACING_MM", "MAX_PROFILE_SHIFT_IPD", "PROFILE_PASSES", "PROFILE_WIDTH_MM", "HOLD_MM",
           "ProfileControls", "profile_controls", "follow_profile", "match_profile"]

#: Spacing of the profile's controls along the face's height, millimetres.
PROFILE_SPACING_MM = 3.0
#: A control is not placed this close to a feature point (millimetres): the point already
#: holds the skin there.
_CLEAR_OF_POINTS_MM = 3.0
#: Largest move of the profile towards the photo's outline, in interpupillary distances
#: (a tenth: 6 mm); a row further off is not the face's outline.
MAX_PROFILE_SHIFT_IPD = 0.1
#: Rounds of :func:`match_profile`: near the feature points their holds take part of each
#: move back, and the rendered outline is read again after each round (on meds_s001 the
#: controls' mean move was 2.2, 0.7, then 0.4 mm). A third round brought the real pairs'
#: profile line closer to their outlines (3.11 to 2.89 % of the IPD) but took the synthetic
#: people's profiles further from the truth (1.38 to 1.47 mm): two.
PROFILE_PASSES = 2
#: How far to either side of the midline the profile's move reaches, millimetres (the
#: standard deviation of its Gaussian fall-off across the face): about half a nose's width.
PROFILE_WIDTH_MM = 8.0
#: How far about the vertices a feature point is bound to its hold reaches, millimetres:
#: the skin this close bends from the point's place to the profile's move.
HOLD_MM = 8.0
#: Midline vertices: this close to the head's plane of symmetry, millimetres.
_MIDLINE_MM = 1.0
#: Controls along the profile a move is the median of (odd).
_MEDIAN_OF = 3
_BROW_IDS = ("4.1", "4.2", "4.3", "4.4", "4.5", "4.6")


@dataclass
class ProfileControls:
    """Midline vertices moved onto the side photo's outline.

    Attributes
    ----------
    vertices : (M,) int64
        Skin vertices used as controls.
    rest, goal : (M, 3) float64
        Where they are and where the outline puts them, metres.
    shift_mm : (M,) float64
        Forward (+) or back (-) along the face's depth.
    left_out : int
        Midline vertices between the brow and the chin whose outline row disagreed too much.
    """

    vertices: np.ndarray
    rest: np.ndarray
    goal: np.ndarray
    shift_mm: np.ndarray
    left_out: int = 0


def _face_edge(mask: np.ndarray, rows: np.ndarray, towards: int) -> np.ndarray:
    """(len(rows),) the face-side edge of ``mask`` in each (integer) row, at the outer side
    of its last pixel; NaN where empty. ``towards``: -1 when the face looks to the image's
    left, +1 to its right."""
    from recon.landmarks.silhouette import row_extents

    left, right = row_extents(mask)
    return left[rows] - 0.5 if towards < 0 else right[rows] + 0.5


def _rendered(head: Head, camera: Camera) -> np.ndarray:
    """(H, W) bool: where ``head`` covers the camera's image."""
    from mpeg4.preview import head_meshes
    from mpeg4.render import render

    _, depth = render(head_meshes(head), camera, return_depth=True, samples=0, ambient=1.0)
    return np.isfinite(depth)


def profile_controls(head: Head, side_mask: np.ndarray, camera: Camera, side_points: Mapping[str, np.ndarray],
                     spacing_mm: float = PROFILE_SPACING_MM) -> ProfileControls:
    """The head's midline vertices between the brow and the chin, and where the side
    photo's outline puts them.

    Parameters
    ----------
    head : Head
        The fitted head (metres; +z the face's forward direction).
    side_mask : (H, W) bool
        The head's silhouette in the side photo.
    camera : Camera
        The side photo's camera for ``head``.
    side_points : mapping of str to (2,) float
        Feature points on the side photo (pixels): the highest eyebrow point and the chin
        (2.1) bound the outline used.
    spacing_mm : float
        Distance between controls along the face's height.

    Returns
    -------
    ProfileControls
        Empty (no vertices) when the photo shows no usable outline.
    """
    none = ProfileControls(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    mask = np.asarray(side_mask, bool)
    brows = [side_points[i][1] for i in _BROW_IDS if i in side_points]
    if not brows or "2.1" not in side_points or not mask.any():
        return none
    top_row, chin_row = min(brows), float(side_points["2.1"][1])
    skin = head.skin.vertices
    # The face's forward direction in the image: the head's forward axis projected at the eyes.
    centre = 0.5 * (head.fp_position("3.5") + head.fp_position("3.6"))
    a, b = camera.project(np.array([centre, centre + [0.0, 0.0, 0.01]]))
    towards = 1 if b[0] > a[0] else -1
    du_dz = (b[0] - a[0]) / 0.01  # pixels per metre forward, at the eyes' depth
    ipd_px = abs(du_dz) * float(np.linalg.norm(head.fp_position("3.5") - head.fp_position("3.6")))
    fps = np.array(list(head.fp_positions().values()))
    mid = np.flatnonzero(np.abs(skin[:, 0]) < _MIDLINE_MM * 1e-3)
    mid = mid[skin[mid, 2] > centre[2] - 0.01]  # the face's side of the head
    if not len(mid):
        return none
    uv = camera.project(skin[mid])
    inside = (uv[:, 1] >= top_row) & (uv[:, 1] <= chin_row)
    mid, uv = mid[inside], uv[inside]
    # Per height, the midline vertex furthest forward: the one the outline is made by.
    order = np.argsort(skin[mid, 1])
    mid, uv = mid[order], uv[order]
    bins = np.floor((skin[mid, 1] - skin[mid, 1].min()) / (spacing_mm * 1e-3)).astype(int)
    pick = []
    for k in np.unique(bins):
        j = np.flatnonzero(bins == k)
        pick.append(j[np.argmax(skin[mid[j], 2])])
    mid, uv = mid[pick], uv[pick]
    clear = np.min(np.linalg.norm(skin[mid][:, None] - fps[None], axis=2), axis=1) > _CLEAR_OF_POINTS_MM * 1e-3
    mid, uv = mid[clear], uv[clear]
    if len(mid) < _MEDIAN_OF:
        return none
    rows = np.clip(np.round(uv[:, 1]).astype(int), 0, mask.shape[0] - 1)
    # The photo's outline against the head's own, row by row: where the outline is not made
    # by the midline (below the nose the alae may stand out), the two still agree when the
    # head is right.
    shift_px = (_face_edge(mask, rows, towards) - _face_edge(_rendered(head, camera), rows, towards)) * towards
    limit = MAX_PROFILE_SHIFT_IPD * ipd_px
    ok = np.isfinite(shift_px) & (np.abs(shift_px) <= limit)
    # A move its neighbours along the profile do not share is noise in the outline.
    padded = np.where(ok, shift_px, np.nan)
    half = _MEDIAN_OF // 2
    smooth = np.array([np.nanmedian(padded[max(0, k - half):k + half + 1])
                       if np.isfinite(padded[max(0, k - half):k + half + 1]).any() else np.nan
                       for k in range(len(padded))])
    ok &= np.isfinite(smooth) & (np.abs(shift_px - smooth) <= 0.03 * ipd_px)
    shift_m = smooth[ok] / abs(du_dz)
    v = mid[ok]
    rest = skin[v].copy()
    goal = rest + shift_m[:, None] * [0.0, 0.0, 1.0]
    return ProfileControls(v, rest, goal, shift_m * 1000.0, left_out=int((~ok).sum()))


def _profile_field(points: np.ndarray, ys: np.ndarray, zs: np.ndarray, moves: np.ndarray,
                   width_mm: float) -> np.ndarray:
    """(N,) metres: the profile's move at ``points`` along the face's depth: the controls'
    moves (at heights ``ys``, depths ``zs``) interpolated by height and faded out over two
    spacings beyond the first and last (a raised cosine: nothing above the brow or below
    the chin), times a Gaussian of the distance from the midline (``width_mm``), on the
    face's side of the head only (within 3-5 cm of the profile's depth)."""
    v = np.asarray(points, float)
    along = np.interp(v[:, 1], ys, moves)
    fade = 2 * PROFILE_SPACING_MM * 1e-3
    beyond = np.maximum(np.maximum(ys[0] - v[:, 1], v[:, 1] - ys[-1]), 0.0)
    along = along * 0.5 * (1 + np.cos(np.pi * np.minimum(beyond / fade, 1.0)))
    across = np.exp(-0.5 * (v[:, 0] / (width_mm * 1e-3)) ** 2)
    behind = np.interp(v[:, 1], ys, zs) - v[:, 2]
    front = 0.5 * (1 + np.cos(np.pi * np.clip((behind - 0.03) / 0.02, 0.0, 1.0)))
    return along * across * front


def follow_profile(head: Head, controls: ProfileControls, width_mm: float = PROFILE_WIDTH_MM) -> Head:
    """``head`` with its face moved along its depth onto the profile, the feature points
    held: the controls' moves (:func:`profile_controls`) as one smooth field (carried
    between their heights, and across the face with a Gaussian fall-off from the midline,
    ``width_mm``), less the smoothest field over the skin (bi-harmonic,
    :func:`mpeg4.surface.bilaplacian`) that equals it at the vertices the feature points
    are bound to and vanishes :data:`HOLD_MM` from them: every point stays exactly where it
    was put, and the skin around bends smoothly from it. The eyes, teeth and tongue stay
    where they are: the profile is skin (and the pupils, feature points on the eyeballs,
    must not move).

    The profile's moves were once DFFD controls on the midline's vertices, 3 mm apart: the
    DFFD is only continuous at its controls, and a row of them folded the skin along the
    midline (a crease down the philtrum and the chin of a real pair's head)."""
    from scipy.spatial import cKDTree

    from mpeg4.surface import bilaplacian, smoothest_fill

    from .deform import RIGID_PARTS

    if not len(controls.vertices):
        return head
    order = np.argsort(controls.rest[:, 1])
    ys, zs = controls.rest[order, 1], controls.rest[order, 2]
    moves = controls.goal[order, 2] - controls.rest[order, 2]
    out = head.copy()
    for name, part in out.parts.items():
        if name in RIGID_PARTS or not len(part.vertices):
            continue
        v = part.vertices
        move = _profile_field(v, ys, zs, moves, width_mm)
        held = np.array(sorted({int(i) for b in head.feature_points.values() if b.part == name
                                for i in b.vertices}), dtype=np.int64)
        acting = held[np.abs(move[held]) > 1e-9] if len(held) else held
        if len(acting) and len(part.triangles):
            # Every point's vertices are held (back = move there), the skin within HOLD_MM
            # of those the field reaches bends, the rest keeps the field.
            near = cKDTree(v[acting]).query(v, distance_upper_bound=HOLD_MM * 1e-3)[0] < np.inf
            free = near & ~np.isin(np.arange(len(v)), held)
            back = np.zeros(len(v))
            back[held] = move[held]
            try:
                back = smoothest_fill(bilaplacian(v, part.triangles), back, free)
            except RuntimeError:  # skin near a point but on a piece of its own: the point alone held
                pass
            move = move - back
        part.vertices = v + move[:, None] * [0.0, 0.0, 1.0]
    return out


def match_profile(head: Head, side_mask: np.ndarray, camera: Camera, side_points: Mapping[str, np.ndarray],
                  passes: int = PROFILE_PASSES) -> Head:
    """:func:`profile_controls` then :func:`follow_profile`, ``passes`` times;
    ``metadata["fit"]["profile"]`` records the controls of each round (how many, how many
    rows were left out, their mean and largest move in millimetres)."""
    rounds = []
    for _ in range(passes):
        pc = profile_controls(head, side_mask, camera, side_points)
        if not len(pc.vertices):
            break
        head = follow_profile(head, pc)
        s = pc.shift_mm
        rounds.append({"controls": int(len(s)), "left_out": pc.left_out,
                       "mean_move_mm": round(float(np.abs(s).mean()), 2),
                       "largest_move_mm": round(float(s[np.argmax(np.abs(s))]), 2)})
    fit = dict(head.metadata.get("fit", {}))
    fit["profile"] = {"rounds": rounds} if rounds else {"rounds": [], "note": "no outline between the brow and the chin"}
    head.metadata = dict(head.metadata, fit=fit)
    return head
