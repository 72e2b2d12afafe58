"""Where the generic head's feature points lie in a front and a side photo.

Both the automatic detection (:mod:`recon.landmarks`) and the annotation page
(:mod:`recon.annotate`) start from this layout: which points each photo can show, which
side a side photo shows, and the generic head's points as an orthographic front and side
camera see them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS

__all__ = ["shown_in", "visible_side", "generic_layout"]


def shown_in(view: str, side: str = "L") -> list[str]:
    """Ids of the feature points a photo can show, in catalogue order.

    Parameters
    ----------
    view : {"front", "side"}
    side : {"L", "R"}
        The side of the face a side photo shows.

    Examples
    --------
    >>> len(shown_in("front")), "6.1" in shown_in("front"), "3.6" in shown_in("side")
    (72, False, False)
    """
    if view == "front":
        return [i for i in FP_IDS if FEATURE_POINTS[i].front != "N"]
    if view == "side":
        return [i for i in FP_IDS if FEATURE_POINTS[i].side_view != "N" and FEATURE_POINTS[i].side in ("C", side)]
    raise ValueError(f"unknown view {view!r}")


def visible_side(points: Mapping[str, object]) -> str:
    """``"L"`` or ``"R"``: the face's side a side photo shows, by the majority of its labels.

    The same rule as :func:`recon.shape.calibrate.calibrate`; ``"L"`` when undecided.
    """
    labels = [FEATURE_POINTS[i].side for i in points if i in FEATURE_POINTS]
    return "R" if labels.count("R") > labels.count("L") else "L"


def generic_layout(head=None) -> dict[str, dict[str, np.ndarray]]:
    """The generic head's feature points as an orthographic front and side camera see them.

    Parameters
    ----------
    head : mpeg4.Head, optional
        The shipped generic head by default.

    Returns
    -------
    dict
        ``"front"``: FP id → (2,) metres, (x, −y), image axes (x right, y down; the face's
        left on the image's right). ``"side"``: FP id → (2,) metres, (−z, −y): the left
        side seen from the face's left with the nose towards the image's left (a right
        side photo is the mirror image, which :func:`fit_view` finds).
    """
    if head is None:
        # The stored positions alone: decoding the whole head would double the tool's start-up.
        from mpeg4.generic_head import generic_feature_points

        pts = generic_feature_points()
    else:
        pts = head.fp_positions()
    return {"front": {i: np.array([p[0], -p[1]]) for i, p in pts.items()},
            "side": {i: np.array([-p[2], -p[1]]) for i, p in pts.items()}}
