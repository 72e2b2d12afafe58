"""The ears' feature points from the ear's own shape (:func:`ears_by_outline`).

A grey render shows a photo detector no ear it can read, so the ear points are guessed
(:func:`recon.mark.views.untextured_guesses`) and come from the generic head fitted to the
surface (``how`` ``"shape"``). The generic head's ear is not the mesh's: on MakeHuman's
head the fitted top of the ear and the upper join sat 5-6 mm behind the helix (10.1, 10.9)
and the lowest point of the lobe 8 mm inside it, on the side of the head (10.5).

The auricle is the one part of a head that stands free of it: a ray from the side through
its rim meets the surface at least three times before the midline (into the flap, out of
it, into the head), where a ray through the cheek or the skull meets it once. The pixels
of a side-on grid whose rays do so are the ear's free rim (the helix and the lobe), and the
standard's ear points are read off that outline (:data:`EAR_RULES`):

- 10.1 / 10.2 top of the ear: the rim's highest point;
- 10.5 / 10.6 lowest point of the lobe: its lowest;
- 10.3 / 10.4 rear rim at mid height: the rim's rearmost point halfway between the two;
- 10.9 / 10.10 upper point where the ear joins the head: the rim's front end above mid
  height (where the helix runs into the head).

10.7 / 10.8 (where the lobe joins the face) is left to the fit: on an attached lobe the
free rim ends at the lobe's lowest point, and the join in front of it is no edge a ray sees.
Each point is the first surface the side ray at its pixel meets (the rim itself).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .lift import Hit, _Surface

__all__ = ["EAR_RULES", "ear_rim", "ears_by_outline"]

#: Left ear point, its right partner and the rule that reads it off the rim.
EAR_RULES = (("10.1", "10.2", "top"), ("10.5", "10.6", "bottom"), ("10.3", "10.4", "rear"),
             ("10.9", "10.10", "front_top"))

#: Where the lobe joins the face (left, right): left to the fit, but part of the ear.
_JOINS = (("10.7", "10.8", "bottom_join"),)

#: The ear points the rim is looked for around (left, right).
_EAR_GUIDES = (("10.1", "10.3", "10.5"), ("10.2", "10.4", "10.6"))

_STEP = 0.0005  # grid spacing on the side, metres: the rim is a few millimetres wide
_MARGIN = 0.015  # the grid reaches this far beyond the guessed top, rear and lowest points
_NEAR = 0.012  # the rim must pass this near each guide point in the side view (the fit's ear error)
_MIN_HEIGHT = 0.02  # a rim shorter than this is not an ear's
_BAND = 0.001  # the top and bottom are the middles of the rim's highest and lowest millimetre
_COARSE = 4  # the first pass's step, in steps: the rim's piece is found at 2 mm
_COARSE_PAD = 0.006  # the fine pass reaches this far beyond the piece the first pass found (metres)


def ear_rim(surface: _Surface, top: float, front: float, size: tuple[float, float], side: float,
            step: float = _STEP, only: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Where the side rays through a grid meet the skin (the surface, on a head without a
    ``skin`` part) three times or more on the ear's side of the midline.

    Parameters
    ----------
    surface : _Surface
        The head in the neutral frame, metres.
    top, front : float
        The grid's highest y and lowest z (neutral frame, metres).
    size : (2,) float
        Its height and depth, metres.
    side : float
        +1 for the left ear (x > 0; rays along −x), −1 for the right.
    step : float
        The grid's spacing, metres.
    only : (R, C) bool, optional
        Cast only these rays (the others are no rim and meet nothing).

    Returns
    -------
    rim : (R, C) bool
        Row r at height ``top - r * step``, column c at depth ``front + c * step``.
    first : (R, C, 3) float
        The first skin point each ray meets (NaN where none).
    """
    ys = top - step * np.arange(int(np.ceil(size[0] / step)))
    zs = front + step * np.arange(int(np.ceil(size[1] / step)))
    z, y = np.meshgrid(zs, ys)
    start = side * (np.abs(surface.vertices[:, 0]).max() + 0.01)
    o = np.c_[np.full(z.size, start), y.ravel(), z.ravel()]
    cast = np.arange(len(o)) if only is None else np.flatnonzero(np.asarray(only, bool).ravel())
    d = np.tile([-side, 0.0, 0.0], (len(cast), 1))
    loc, ray, tri = surface.mesh.ray.intersects_location(o[cast], d, multiple_hits=True)
    loc, tri = np.reshape(loc, (-1, 3)), np.asarray(tri, dtype=np.int64)
    ray = cast[np.asarray(ray, dtype=np.int64)]
    if "skin" in surface.names:
        # Only the skin: hair over an ear (its own part) would stand free of the head too.
        on_skin = surface.part_of[tri] == surface.names.index("skin")
        loc, ray = loc[on_skin], ray[on_skin]
    near_side = side * loc[:, 0] > 0
    count = np.bincount(ray[near_side], minlength=len(o))
    first = np.full((len(o), 3), np.nan)
    # The first hit of each ray is the one furthest out along the ray's start side.
    order = np.lexsort((-side * loc[:, 0], ray))
    lead = order[np.r_[True, ray[order][1:] != ray[order][:-1]]] if len(order) else order
    first[ray[lead]] = loc[lead]
    return (count >= 3).reshape(z.shape), first.reshape(z.shape + (3,))


