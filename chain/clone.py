"""Cloning onto any head mesh: its feature points read from its ``fdp.json``, or detected."""

from __future__ import annotations

import os

from mpeg4.head import Head

__all__ = ["target_head", "clone_onto"]


def target_head(path, detect=None, progress=None, parts=None) -> tuple[Head, list[str]]:
    """A clone target with feature points, and warnings about them.

    The head as :func:`mpeg4.io.load_head` reads it (a GLB of this project, or a mesh with
    its ``<stem>.fdp.json`` beside it); a head without the points cloning needs is marked
    first by :func:`recon.mark.mark` (nothing is written).

    Parameters
    ----------
    path : path
        GLB, glTF, OBJ or PLY.
    detect : callable, optional
        Passed to :func:`recon.mark.mark`.
    progress : callable, optional
    parts : mapping of str to str or None, optional
        Roles of the mesh's parts a person gives, for a mesh that is marked here
        (:func:`recon.mark.given_parts`); a head with its feature points keeps its own parts,
        and giving roles then is an error.

    Returns
    -------
    head : Head
    warnings : list of str
        Points detected here, or saved by ``fmc mark`` and never reviewed, say so.
    """
    from fmc.clone import REQUIRED_FPS
    from mpeg4.io import load_head

    head = load_head(path)
    name = os.path.basename(os.fspath(path))
    if all(i in head.feature_points for i in REQUIRED_FPS):
        if parts:
            from mpeg4.errors import InputError

            raise InputError("--part names the parts of a mesh that is marked here, but this head has its feature "
                             "points and parts already", where=name,
                             fix=f"mark it again with its parts named: fmc mark {name} --part ROLE=PART, then clone")
        info = head.metadata.get("mark3d") if isinstance(head.metadata.get("mark3d"), dict) else None
        if info is not None and info.get("reviewed") is False:
            return head, [f"the feature points of {name} were detected automatically and not reviewed "
                          f"(check them: recon annotate {name})"]
        return head, []
    from recon.mark import mark

    result = mark(path, detect=detect, progress=progress, parts=parts)
    warnings = [f"{name} has no feature points: they were detected automatically and are unreviewed "
                f"(save them with fmc mark {name}, check them with recon annotate {name})"]
    return result.head, (warnings + [f"{name}: {w}" for w in result.warnings]
                         + [f"{name}: unreliable points: {p.message}" for p in result.problems])


def clone_onto(source, target, detect=None, progress=None, parts=None, **options) -> tuple[Head, list[str]]:
    """:func:`fmc.clone.clone` of a head file onto another, marking the target if needed.

    ``source`` is read by :func:`fmc.heads.animated_head` (``None`` or ``"generic"``: the
    generic head with its tables).

    ``parts`` goes to :func:`target_head`; ``options`` to :func:`fmc.clone.clone` (``antialias``,
    ``triangulation``, ``alignment``).

    Returns
    -------
    head : Head
        The target with the source's motion.
    warnings : list of str
    """
    from fmc.clone import clone
    from fmc.heads import animated_head

    tgt, warnings = target_head(target, detect=detect, progress=progress, parts=parts)
    head, more = clone(animated_head(source), tgt, **options)
    return head, warnings + more
