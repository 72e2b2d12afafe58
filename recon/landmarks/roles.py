"""Photos checked against their roles: a front photo shows a frontal face, a side photo a
profile, and the two are not the same picture.

Annotations given with ``--fdp`` skip detection, so nothing else would notice two photos
given the wrong way round or the same photo twice: the build would go on to a garbled head.
The face mesh tells a frontal face from a turned one by where the nose tip sits between
the face's two outer edges (:func:`turn`).
"""

from __future__ import annotations

import numpy as np

from mpeg4.errors import InputError

__all__ = ["FRONTAL", "TURNED", "turn", "check_roles"]

#: A face whose nose tip is off its edges' middle by at most this share of the face's
#: width is seen from the front; the side photo's test uses the same bound (a profile's
#: nose is at an edge, or the face mesh finds no face at all).
FRONTAL = 0.3
#: A front photo whose face is turned further than this (a three-quarter view or a
#: profile) is refused; between :data:`FRONTAL` and this it is taken with a warning:
#: booking photos and selfies are often turned a little (about 0.5 at 20 degrees).
TURNED = 0.75


def turn(image: np.ndarray) -> float | None:
    """How far the face in ``image`` is turned: the nose tip's offset from the middle of
    the face's outer edges over half their distance (0 frontal, ±1 a profile); None when
    the face mesh finds no face.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.
    """
    from .models import face_landmarks

    faces = face_landmarks(image)
    if not faces:
        return None
    lm = faces[0]
    nose, left_edge, right_edge = lm[1, 0], lm[234, 0], lm[454, 0]
    return float(((right_edge - nose) - (nose - left_edge)) / max(right_edge - left_edge, 1e-9))


def check_roles(front: np.ndarray, side: np.ndarray, front_name: str = "front photo",
                side_name: str = "side photo") -> list[str]:
    """Raise :class:`InputError` when the photos do not fit their roles.

    Parameters
    ----------
    front, side : (H, W, 3) uint8
        RGB photos as given.
    front_name, side_name : str
        Their names, for the messages.

    Returns
    -------
    list of str
        Warnings: a front photo turned a little (see :data:`TURNED`).

    Raises
    ------
    InputError
        The same picture twice; the front photo shows no face or a turned one; the side
        photo shows a frontal face. Without mediapipe only the first is checked.
    """
    from .models import MediapipeMissing

    if front.shape == side.shape and np.abs(front.astype(np.int16) - side).mean() < 2.0:
        raise InputError("the front and the side photo are the same picture", where=side_name,
                         fix="give a profile photo of the same person as the side photo")
    try:
        t_front, t_side = turn(front), turn(side)
    except MediapipeMissing:
        return []
    swapped = t_side is not None and abs(t_side) < FRONTAL and (t_front is None or abs(t_front) >= FRONTAL)
    if swapped:
        raise InputError("the side photo shows the face from the front and the front photo does not",
                         where=side_name, fix="the two photos seem given the other way round: swap them")
    if t_front is None:
        raise InputError("no face found in the front photo", where=front_name,
                         fix="give a photo of the face from the front, eyes open, the whole face in the picture")
    if abs(t_front) >= TURNED:
        raise InputError(f"the front photo shows the face turned (the nose {abs(t_front):.0%} of the way to the "
                         "face's edge)", where=front_name,
                         fix="give a photo with the face towards the camera")
    if t_side is not None and abs(t_side) < FRONTAL:
        raise InputError("the side photo shows the face from the front", where=side_name,
                         fix="give a profile photo (the head turned 90 degrees, one ear towards the camera)")
    if abs(t_front) >= FRONTAL:
        return [f"{front_name}: the face is turned a little (the nose {abs(t_front):.0%} of the way to the face's "
                "edge); the head's width and the texture's sides suffer"]
    return []
