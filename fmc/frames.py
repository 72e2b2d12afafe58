"""What one frame's FAP values are played as, by every player of this project.

The values a stream gives go through three steps before the tables are applied (the
fast :class:`fmc.play.Player` and the GLB animations of :mod:`fmc.animate` alike, so
they show the same face):

1. a lip FAP set without its inner/outer partner gives it its value
   (:func:`mpeg4.io.fap.fill_lip_contours`);
2. the limits a face has (:class:`fmc.limits.Limits`), unless switched off;
3. the lip FAPs lose what the jaw FAPs already do to their points
   (:class:`fmc.decouple.Decoupler`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping

from mpeg4.head import Head
from mpeg4.io.fap import fill_lip_contours

from .decouple import Decoupler
from .limits import Limits

__all__ = ["FrameDecoder"]


class FrameDecoder:
    """Frame values → the values the tables are played at.

    Parameters
    ----------
    head : Head
        With ``head.fat``.
    limits : bool
        Apply :class:`fmc.limits.Limits` (``fmc play --no-limits`` switches them off).

    Attributes
    ----------
    clamped : collections.Counter
        Phrase → number of frames in which that limit acted, since construction.
    """

    def __init__(self, head: Head, limits: bool = True):
        self.decouple = Decoupler(head)
        self.limits = Limits(head) if limits else None
        self.clamped: Counter = Counter()

    def __call__(self, values: Mapping) -> dict:
        values = fill_lip_contours(values)
        if self.limits is not None:
            values, changed = self.limits(values)
            self.clamped.update(changed)
        return self.decouple(values)