def _rim_piece(rim: np.ndarray, guides_px: np.ndarray, near_px: float) -> np.ndarray | None:
    """(K, 2) row, column of the connected piece of ``rim`` that passes nearest the guide
    pixels (each within ``near_px``), or None."""
    from scipy import ndimage

    labels, n = ndimage.label(rim, structure=np.ones((3, 3)))
    best, best_cost = None, np.inf
    for k in range(1, n + 1):
        px = np.argwhere(labels == k)
        gaps = np.array([np.min(np.linalg.norm(px - g, axis=1)) for g in guides_px])
        if gaps.max() <= near_px and gaps.sum() < best_cost:
            best, best_cost = px, gaps.sum()
    return best


def rim_points(px: np.ndarray, forward: float = 1.0) -> dict[str, tuple[int, int]]:
    """The rules of :data:`EAR_RULES` on a rim's (K, 2) row, column pixels (row 0 the
    highest, columns forward with ``forward`` = +1): rule → (row, column)."""
    rows = px[:, 0]
    top, bottom = rows.min(), rows.max()
    mid = int(round(0.5 * (top + bottom)))
    # The top of a helix is flat for about a centimetre: its single highest pixel wanders
    # along it with the slightest roll of the frame, the middle of its highest band does not.
    band = max(1, int(round(_BAND / _STEP)))
    out = {"top": _middle(px[rows <= top + band], -1), "bottom": _middle(px[rows >= bottom - band], 1)}
    # The row at mid height, or the nearest row the rim has.
    row = rows[np.argmin(np.abs(rows - mid))]
    at = px[rows == row]
    out["rear"] = (int(row), int(at[np.argmin(at[:, 1] * forward), 1]))
    upper = px[rows < mid]
    k = np.argmax(upper[:, 1] * forward)
    out["front_top"] = (int(upper[k, 0]), int(upper[k, 1]))
    return out


def _middle(px: np.ndarray, down: int) -> tuple[int, int]:
    """The rim pixel at the middle column of a band of (K, 2) row, column pixels, at the
    band's outer edge (its highest with ``down`` = −1, its lowest with +1): on the rim,
    where the ray meets the ear rather than the head behind it."""
    col = np.median(px[:, 1])
    at = px[np.abs(px[:, 1] - col) == np.abs(px[:, 1] - col).min()]
    k = np.argmax(at[:, 0] * down)
    return int(at[k, 0]), int(at[k, 1])


