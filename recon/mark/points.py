"""Feature points the renders cannot show: from the generic head fitted to the surface.

:func:`fitted_points` fits the generic head's skin to the mesh, following the points found
on it, and takes the points a grey render can only guess from the fit;
:func:`inner_lip_halfway` puts the inner lip contour's half-way points halfway to the
corners, on the contour a front scan finds; :func:`lips_on_their_own_side` keeps the inner
lip points on their own lip where the lips touch; :func:`pupils_in_openings` centres the
pupils of a head without eyeballs in its eye openings; :func:`hidden_points` places those no view shows and no fit reached (teeth,
tongue).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import Head
from recon.shape.deform import fit_similarity

from .lift import Hit, _Surface

__all__ = ["fitted_points", "lips_on_their_own_side", "inner_lip_halfway", "pupils_in_openings", "hidden_points"]

#: The inner lip points by lip (+1 upper, -1 lower), and the outer points each lip is
#: known by: the vermilion's top and bottom and the philtrum's and chin's sides of it.
INNER_LIP_SIDE = {"2.2": 1.0, "2.6": 1.0, "2.7": 1.0, "2.3": -1.0, "2.8": -1.0, "2.9": -1.0}
OUTER_LIP_POINTS = {1.0: ("8.1", "8.5", "8.6"), -1.0: ("8.2", "8.7", "8.8")}

#: The inner lip contour's half-way points: the corner they are halfway to (the
#: standard's "halfway between 2.2 and 2.4" and so on), the upper point, the lower point.
#: Not the midline's 2.2 and 2.3: read so they lay 2.3 mm apart on closed lips (the upper
#: lip's front edge, the lower lip under it), and the p/b/m viseme's lip gap, measured
#: between them, went from 0.74 to 1.90 mm on MakeHuman's head.
INNER_LIP_HALVES = (("2.4", "2.6", "2.8"), ("2.5", "2.7", "2.9"))

_LIP_SCAN_STEP = 0.0001  # metres between the front rays of a scan down across the lips

#: Each pupil's eye: its two corners and its lid margins' centres (upper, lower).
PUPIL_EYE = {"3.5": (("3.7", "3.11"), ("3.1", "3.3")), "3.6": (("3.12", "3.8"), ("3.2", "3.4"))}

# How far along the mesh (metres) a lip's outer points claim its vertices: past the
# vermilion's depth (about 15 mm at the middle, round to the inner surface), short of the
# other lip by way of the corners.
_LIP_CLAIM = 0.03


def fitted_points(head: Head, hits: dict[str, Hit], guessed=(), give: float = 0.0,
                  surface: _Surface | None = None, generic: Head | None = None) -> dict[str, Hit]:
    """Points from the generic head fitted to the surface (:func:`recon.shape.template_fit.fit_generic`).

    The found skin points (all but ``guessed``) are the fit's anchors. Then:

    - a guessed point, one the detector missed, or an anchor the fit leaves out as an
      outlier: the fitted generic head's point, snapped to the skin (``how`` ``"shape"``;
      confidence 0.5 on the face, 0.3 for the ears, skull and hairline);
    - an anchor, when ``give`` > 0: the fitted point snapped to the skin, which smooths the
      detector's noise by the generic head's shape (``"fitted"``; the detector's
      confidence, lowered by how far the fit moved it);
    - 7.1 (inside the neck): the generic head's, carried by the fit, bound inside (0.3).

    Points not on the skin (pupils, teeth, tongue) are left as they are.

    Parameters
    ----------
    head : Head
        In the neutral frame, parts named (a ``skin`` part; else ``hits`` are returned).
    hits : dict of str to Hit
        From :func:`lift`.
    guessed : collection of str
        Points the detector could only guess (:func:`untextured_guesses`).
    give : float
        How far the shape may overrule the anchors (see ``fit_generic``); 0 keeps them.

    Returns
    -------
    dict of str to Hit
        In catalogue order.
    """
    from recon.shape.template_fit import fit_generic

    if "skin" not in head.parts:
        return hits
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    surface = surface or _Surface(head)
    gb = generic.feature_points
    anchors = {i: h for i, h in hits.items() if i not in guessed and h.confidence > 0 and i in gb
               and gb[i].part == "skin" and h.part == "skin"}
    skin = head.parts["skin"]
    try:
        fit = fit_generic(skin.vertices, skin.triangles, {i: h.point for i, h in anchors.items()},
                          {i: h.confidence for i, h in anchors.items()}, generic, give=give)
    except InputError:
        return hits
    out = dict(hits)
    ids = [i for i in fit.points if i in FEATURE_POINTS and i != "7.1"
           and (i not in anchors or give > 0 or i not in fit.anchors)]
    if ids:
        tri, snapped = surface.closest(np.array([fit.points[i] for i in ids]), ["skin"])
        for i, t, p in zip(ids, tri, snapped):
            if i in anchors and i in fit.anchors:
                moved = float(np.linalg.norm(p - anchors[i].point))
                out[i] = surface.hit(t, p, anchors[i].confidence * np.exp(-(moved / 0.006) ** 2), "fitted")
            else:
                far = FEATURE_POINTS[i].group in (7, 10, 11)
                out[i] = surface.hit(t, p, 0.3 if far else 0.5, "shape")
    if "7.1" in gb:
        out["7.1"] = Hit(fit.move(generic.fp_position("7.1"))[0], "skin", -1, np.zeros(3), 0.3, "shape")
    return {i: out[i] for i in FP_IDS if i in out}


def _generic_map(hits: Mapping[str, Hit], generic: Head):
    """Similarity taking the generic head's points onto the found ones (those with confidence)."""
    g = generic.fp_positions()
    ids = [i for i, h in hits.items() if i in g and h.confidence > 0 and h.how not in ("generic", "teeth", "tongue")]
    if len(ids) < 4:
        raise InputError(f"only {len(ids)} feature points were found on the surface", fix="check the mesh is a head")
    return fit_similarity(np.array([g[i] for i in ids]), np.array([hits[i].point for i in ids]),
                          np.array([hits[i].confidence for i in ids]))


