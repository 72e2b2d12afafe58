"""Reading the user's photos: RGB arrays the right way up, with clear errors.

Phones store many photos sideways with an EXIF orientation tag that viewers (and the
annotation page) apply; :func:`read_photo` applies it too, so pixels marked on what the
user saw are pixels of the array. :func:`check_photo` refuses photos too small to texture
a head from.
"""

from __future__ import annotations

import os

import numpy as np

from mpeg4.errors import InputError, require_file

__all__ = ["MIN_PHOTO_PX", "read_photo", "photo_size", "check_photo"]

#: Shortest side (pixels) a photo needs for a texture worth having.
MIN_PHOTO_PX = 256


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
