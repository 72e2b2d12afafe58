"""A head with its motion, by name: the generic head by default, or a head file with its
animation tables in it or stored beside it (``fmc play``, ``fmc say``, ``fmc clone``)."""

from __future__ import annotations

import os

from mpeg4.head import Head

__all__ = ["GENERIC", "animated_head"]

#: The name that stands for the generic head with its Facial Animation Tables.
GENERIC = "generic"


def animated_head(source: str | os.PathLike | None = None) -> Head:
    """A head with its motion (morph targets, Facial Animation Tables).

    ``None`` or ``"generic"``: the generic head with its Facial Animation Tables. A head
    file: as :func:`mpeg4.io.load_head` reads it, with the tables stored beside it as
    ``<stem>_fat.npz`` when the file itself carries none (the generic head's GLB keeps its
    tables so).
    """
    from mpeg4.io import load_head

    if source is None or os.fspath(source) == GENERIC:
        from mpeg4.generic_head import load_generic_head

        return load_generic_head(with_fat=True)
    head = load_head(source)
    beside = os.path.splitext(os.fspath(source))[0] + "_fat.npz"
    if (head.fat is None or not len(head.fat)) and os.path.isfile(beside):
        from mpeg4.io.fat_npz import read_fat_npz

        head.fat = read_fat_npz(beside)
    return head