def hidden_points(head: Head, hits: dict[str, Hit], generic: Head | None = None,
                  surface: _Surface | None = None) -> dict[str, Hit]:
    """Add the feature points no view shows, and any the detector missed.

    - teeth (9.8–9.11) and tongue (6.x) points: the generic head's, moved by the
      similarity between the generic head's mouth and nose points and the found ones,
      snapped to the head's own teeth or tongue (confidence 0.5);
    - 7.1 (inside the neck): the generic head's, moved by the similarity between the
      generic head's points and the found ones, bound inside (confidence 0.3);
    - any other point: the same, snapped to the skin (confidence 0: a guess).

    Returns
    -------
    dict of str to Hit
        ``hits`` with the new points added (catalogue order).
    """
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    surface = surface or _Surface(head)
    g = generic.fp_positions()
    out = dict(hits)
    to_head = _generic_map(hits, generic)
    mouth = {i: h for i, h in hits.items() if FEATURE_POINTS[i].group in (2, 8) or i in ("9.15", "9.1", "9.2", "9.3")}
    to_mouth = _generic_map(mouth, generic) if len(mouth) >= 6 else to_head
    groups = {"teeth_upper": ("teeth_upper", "gums_upper"), "teeth_lower": ("teeth_lower", "gums_lower"),
              "tongue": ("tongue",)}
    for i in FP_IDS:
        if i in out or i not in g:
            continue
        b = generic.feature_points[i]
        role = b.part if b.part in groups and b.part in head.parts else None
        if role is not None:
            p = to_mouth(g[i])
            tri, snapped = surface.closest(p[None], [role])
            out[i] = surface.hit(tri[0], snapped[0], 0.5, "teeth" if role != "tongue" else "tongue")
        elif i == "7.1":
            out[i] = Hit(to_head(g[i]), "skin", -1, np.zeros(3), 0.3, "generic")
        elif b.part == "skin" and "skin" in head.parts:
            tri, snapped = surface.closest(to_head(g[i])[None], ["skin"])
            out[i] = surface.hit(tri[0], snapped[0], 0.0, "generic")
    return {i: out[i] for i in FP_IDS if i in out}


