"""Feature points the renders cannot show: from the generic head fitted to the surface.

:func:`fitted_points` fits the generic head's skin to the mesh, following the points found
on it, and takes the points a grey render can only guess from the fit;
:func:`hidden_points` places those no view shows and no fit reached (teeth, tongue).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import Head
from recon.shape.deform import fit_similarity

from .lift import Hit, _Surface

__all__ = ["fitted_points", "hidden_points"]


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
