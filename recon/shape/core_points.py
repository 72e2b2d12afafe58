"""The face's core feature points: the eyes, nose, mouth and chin.

The face mesh finds them on both photos to a millimetre or two of each other; an
automatic route never leaves them out (:mod:`recon.shape.calibrate`), and a head's turn in
the front photo is read from them (:mod:`recon.shape.turn`).
"""

from __future__ import annotations

from mpeg4.catalogue import FEATURE_POINTS

__all__ = ["CORE_GROUPS", "is_core"]

#: The face's core: eyes, nose, mouth and chin (groups 3, 8, 9 and 2.1-2.10; the jaw's
#: contour 2.11-2.14 is not: the side photo shows it under the ear and the hair). Their
#: heights are found by the face mesh on both photos; when they disagree the photos or
#: the cameras are wrong, and dropping points would hide it.
CORE_GROUPS = (2, 3, 8, 9)
_NOT_CORE = ("2.11", "2.12", "2.13", "2.14")


def is_core(fp_id: str) -> bool:
    """Whether a point belongs to the face's core (eyes, nose, mouth, chin), which an
    automatic route never leaves out."""
    return FEATURE_POINTS[fp_id].group in CORE_GROUPS and fp_id not in _NOT_CORE
