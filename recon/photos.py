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
#: EXIF tags: the Exif sub-IFD; the focal length in 35 mm film terms; the focal length
#: (mm), the sensor's resolution and its unit, the recorded image width.
_EXIF_IFD, _FOCAL_35MM = 0x8769, 0xA405
_FOCAL_MM, _PLANE_X_RES, _PLANE_UNIT, _PIXEL_X = 0x920A, 0xA20E, 0xA210, 0xA002
#: Millimetres per FocalPlaneResolutionUnit: inch (2), centimetre (3), and the
#: millimetre (4) and micrometre (5) some cameras write.
_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 1e-3}


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

    Two ways, the first that the photo records:

    - ``FocalLength`` (mm) times the sensor's ``FocalPlaneXResolution`` (pixels per inch,
      cm or mm), rescaled from the recorded ``PixelXDimension`` to the photo's width: exact
      for an uncropped photo at any size;
    - ``FocalLengthIn35mmFilm``, relative to the diagonal of a 36 × 24 mm frame:
      ``f_px = f35 / 43.27 mm × the photo's diagonal in pixels`` (what phones record).

    A cropped photo keeps the tags but not the field of view; such photos need ``--focal``.

    Returns
    -------
    (focal_px, focal_35mm) or None
        ``focal_35mm`` as recorded, or as the first way implies; None when the photo
        records neither.
    """
    from PIL import Image, UnidentifiedImageError

    path = require_file(path, kind)
    try:
        with Image.open(path) as im:  # as stored: the sensor's axes
            exif = im.getexif()
            ifd = dict(exif.get_ifd(_EXIF_IFD))
            stored_w, stored_h = im.size
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise InputError(f"not an image this tool can read ({e.__class__.__name__})", where=path,
                         fix="give a JPEG or PNG photo") from None
    w, h = stored_w, stored_h  # the diagonal does not turn with the EXIF orientation

    def number(tag):
        try:
            v = float(ifd[tag])
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            return None
        return v if np.isfinite(v) and v > 0 else None

    diagonal = float(np.hypot(w, h))
    focal, res, unit = number(_FOCAL_MM), number(_PLANE_X_RES), ifd.get(_PLANE_UNIT, 2)
    if focal is not None and res is not None and unit in _UNIT_MM:
        px_per_mm = res / _UNIT_MM[unit]
        width = number(_PIXEL_X)  # the sensor's x is the stored image's width
        if width is not None:
            px_per_mm *= stored_w / width
        f = focal * px_per_mm
        return f, f / diagonal * FILM_DIAGONAL_MM
    f35 = number(_FOCAL_35MM)
    if f35 is None:
        return None
    return f35 / FILM_DIAGONAL_MM * diagonal, f35


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
        return None, (f"the photos record different focal lengths ({a:.0f} and {b:.0f} mm, 35 mm equivalent): "
                      f"orthographic cameras (give --focal)")
    f = 0.5 * (f1 + f2)
    return f, f"focal length {f:.0f} px from the photos' EXIF ({a:.0f} mm, 35 mm equivalent)"
