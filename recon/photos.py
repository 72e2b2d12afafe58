"""Reading the user's photos: RGB arrays the right way up, with clear errors.

Phones store many photos sideways with an EXIF orientation tag that viewers (and the
annotation page) apply; :func:`read_photo` applies it too, so pixels marked on what the
user saw are pixels of the array. :func:`check_photo` refuses photos too small to texture
a head from. :func:`exif_focal_px` and :func:`photos_focal_px` read the lens's focal
length the camera recorded, so that close-up photos are calibrated in perspective without
the user knowing their focal length in pixels.

Photos larger than :data:`MAX_PHOTO_PIXELS` are read smaller (:func:`photo_scale`,
:func:`read_photo` with ``scale``): a 2048² texture cannot use more, and a build's memory
grows with the photos' pixels (a 12000 × 9000 photo took 9.2 GB at full size). A JPEG is
decoded at the reduced size directly (its DCT scaling), so the full size is never held in
memory; the points marked on the photo follow (:func:`view_at_size`).
"""

from __future__ import annotations

import os

import numpy as np

from mpeg4.errors import InputError, require_file

__all__ = ["MIN_PHOTO_PX", "MAX_PHOTO_PIXELS", "read_photo", "decode_photo", "photo_size", "photo_scale",
           "view_at_size", "check_photo", "exif_focal_px", "photo_focal_px",
           "photos_focal_px"]

#: Shortest side (pixels) a photo needs for a texture worth having.
MIN_PHOTO_PX = 256
#: Most pixels a photo is processed at (8 megapixels, 3264 × 2448); larger photos are read
#: smaller, both photos of a pair by the same factor.
MAX_PHOTO_PIXELS = 8_000_000
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


def _open(source, where: str, scale: float = 1.0, load: bool = True):
    """The image of a path or of bytes, as displayed, ``scale`` times its size (a JPEG
    decoded at the nearest power-of-two reduction above it, then resampled by area)."""
    import io

    from PIL import Image, ImageOps, UnidentifiedImageError

    try:
        im = Image.open(io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else source)
        orientation = im.getexif().get(0x0112, 1)
        size = im.size if orientation not in (5, 6, 7, 8) else im.size[::-1]
        target = (max(1, round(size[0] * scale)), max(1, round(size[1] * scale)))
        if scale < 1:
            stored = target if orientation not in (5, 6, 7, 8) else target[::-1]
            im.draft("RGB", stored)  # JPEG only: decode at 1/2, 1/4 or 1/8 where that still covers it
        if load:
            im.load()
    except Image.DecompressionBombError:
        raise InputError(f"the image claims more than {2 * Image.MAX_IMAGE_PIXELS} pixels, too many to read safely",
                         where=where, fix="give a photo of a sensible size (a few tens of megapixels at most)") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise InputError(f"not an image this tool can read ({e.__class__.__name__})", where=where,
                         fix="give a JPEG or PNG photo") from None
    if not load:
        return im
    im = ImageOps.exif_transpose(im)
    if im.size != target:
        im = Image.fromarray(_rgb8(im)).resize(target, Image.Resampling.BOX)
    return im


def photo_size(path: str | os.PathLike, kind: str = "photo") -> tuple[int, int]:
    """(width, height) in pixels of a photo as displayed (EXIF orientation applied), from
    its header (the pixels are not decoded)."""
    path = require_file(path, kind)
    with _open(path, path, load=False) as im:
        orientation = im.getexif().get(0x0112, 1)
        return im.size if orientation not in (5, 6, 7, 8) else im.size[::-1]


def photo_scale(sizes, max_pixels: int = MAX_PHOTO_PIXELS) -> float:
    """The factor (at most 1) that brings the largest of ``sizes`` ((width, height) pairs)
    to ``max_pixels``: one factor for the photos of a pair, so that one focal length in
    pixels still serves both."""
    largest = max(w * h for w, h in sizes)
    return min(1.0, float(np.sqrt(max_pixels / largest))) if largest > 0 else 1.0


def _rgb8(im) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a PIL image of any mode.

    Pillow's own conversion clips 16-bit and 32-bit greys to white: they are scaled here
    (16-bit data to 8 by 257, floats in [0, 1] by 255), then repeated to RGB.
    """
    if im.mode.startswith("I") or im.mode == "F":
        a = np.asarray(im, dtype=np.float64)
        if im.mode == "F" and a.size and np.nanmax(a) <= 1.0:
            a = a * 255.0
        elif im.mode != "F" and a.size and (im.mode.startswith("I;16") or np.nanmax(a) > 255):
            a = a / 257.0
        g = np.clip(np.round(np.nan_to_num(a)), 0, 255).astype(np.uint8)
        return np.repeat(g[..., None], 3, axis=2)
    return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()


def read_photo(path: str | os.PathLike, kind: str = "photo", scale: float = 1.0) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a photo as displayed (EXIF orientation applied, alpha and
    palette flattened), ``scale`` (at most 1) times its size, each side rounded."""
    path = require_file(path, kind)
    with _open(path, path, scale) as im:
        return _rgb8(im)


def decode_photo(data: bytes, where: str, kind: str = "photo") -> np.ndarray:
    """As :func:`read_photo`, from the bytes of the file (``where`` names it in errors)."""
    with _open(bytes(data), where) as im:
        return _rgb8(im)


def view_at_size(view, width: int, height: int):
    """A copy of a :class:`mpeg4.io.fdp_json.ViewAnnotation` whose points are carried onto
    the same photo at ``width`` × ``height`` pixels (pixel centres map onto pixel centres)."""
    from mpeg4.io.fdp_json import ViewAnnotation

    sx, sy = width / view.width, height / view.height
    points = {i: (np.asarray(p, float) + 0.5) * (sx, sy) - 0.5 for i, p in view.points.items()}
    return ViewAnnotation(view.image, int(width), int(height), points, dict(view.confidence))


def check_photo(image: np.ndarray | tuple[int, int], where: str, min_px: int = MIN_PHOTO_PX) -> None:
    """Refuse a photo (an image, or its (width, height)) whose shorter side is under
    ``min_px`` pixels."""
    w, h = image if isinstance(image, tuple) else image.shape[1::-1]
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


def photo_focal_px(photo: str | os.PathLike, name: str = "front photo") -> tuple[float | None, str]:
    """A photo's focal length in pixels from its EXIF (None when it records none), and
    what was found."""
    found = exif_focal_px(photo, name)
    if found is None:
        return None, f"no focal length recorded in the {name}"
    f, mm = found
    return f, f"focal length {f:.0f} px from the {name}'s EXIF ({mm:.0f} mm, 35 mm equivalent)"


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
