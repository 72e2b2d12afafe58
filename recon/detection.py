"""Feature points detected for a build when none are given: written where a person can
correct them, and never over points a person reviewed.

``recon build FRONT SIDE -o OUT`` and a ``recon batch`` row without annotations call
:func:`detect_annotations`; their messages say how to correct the points
(:func:`correction_hint`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from mpeg4.errors import InputError

__all__ = ["DETECTED_NAME", "detect_annotations", "detect_for_build", "correction_hint"]


#: Where ``recon build`` without annotations writes the points it detected, in its output.
DETECTED_NAME = "annotations.fdp.json"


def detect_annotations(front: str | os.PathLike, side: str | os.PathLike | None, path: str | os.PathLike,
                       detect: Callable | None = None, side_facing: str | None = None,
                       where: str = "recon build") -> Path:
    """Feature points detected on two photos, written to ``path`` marked unreviewed.

    Parameters
    ----------
    front, side : path
        The photos; ``side`` None for a front photo alone.
    path : path
        Where the annotations go (``"reviewed": false`` in their metadata, so that the
        build drops points whose heights disagree instead of failing; see
        :func:`recon.shape.fit.fit_head`). A file there that a person reviewed (saved
        by ``recon annotate``) is never replaced: that is an error saying to build with it.
    detect : callable, optional
        ``detect(front, side) -> FdpFile``; :func:`recon.landmarks.detect` by default.
    side_facing : {"left", "right"}, optional
        Where the nose points in the side photo (:func:`recon.landmarks.detect`).
    where : str
        Who asks, for the messages.

    Returns
    -------
    Path
        ``path``.
    """
    from mpeg4.errors import require_file
    from mpeg4.io import read_fdp_json, write_fdp_json
    from mpeg4.io.fdp_json import FdpFile

    path = Path(path)
    if path.exists():
        try:
            reviewed = read_fdp_json(path).metadata.get("reviewed") is not False
        except InputError:
            reviewed = True  # not ours to replace
        if reviewed:
            raise InputError(f"{path} holds points a person placed or checked", where=where,
                             fix=f"build with them: recon build {front} {side} --fdp {path} -o ...; or move the "
                                 "file away to detect the points again")
    front = require_file(front, "front photo")
    side = require_file(side, "side photo") if side is not None else None
    if detect is None:
        from .landmarks import detector

        detect, why = detector()
        if detect is None:
            raise InputError(f"no annotations were given and {why}", where=where,
                             fix="mark the points with recon annotate FRONT SIDE and build with --fdp F.fdp.json")
        found = detect(front, side, side_facing=side_facing)
    else:
        found = detect(front, side)
    if not isinstance(found, FdpFile):
        raise TypeError(f"automatic detection returned {type(found).__name__}, not an FdpFile")
    for name, photo in (("front", front), ("side", side)):
        if photo is None:
            continue
        if name not in found.views or not found.views[name].points:
            raise InputError(f"automatic detection found no feature points on the {name} photo", where=photo,
                             fix="check that the photo shows the face, or mark the points with recon annotate")
        found.views[name].image = photo
    found.metadata = dict(found.metadata, reviewed=False, source="automatic detection (recon.landmarks)")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_fdp_json(path, found)
    return path


def detect_for_build(front, side, path, side_facing: str | None = None,
                     say: Callable[[str], None] = lambda m: None) -> tuple[Path, object, str | None]:
    """:func:`detect_annotations` for ``recon build``: a side photo whose edge cuts the
    face's profile off (:class:`recon.landmarks.side.ProfileCutOff`) gives no shape, so it
    is left out with a warning and the points detected on the front photo alone.

    Returns
    -------
    path : Path
        The annotations written.
    side : path or None
        The side photo still used (None once left out).
    unused : str or None
        Why the side photo was left out (None when it was not).
    """
    from .landmarks.side import ProfileCutOff

    try:
        return detect_annotations(front, side, path, side_facing=side_facing), side, None
    except ProfileCutOff as e:
        if side is None:
            raise
        say(f"warning: {e} -- the side photo is not used: the head is built from the front photo alone, "
            f"its depth estimated")
        return detect_annotations(front, None, path), None, str(e)


def correction_hint(front, side, fdp_path) -> str:
    """How to correct detected points and build again."""
    if side is None:  # the page shows two photos: a front photo alone is corrected in the file
        return (f"check them in {fdp_path} (pixels per point on the front photo; the annotation page needs a side "
                f"photo too: recon annotate {front} SIDE --fdp {fdp_path}), then build again with --fdp {fdp_path}")
    return (f"check and correct them with: recon annotate {front} {side} --fdp {fdp_path}, then build again with "
            f"--fdp {fdp_path}")