def lip_sides(head: Head, hits: Mapping[str, Hit], reach: float = _LIP_CLAIM) -> np.ndarray:
    """(N,) +1 / −1 for skin vertices nearer along the mesh to the upper / lower lip's outer
    points (:data:`OUTER_LIP_POINTS`), 0 beyond ``reach`` metres of both or when a lip has
    none on the skin.

    Along the mesh the two lips meet only at the corners (and deep in the mouth), so
    vertices where the lips touch, a fraction of a millimetre apart, are told apart.
    """
    from mpeg4.surface import edge_graph, nearest_seed_labels

    skin = head.parts["skin"]
    seeds, sign = [], []
    for side, ids in OUTER_LIP_POINTS.items():
        own = [int(v) for i in ids if i in hits and hits[i].part == "skin" and hits[i].triangle >= 0
               for v in skin.triangles[hits[i].triangle]]
        if not own:
            return np.zeros(len(skin.vertices))
        seeds += own
        sign += [side] * len(own)
    # A vertex seeded by both lips (a corner) takes the lower's, given last.
    return nearest_seed_labels(edge_graph(skin.vertices, skin.triangles), seeds, sign, reach)


def _lips(head: Head, hits: Mapping[str, Hit], surface: _Surface | None) -> tuple[_Surface, np.ndarray] | None:
    """The surface (``surface``, or the head's) and :func:`lip_sides`, or None when the head
    has no skin or no lip is found."""
    if "skin" not in head.parts:
        return None
    sides = lip_sides(head, hits)
    return (surface or _Surface(head), sides) if sides.any() else None


def lips_on_their_own_side(head: Head, hits: dict[str, Hit], surface: _Surface | None = None) -> dict[str, Hit]:
    """``hits`` with each inner lip point (:data:`INNER_LIP_SIDE`) on a triangle of its own lip.

    Where the lips touch, the front ray, or the snap to the surface after the fit, may
    land on the other lip a fraction of a millimetre away: MakeHuman's upper inner lip
    point was bound to a vertex of its lower lip, and cloned motion then opened the
    target's upper lip with the jaw. A point whose triangle has a vertex of the other lip
    (:func:`lip_sides`) moves to the closest point among the triangles wholly on its own;
    its confidence and ``how`` are kept.
    """
    found = _lips(head, hits, surface)
    if found is None:
        return hits
    surface, sides = found
    skin = head.parts["skin"]
    mine = np.flatnonzero(surface.part_of == surface.names.index("skin"))  # the skin's triangles among all parts'
    out = dict(hits)
    for i, side in INNER_LIP_SIDE.items():
        h = hits.get(i)
        if h is None or h.part != "skin" or h.triangle < 0 or not (sides[skin.triangles[h.triangle]] == -side).any():
            continue
        own = mine[(sides[skin.triangles[surface.local[mine]]] == side).all(axis=1)]
        if not len(own):
            continue
        tri, p = surface._closest_among(h.point[None], own)
        out[i] = surface.hit(int(tri[0]), p[0], h.confidence, h.how)
    return out


