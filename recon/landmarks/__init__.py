"""Automatic MPEG-4 feature points on a front and a side photo.

:func:`detect` places every point the two photos can show, each with a confidence in
[0, 1] and the way it was found, so that a person only corrects them
(``recon annotate`` starts from them):

- front photo (:mod:`recon.landmarks.front`): MediaPipe's face mesh and irises
  (:mod:`recon.landmarks.models`), mapped to the MPEG-4 points by a table stored as data
  (:mod:`recon.landmarks.mapping`, ``recon/data/facemesh_mpeg4.csv``); the points no face
  mesh has from the head's silhouette and colours (:mod:`recon.landmarks.colour`): the
  hairline where the skin gives way to hair up the forehead, the top of the head, the ears
  where they stand out of the head's outline; from the face's proportions when the photo
  shows nothing better;
- side photo (:mod:`recon.landmarks.side`), facing either way: the front photo's face mesh
  laid onto the profile silhouette (:mod:`recon.landmarks.profile`) and carried into the
  side photo by a second table (``recon/data/facemesh_side.csv``), the heights the front
  photo gives; then moved onto what the side photo shows (:mod:`recon.landmarks.side_parts`:
  the white of the eye, the lips, the ear's outline) and onto the profile's outline, with
  the hairline, the top and the back of the head read off it.

The models run offline from the ``mediapipe`` wheel; without it :func:`detect` raises
:class:`~recon.landmarks.models.MediapipeMissing` saying how to install it.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable

from mpeg4.io.fdp_json import FdpFile, ViewAnnotation

from .front import SOURCES, ViewPoints, detect_front
from .mapping import FpMapping, apply_mapping, load_mapping
from .models import MediapipeMissing, mediapipe_available
from .side import detect_side, facing_of
from .silhouette import head_masks

__all__ = ["detect", "detector", "detect_images", "detect_front", "detect_side", "facing_of", "ViewPoints", "SOURCES",
           "load_mapping", "apply_mapping", "FpMapping", "MediapipeMissing", "mediapipe_available"]


_METHOD = "recon.landmarks (MediaPipe face mesh + silhouettes)"  # recorded in the annotations


def detect_images(front, side, front_name: str = "front photo", side_name: str = "side photo",
                  side_facing: str | None = None) -> FdpFile:
    """:func:`detect` on (H, W, 3) uint8 RGB arrays.

    Returns
    -------
    FdpFile
        ``views["front"]`` and ``views["side"]`` with points and confidences;
        ``metadata["landmarks"]``: per view, the source of each point
        (:data:`SOURCES`; on the side photo all are ``silhouette`` or ``rule``: its points
        are the front photo's mesh placed by the side photo's silhouette), per view the
        skull points whose outline is hair (``under_hair``, :mod:`recon.shape.hair`), the side the side
        photo shows, which way it faces and how sure that is (``side_facing``, see
        :mod:`recon.landmarks.facing`), which of the eye, lips and ear the side photo was
        seen to show, the side points placed ahead of the face's outline and taken back onto
        it (``side_ahead_of_profile``), and ``warnings`` (a facing taken with some cues against it).
    side_facing : {"left", "right"}, optional
        Where the nose points in the side photo, when the user knows.
    """
    from .facing import AGREE

    if side is None:  # a front photo alone
        (front_mask,) = head_masks([front])
        f = detect_front(front, front_name, front_mask)
        view = ViewAnnotation(image=None, width=int(front.shape[1]), height=int(front.shape[0]),
                              points=dict(f.points), confidence=dict(f.confidence))
        return FdpFile(views={"front": view}, metadata={"landmarks": {
            "method": _METHOD, "source": {"front": dict(f.source)},
            "under_hair": {"front": list(f.extras.get("under_hair", []))}}})
    front_mask, side_mask = head_masks([front, side])
    f = detect_front(front, front_name, front_mask)
    s, shown = detect_side(side, f, front.shape[0], side_name, side_mask, facing=side_facing)
    facing = s.extras["facing_found"]
    views = {}
    for name, v, img, path in (("front", f, front, front_name), ("side", s, side, side_name)):
        views[name] = ViewAnnotation(image=None, width=int(img.shape[1]), height=int(img.shape[0]),
                                     points=dict(v.points), confidence=dict(v.confidence))
    meta = {"landmarks": {"method": _METHOD,
                          "side_shows": shown,
                          "side_facing": facing.record(),
                          "side_parts_seen": [k for k in ("eye", "lips", "ear") if s.extras.get(k) is not None],
                          "side_ahead_of_profile": list(s.extras.get("ahead_of_profile", [])),
                          "under_hair": {"front": list(f.extras.get("under_hair", [])),
                                         "side": list(s.extras.get("under_hair", []))},
                          "source": {"front": dict(f.source), "side": dict(s.source)}}}
    if not facing.given and (facing.confidence < AGREE or facing.against):
        meta["landmarks"]["warnings"] = [
            f"the side photo was read as {facing.describe()}; if the nose points the other way, give "
            f"--side-facing {'right' if facing.facing == 'left' else 'left'}"]
    return FdpFile(views=views, metadata=meta)


def detect(front_path: str | os.PathLike, side_path: str | os.PathLike | None, side_facing: str | None = None) -> FdpFile:
    """Feature points on a front and a side photo, with confidences.

    Parameters
    ----------
    front_path, side_path : path
        The photos (JPEG/PNG; EXIF orientation applied, as the annotation page shows them);
        ``side_path`` None for a front photo alone (only its view is returned).
    side_facing : {"left", "right"}, optional
        Where the nose points in the side photo (found when omitted).

    Returns
    -------
    FdpFile
        See :func:`detect_images`; each view's ``image`` is the path given.

    Raises
    ------
    mpeg4.errors.InputError
        A photo cannot be read, or shows no face (front) or no head (side), or the two
        look swapped; the message names the photo and the fix.
    MediapipeMissing
        mediapipe is not installed.
    """
    from recon.photos import check_photo, photo_scale, photo_size, read_photo, view_at_size

    paths = {"front": front_path, "side": side_path} if side_path is not None else {"front": front_path}
    sizes = {n: photo_size(p, f"{n} photo") for n, p in paths.items()}
    for n, size in sizes.items():
        check_photo(size, os.fspath(paths[n]))
    scale = photo_scale(sizes.values())  # a huge photo is read smaller, its points carried back
    front, side = (read_photo(paths[n], f"{n} photo", scale) if n in paths else None for n in ("front", "side"))
    fdp = detect_images(front, side, os.fspath(front_path), os.fspath(side_path or ""), side_facing)
    for n, p in paths.items():
        fdp.views[n] = view_at_size(fdp.views[n], *sizes[n])
        fdp.views[n].image = os.fspath(p)
    return fdp


def detector() -> tuple[Callable | None, str | None]:
    """:func:`detect` when the face models can be loaded, else None and why.

    A cheap check (the ``mediapipe`` package is found, not imported), for the annotation
    page and ``fmc mark`` to decide whether to offer detection.

    Returns
    -------
    detect : callable or None
        ``detect(front_path, side_path) -> FdpFile`` with per-point confidences.
    reason : str or None
        When ``detect`` is None: a short reason for the page.
    """
    if importlib.util.find_spec("mediapipe") is None:
        return None, "automatic detection needs mediapipe, which is not installed (bash install.sh installs it)"
    return detect, None
