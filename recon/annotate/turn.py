"""Turning the side photo's points round: a profile read facing the wrong way, put right at once.

A profile read backwards puts the face's points on the back of the head (on a ponytail,
say) and the ear's on the cheek. Rather than drag thirty points across one by one, the
user turns them round: :func:`turn_side` places the side photo's points again for the
other facing, by detection told the facing (:func:`recon.landmarks.detect` with
``side_facing``) when it can run, else by mirroring the points across the head and
swapping each point for its left/right partner (the photo then shows the face's other
side). The front photo's points are left as they are.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.io.fdp_json import ViewAnnotation
from recon.landmarks.layout import visible_side

from .placement import complete_views

__all__ = ["side_facing", "mirrored_side", "turn_side"]


def side_facing(view: ViewAnnotation) -> str:
    """Where the nose points in the side photo, by the side of the face its points are
    of: ``"left"`` for the face's left side (``L`` points: the nose to the image's left)."""
    return "left" if visible_side(view.points) == "L" else "right"


def mirrored_side(view: ViewAnnotation) -> ViewAnnotation:
    """The side photo's points mirrored across the head (about the middle of their extent)
    and each left/right point given its partner's id: the same profile facing the other way.

    Parameters
    ----------
    view : ViewAnnotation
        The side photo's points, pixels.

    Returns
    -------
    ViewAnnotation
        New; confidences kept (a point's partner takes its confidence).
    """
    if not view.points:
        return ViewAnnotation(image=view.image, width=view.width, height=view.height)
    xs = np.array([p[0] for p in view.points.values()], dtype=np.float64)
    centre = 0.5 * (xs.min() + xs.max())
    points, confidence = {}, {}
    for i, p in view.points.items():
        j = FEATURE_POINTS[i].mirror or i
        points[j] = np.array([2.0 * centre - float(p[0]), float(p[1])])
        if i in view.confidence:
            confidence[j] = view.confidence[i]
    return ViewAnnotation(image=view.image, width=view.width, height=view.height, points=points,
                          confidence=confidence)


def turn_side(views: Mapping[str, ViewAnnotation], photos: Mapping[str, str | os.PathLike],
              sizes: Mapping[str, tuple[int, int]], layout: Mapping, detect: Callable | None) -> tuple[dict, dict]:
    """The annotation with the side photo's points placed again for the other facing.

    Parameters
    ----------
    views : mapping of str to ViewAnnotation
        ``front`` and ``side``, as the user has them.
    photos : mapping of str to path
        ``front`` and ``side`` photos, for detection.
    sizes : mapping of str to (width, height)
    layout : dict
        :func:`recon.annotate.placement.generic_layout`, to place what detection leaves out.
    detect : callable or None
        ``detect(front, side, side_facing=...) -> FdpFile`` (:func:`recon.landmarks.detect`);
        None: mirror the points (:func:`mirrored_side`).

    Returns
    -------
    views : dict of str to ViewAnnotation
        The front view unchanged, the side view new.
    report : dict
        ``facing`` (the new facing), ``was`` (the old), ``how`` (a few words on what placed
        the points), ``placed`` (side points placed from the generic head).
    """
    was = side_facing(views["side"])
    facing = "right" if was == "left" else "left"
    side, how = None, None
    if detect is not None:
        try:
            found = detect(os.fspath(photos["front"]), os.fspath(photos["side"]), side_facing=facing)
            side = found.views["side"]
            how = f"detected again facing {facing}"
        except (InputError, TypeError, ValueError) as e:  # detection is a help: mirror instead
            how = f"mirrored (detection failed: {e})"
    if side is None:
        side = mirrored_side(views["side"])
        how = how or "mirrored across the head"
    side = ViewAnnotation(image=views["side"].image, width=sizes["side"][0], height=sizes["side"][1],
                          points=dict(side.points), confidence=dict(side.confidence))
    filled, report = complete_views({"front": views["front"], "side": side}, sizes, layout)
    filled["front"] = views["front"]
    return filled, {"facing": facing, "was": was, "how": how, "placed": report["side"]["placed"]}