def pupils_in_openings(head: Head, hits: dict[str, Hit], surface: _Surface | None = None) -> dict[str, Hit]:
    """``hits`` with each pupil on the skin (a head without eyeballs) at its eye opening's
    centre: across, midway between the eye's corners (the reference's rule for the lid
    margins' centres); up, midway between the lid margins; on the surface the front ray
    there meets (the socket behind the opening, or a lid).

    A grey render of an empty socket shows the detector no pupil: on MakeHuman's head it
    put the left one 10 mm inside the eye's centre, and the eye separation (ES0, the FAPU
    of the eyes' and brows' FAPs) came out short by about as much. A pupil on an eyeball is left alone.
    The confidence is the lower of the corners'; ``how`` is ``"eye opening"``.
    """
    if "skin" not in head.parts:
        return hits
    surface = surface or _Surface(head)
    out = dict(hits)
    for i, (corners, lids) in PUPIL_EYE.items():
        h = hits.get(i)
        if h is None or h.part != "skin" or not all(k in hits for k in corners + lids):
            continue
        across = 0.5 * (hits[corners[0]].point + hits[corners[1]].point)
        up = 0.5 * (hits[lids[0]].point[1] + hits[lids[1]].point[1])
        start = np.array([across[0], up, across[2] + 0.05])
        tri, loc = surface.cast(start[None], np.array([[0.0, 0.0, -1.0]]), radius=0.0)
        if tri[0] < 0:
            tri, loc = surface.closest(np.array([[across[0], up, across[2]]]), ["skin"])
        confidence = min(h.confidence, hits[corners[0]].confidence, hits[corners[1]].confidence)
        out[i] = surface.hit(int(tri[0]), loc[0], confidence, "eye opening")
    return out


def inner_lip_halfway(head: Head, hits: dict[str, Hit], surface: _Surface | None = None) -> dict[str, Hit]:
    """``hits`` with the inner lip contour's half-way points (:data:`INNER_LIP_HALVES`) where
    the standard puts them: halfway across between the midline (2.2, 2.3) and each
    corner, on the inner contour as the front view shows it.

    The points a detector gives there are its training faces' convention, not the
    standard's: the generic (ICT) head's 2.6 is 45 % of the way to the corner, and on
    MakeHuman's head the detector's came out 43 % (1.5-2.5 mm towards the midline); the
    fit then pulled the upper points 1-2 mm into the lips' crease, the lower 1-2 mm out of it.

    At each point's x, front rays scan down across the mouth, from the upper lip's outer
    contour (8.1's height) to the lower's (8.2's); each ray's first hit is on the upper lip
    or the lower (:func:`lip_sides`). The upper point is the last hit on the upper lip, the
    lower point the first hit on the lower one after it: the lips' contact line (or the
    opening's rims) as seen from the front, each on its own lip. Where a scan finds no
    such change (no lips, too few points), the points are left as they are.
    """
    found = _lips(head, hits, surface) if all(i in hits for i in ("2.2", "2.3", "8.1", "8.2")) else None
    if found is None:
        return hits
    surface, sides = found
    skin = head.parts["skin"]
    skin_index = surface.names.index("skin")
    mid_x = 0.5 * (hits["2.2"].point[0] + hits["2.3"].point[0])
    top, bottom = hits["8.1"].point[1], hits["8.2"].point[1]
    ys = np.arange(top, bottom, -_LIP_SCAN_STEP)
    z0 = surface.vertices[:, 2].max() + 0.01
    out = dict(hits)
    for corner, upper, lower in INNER_LIP_HALVES:
        if corner not in hits:
            continue
        x = 0.5 * (mid_x + hits[corner].point[0])
        o = np.c_[np.full(len(ys), x), ys, np.full(len(ys), z0)]
        tri, loc = surface.cast(o, np.tile([0.0, 0.0, -1.0], (len(ys), 1)), radius=0.0)
        lip = np.zeros(len(ys))
        on_skin = (tri >= 0) & (surface.part_of[np.maximum(tri, 0)] == skin_index)
        lip[on_skin] = np.sign(sides[skin.triangles[surface.local[tri[on_skin]]]].sum(axis=1))
        ups = np.flatnonzero(lip > 0)
        if not len(ups):
            continue
        below = np.flatnonzero(lip[ups[0]:] < 0)
        if not len(below):
            continue
        k_low = ups[0] + below[0]
        k_up = ups[ups < k_low].max()
        for i, k in ((upper, k_up), (lower, k_low)):
            if i in hits:
                out[i] = surface.hit(int(tri[k]), loc[k], hits[i].confidence, "lip contour")
    return out
