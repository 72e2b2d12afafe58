"""A built head made animatable: a source head's motion cloned onto it.

The step where the photo side hands over to the motion side, so it lives here, above both:
:mod:`recon.batch` knows nothing of :mod:`fmc` and receives :func:`clone_step` as a plain
function (``recon batch`` passes it; it pickles by reference, so it travels to local worker
processes and to Dask workers alike).
"""

from __future__ import annotations

import functools
import os

from mpeg4.head import Head
from recon.batch import GENERIC_SOURCE

__all__ = ["GENERIC_SOURCE", "clone_step", "load_source"]


@functools.lru_cache(maxsize=2)
def load_source(source: str = GENERIC_SOURCE) -> Head:
    """The head whose motion is cloned: ``"generic"`` for the generic head with its
    Facial Animation Tables, or a head file (:func:`fmc.heads.animated_head`).

    Kept per process (at most two sources), so a long batch reads each source once and a
    worker's memory does not grow with the number of heads.
    """
    from fmc.heads import animated_head

    return animated_head(source)


def clone_step(head: Head, source: str | os.PathLike = GENERIC_SOURCE) -> tuple[Head, list[str]]:
    """``head`` with the motion of ``source`` cloned onto it (:func:`fmc.clone.clone`).

    Parameters
    ----------
    head : Head
        A head with feature points (a ``recon build`` result).
    source : str or path
        ``"generic"`` or a head file; see :func:`load_source`.

    Returns
    -------
    head : Head
        The animatable head (morph targets and Facial Animation Tables).
    warnings : list of str
        What the cloning could not carry over.
    """
    from fmc.clone import clone

    return clone(load_source(os.fspath(source)), head)
