"""Reading the user's photos: RGB arrays the right way up, with clear errors.

Phones store many photos sideways with an EXIF orientation tag that viewers (and the
annotation page) apply; :func:`read_photo` applies it too, so pixels marked on what the
user saw are pixels of the array. :func:`check_photo` refuses photos too small to texture
a head from. :func:`exif_focal_px` and :func:`photos_focal_px` read the lens's focal
length the camera recorded, so that close-up photos are calibrated in perspective without
the user knowing their focal length in pixels.
"""

from __future__ import annotations

import os

import numpy as np

from mpeg4.errors import InputError, require_file

__all__ = ["MIN_PHOTO_PX", "read_photo", "photo_size", "check_photo", "exif_focal_px", "photos_focal_px"]

#: Shortest side (pixels) a photo needs for a texture worth having.
MIN_PHOTO_PX = 256
#: Diagonal of a 35 mm film frame (36 × 24 mm), millimetres: what "35 mm equivalent"
#: focal lengths are relative to.
FILM_DIAGONAL_MM = 43.2666
#: EXIF tags: the Exif sub-IFD, and the focal length in 35 mm film terms.
_EXIF_IFD, _FOCAL_35MM = 0x8769, 0xA405


def _open(path: str | os.PathLike, kind: str):
    from PIL import Image, ImageOps, UnidentifiedImageError

    path = require_file(path, kind)
    try:
        im = Image.open(path)
        im.load()
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise InputError(f"not an image this tool can read ({e.__class__.__name__})", where=path,
                         fix="give a JPEG or PNG photo") from None
    return ImageOps.exif_transpose(im)


def photo_size(path: str | os.PathLike, kind: str = "photo") -> tuple[int, int]:
    """(width, height) in pixels of a photo as displayed (EXIF orientation applied)."""
    with _open(path, kind) as im:
        return im.size


def read_photo(path: str | os.PathLike, kind: str = "photo") -> np.ndarray:
    """(H, W, 3) uint8 RGB of a photo as displayed (EXIF orientation applied, alpha and
    palette flattened)."""
    with _open(path, kind) as im:
        return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()


def check_photo(image: np.ndarray, where: str, min_px: int = MIN_PHOTO_PX) -> None:
    """Refuse a photo whose shorter side is under ``min_px`` pixels."""
    h, w = image.shape[:2]
    if min(h, w) < min_px:
        raise InputError(f"the photo is only {w}x{h} pixels", where=where,
                         fix=f"use a photo at least {min_px} pixels on its shorter side (the head should fill "
                             f"most of it)")


def exif_focal_px(path: str | os.PathLike, kind: str = "photo") -> tuple[float, float] | None:
    """The focal length a camera recorded in a photo's EXIF, in pixels of the photo.

    From the 35 mm equivalent focal length (EXIF ``FocalLengthIn35mmFilm``), which is
    relative to the diagonal of a 36 × 24 mm frame, so it holds for the photo at any
    resolution: ``f_px = f35 / 43.27 mm × the photo's diagonal in pixels``. A cropped
    photo keeps the tag but not the field of view; such photos need ``--focal``.

    Returns
    -------
    (focal_px, focal_35mm) or None
        None when the photo records no 35 mm equivalent focal length.
    """
    with _open(path, kind) as im:
        try:
            f35 = im.getexif().get_ifd(_EXIF_IFD).get(_FOCAL_35MM)
        except (AttributeError, KeyError, TypeError, ValueError):
            return None
        w, h = im.size
    try:
        f35 = float(f35)
    except (TypeError, ValueError):
        return None
    if not np.isfinite(f35) or f35 <= 0:
        return None
    return f35 / FILM_DIAGONAL_MM * float(np.hypot(w, h)), f35


def photos_focal_px(front: str | os.PathLike, side: str | os.PathLike) -> tuple[float | None, str]:
    """One focal length for both photos of a pair from their EXIF, and what was found.

    Returns
    -------
    focal_px : float or None
        The mean of the two photos' focal lengths in pixels when both record one and they
        agree within 5 %; None otherwise (orthographic cameras).
    note : str
        What was used, for the user.
    """
    found = {n: exif_focal_px(p, f"{n} photo") for n, p in (("front", front), ("side", side))}
    if all(v is None for v in found.values()):
        return None, "no focal length recorded in the photos: orthographic cameras (give --focal for close-ups)"
    if any(v is None for v in found.values()):
        which = next(n for n, v in found.items() if v is None)
        return None, (f"only one photo records its focal length (not the {which} photo): orthographic cameras "
                      f"(give --focal)")
    (f1, a), (f2, b) = found["front"], found["side"]
    if abs(f1 - f2) > 0.05 * max(f1, f2):
        return None, (f"the photos record different focal lengths ({a:g} and {b:g} mm, 35 mm equivalent): "
                      f"orthographic cameras (give --focal)")
    f = 0.5 * (f1 + f2)
    return f, f"focal length {f:.0f} px from the photos' EXIF ({a:g} mm, 35 mm equivalent)"