def _fine_rim(surface: _Surface, hi: np.ndarray, lo: np.ndarray, guides: np.ndarray, side: float
              ) -> tuple[np.ndarray, np.ndarray] | None:
    """The rim's piece near the (G, 3) ``guides`` in the grid at :data:`_STEP` spanning
    ``lo`` to ``hi`` (the (y, z) corners, metres: rows down from ``hi[0]``, columns back
    from ``lo[1]``): (K, 2) row, column pixels and the grid's first hits (as
    :func:`ear_rim`), or None.

    A pass at four times the step finds the piece; the fine grid, on the full grid's own
    lattice, then casts only the rays within :data:`_COARSE_PAD` of it, so that the piece is
    the one the full grid gives for a fraction of the rays (the rays are the marking's
    slowest step)."""
    coarse = _COARSE * _STEP
    rim, _ = ear_rim(surface, hi[0], lo[1], hi - lo, side, step=coarse)
    near = _NEAR / coarse
    piece = _rim_piece(rim, np.c_[(hi[0] - guides[:, 1]) / coarse, (guides[:, 2] - lo[1]) / coarse], near)
    if piece is None:
        return None
    # The box in the full grid's rows and columns: the piece's, the guides', and a margin.
    rows = np.r_[piece[:, 0] * _COARSE, (hi[0] - guides[:, 1]) / _STEP]
    cols = np.r_[piece[:, 1] * _COARSE, (guides[:, 2] - lo[1]) / _STEP]
    pad = _COARSE_PAD / _STEP
    r0, c0 = (max(int(np.floor(a.min() - pad)), 0) for a in (rows, cols))
    r1, c1 = (int(np.ceil(a.max() + pad)) for a in (rows, cols))
    top, front = hi[0] - r0 * _STEP, lo[1] + c0 * _STEP
    size = ((r1 - r0) * _STEP, (c1 - c0) * _STEP)
    shape = tuple(int(np.ceil(a / _STEP)) for a in size)
    rr, cc = np.mgrid[:shape[0], :shape[1]]
    near_piece = cKDTree(piece * _COARSE - [r0, c0]).query(np.c_[rr.ravel(), cc.ravel()],
                                                           distance_upper_bound=pad)[0] <= pad
    rim, first = ear_rim(surface, top, front, size, side, only=near_piece.reshape(shape))
    px = _rim_piece(rim, np.c_[(top - guides[:, 1]) / _STEP, (guides[:, 2] - front) / _STEP], _NEAR / _STEP)
    return None if px is None else (px, first)


def ears_by_outline(hits: dict[str, Hit], surface: _Surface, confidence: float = 0.6) -> dict[str, Hit]:
    """``hits`` with the ear points the fit guessed (``how`` ``"shape"``) placed on the ear's
    free rim (see the module docstring; ``how`` ``"ear rim"``).

    Points a detector found (any other ``how``) are kept. An ear whose rim is not found
    near the guessed points (no ear, an ear under hair, a face mask) keeps its guesses.

    Parameters
    ----------
    hits : dict of str to Hit
        After :func:`recon.mark.points.fitted_points`, neutral frame, metres.
    surface : _Surface

    Returns
    -------
    dict of str to Hit
    """
    out = dict(hits)
    for side, guides in zip((1.0, -1.0), _EAR_GUIDES):
        k = 0 if side > 0 else 1
        todo = [rule for rule in EAR_RULES if rule[k] in hits and hits[rule[k]].how == "shape"]
        if not todo or not all(g in hits for g in guides):
            continue
        g = np.array([hits[i].point for i in guides])
        # The grid spans every point of the ear there is (the joins are its front), and more.
        every = np.array([hits[r[k]].point for r in EAR_RULES + _JOINS if r[k] in hits])
        lo, hi = every[:, 1:].min(axis=0) - _MARGIN, every[:, 1:].max(axis=0) + _MARGIN
        found = _fine_rim(surface, hi, lo, g, side)
        if found is None:
            continue
        px, first = found
        if (px[:, 0].max() - px[:, 0].min()) * _STEP < _MIN_HEIGHT:
            continue
        at = rim_points(px)
        for rule in todo:
            r, c = at[rule[2]]
            p = first[r, c]
            if not np.isfinite(p).all():
                continue
            tri, snapped = surface.closest(p[None])
            out[rule[k]] = surface.hit(int(tri[0]), snapped[0], confidence, "ear rim")
    return out
