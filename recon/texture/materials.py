"""Textures for the parts a photo cannot show: eyes, teeth, gums and tongue.

Made here, procedurally: the eye with the iris and sclera colours the photos give
(:func:`iris_colour` samples the iris around the pupils, :func:`sclera_colour` the white
between the iris and the eye's corners), teeth with their enamel gradient and
gaps, gums and tongue with a soft mottle (:func:`mouth_albedo` picks a mouth part's by its
name). :func:`planar_uv` gives such a part texture
coordinates by projecting it along the viewing axis onto its bounding box.
"""

from __future__ import annotations

import numpy as np

from mpeg4.errors import InputError

__all__ = ["IRIS_DEG", "PUPIL_SHARE", "GUM_RGB", "TONGUE_RGB", "SCLERA_RGB", "SCLERA_MAX_CHROMA", "eye_texture", "eye_uv",
           "iris_colour", "sclera_colour",
           "teeth_texture", "mottled_texture", "mouth_albedo", "planar_uv"]

#: Angular radius of the iris seen from the eyeball's centre (about 6 mm on a 15.8 mm
#: eyeball), and the pupil's share of the iris (a third, as in the MPEG-4 neutral face).
IRIS_DEG, PUPIL_SHARE = 22.0, 1.0 / 3.0
#: Base colours (RGB in [0, 1]) of the gums with the palate, and of the tongue.
GUM_RGB, TONGUE_RGB = (0.80, 0.42, 0.45), (0.85, 0.45, 0.45)


#: The sclera's colour when a photo does not show it (RGB, 0..255).
SCLERA_RGB = (236, 232, 226)
#: Chroma over luma at which a colour is too coloured for the white of an eye: the
#: sclera's is about a tenth, skin's (its melanin and blood) a third to a half and more.
SCLERA_MAX_CHROMA = 0.3


def eye_texture(size: int = 256, iris_rgb=(92, 64, 40), sclera_rgb=SCLERA_RGB) -> np.ndarray:
    """(size, size, 3) uint8 eye texture: sclera, iris with radial fibres and a darker limbal
    ring, black pupil, centred; the corners are sclera (the eye's back).

    Parameters
    ----------
    size : int
        Pixels per side.
    iris_rgb, sclera_rgb : (3,) int
        The iris's and the sclera's colours, 0..255.
    """
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size - 0.5
    r = np.hypot(x, y) * 2  # 1 at the texture's edge, which maps to the eyeball's equator
    iris_r = np.sin(np.radians(IRIS_DEG))
    angle = np.arctan2(y, x)
    fibres = 0.85 + 0.15 * np.sin(angle * 47) * np.sin(angle * 13 + 3 * r / iris_r)
    img = np.empty((size, size, 3))
    img[:] = sclera_rgb
    iris = r < iris_r
    shade = np.clip(1.15 - 0.6 * (r / iris_r) ** 4, 0.5, 1.2) * fibres
    img[iris] = np.asarray(iris_rgb, float) * shade[iris, None]
    img[r < iris_r * PUPIL_SHARE] = (12, 10, 10)
    return np.clip(img, 0, 255).astype(np.uint8)


def eye_uv(vertices: np.ndarray, centre: np.ndarray, gaze: np.ndarray) -> np.ndarray:
    """(N, 2) texture coordinates of an eyeball for :func:`eye_texture`: the front
    hemisphere projected along the gaze onto the texture's disc.

    Parameters
    ----------
    vertices : (N, 3) float
        Metres.
    centre : (3,) float
        The eyeball's rotation centre.
    gaze : (3,) float
        Direction of the gaze (need not be unit).
    """
    g = np.asarray(gaze, float) / np.linalg.norm(gaze)
    e1 = np.cross([0.0, 1.0, 0.0], g)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(g, e1)
    d = np.asarray(vertices, float) - centre
    radius = np.linalg.norm(d, axis=1).max()
    uv = 0.5 + 0.5 * np.c_[d @ e1, d @ e2] / radius
    uv[d @ g < 0] = 0.02  # the back of the eye: a sclera corner
    return uv


def iris_colour(photo: np.ndarray, pupil_px: np.ndarray, iris_radius_px: float) -> np.ndarray:
    """(3,) float RGB of an iris: the median of the ring between pupil and limbus.

    Parameters
    ----------
    photo : (H, W, 3) uint8
    pupil_px : (2,) float
        Pixel (x, y) of the pupil's centre (FP 3.5 or 3.6).
    iris_radius_px : float
        Radius of the iris in pixels (half of IRISD0 seen in the photo is a good value).

    Notes
    -----
    The ring's inner half is skipped (the pupil and its catch-light), as are the darkest
    and brightest tenth of its pixels (lashes, reflections).
    """
    h, w = photo.shape[:2]
    r = max(float(iris_radius_px), 1.5)
    x0, y0 = np.asarray(pupil_px, float)
    if not (0 <= x0 < w and 0 <= y0 < h):
        raise InputError(f"the pupil at ({x0:.1f}, {y0:.1f}) lies outside the {w}x{h} photo",
                         where="iris colour", fix="check the pupil feature points 3.5 and 3.6")
    ys, xs = np.mgrid[max(0, int(y0 - r - 1)):min(h, int(y0 + r + 2)), max(0, int(x0 - r - 1)):min(w, int(x0 + r + 2))]
    d = np.hypot(xs - x0, ys - y0)
    ring = (d >= 0.5 * r) & (d <= 0.9 * r)
    pix = photo[ys[ring], xs[ring]].astype(np.float64)
    if len(pix) < 4:
        raise InputError(f"the iris around ({x0:.1f}, {y0:.1f}) covers too few pixels", where="iris colour",
                         fix="use a larger photo")
    lum = pix @ [0.299, 0.587, 0.114]
    lo, hi = np.quantile(lum, [0.1, 0.9])
    keep = (lum >= lo) & (lum <= hi)
    return np.median(pix[keep] if keep.sum() >= 3 else pix, axis=0)


def sclera_colour(photo: np.ndarray, pupil_px: np.ndarray, corners_px, iris_radius_px: float) -> np.ndarray | None:
    """(3,) float RGB of the white of an eye: the median of the photo between the iris and
    the eye's corners, or None when the photo shows too little of it.

    Parameters
    ----------
    photo : (H, W, 3) uint8
    pupil_px : (2,) float
        Pixel (x, y) of the pupil's centre.
    corners_px : sequence of (2,) float
        The eye's corners (3.7 and 3.11, or 3.8 and 3.12), pixels.
    iris_radius_px : float

    Notes
    -----
    Along each line from the pupil to a corner, the pixels from a quarter of the iris
    radius outside the iris up to four fifths of the way to the corner, within a fifth of
    the radius of the line. Of those, the less coloured half (the lids' skin and the
    corner's caruncle are pink or brown, the white is nearly grey), and of that the
    brighter half but the brightest 5 % (lashes and the lids' shadow are dark, reflections
    bright). A colour whose chroma (its largest channel less its smallest) is
    :data:`SCLERA_MAX_CHROMA` of its luma or more is skin, not the white (lowered lids):
    None.
    """
    h, w = photo.shape[:2]
    r = max(float(iris_radius_px), 1.5)
    p0 = np.asarray(pupil_px, float)
    picked = []
    for c in corners_px:
        d = np.asarray(c, float) - p0
        length = float(np.linalg.norm(d))
        if length < 1.5 * r:
            continue
        u = d / length
        n = np.array([-u[1], u[0]])
        for s in np.arange(1.25 * r, 0.8 * length, 0.5):
            for o in np.arange(-0.2 * r, 0.2 * r + 1e-9, 0.5):
                x, y = p0 + s * u + o * n
                if 0 <= x < w and 0 <= y < h:
                    picked.append(photo[int(y), int(x)])
    if len(picked) < 6:
        return None
    pix = np.asarray(picked, np.float64)
    chroma = pix.max(axis=1) - pix.min(axis=1)
    pix = pix[chroma <= np.median(chroma)]
    lum = pix @ [0.299, 0.587, 0.114]
    lo, hi = np.quantile(lum, [0.5, 0.95])
    keep = (lum >= lo) & (lum <= hi)
    white = np.median(pix[keep] if keep.sum() >= 3 else pix, axis=0)
    y = float(white @ [0.299, 0.587, 0.114])
    return white if y > 0 and np.ptp(white) < SCLERA_MAX_CHROMA * y else None


def teeth_texture(size: int = 128, seed: int = 0) -> np.ndarray:
    """(size, size, 3) uint8 teeth: enamel lighter at the biting edge (top of the texture
    is the gum line), faint vertical gaps between teeth, slight mottle."""
    rng = np.random.default_rng(seed)
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    base = np.array([236.0, 230, 212])
    gum_line = np.array([214.0, 196, 170])
    t = np.clip(y * 1.4, 0, 1)[..., None]
    img = gum_line * (1 - t) + base * t
    gaps = 1 - 0.12 * np.exp(-((np.sin(np.pi * x * 8)) ** 2) / 0.004)
    img *= gaps[..., None]
    img *= (1 + 0.02 * rng.standard_normal((size, size)))[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def mottled_texture(rgb, size: int = 128, seed: int = 0, amount: float = 0.06) -> np.ndarray:
    """(size, size, 3) uint8 of one colour with a soft mottle (gums, tongue)."""
    import cv2

    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), size / 40)
    noise /= max(float(np.abs(noise).max()), 1e-9)
    img = np.asarray(rgb, float)[None, None] * (1 + amount * noise)[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def mouth_albedo(part: str, size: int = 128, seed: int = 0) -> np.ndarray:
    """(size, size, 3) uint8 material of a mouth part by its name: :func:`teeth_texture`
    for ``teeth_*``, the gums' (``gums_*``) or the tongue's colour mottled
    (:func:`mottled_texture`) otherwise. The top row lies at the top of the part seen from
    the front (:func:`planar_uv`)."""
    if part.startswith("teeth"):
        return teeth_texture(size, seed)
    rgb = TONGUE_RGB if part.startswith("tongue") else GUM_RGB
    return mottled_texture(np.asarray(rgb) * 255, size, seed)


def planar_uv(vertices: np.ndarray, axes: tuple[int, int] = (0, 1)) -> np.ndarray:
    """(N, 2) texture coordinates by projection onto two axes, scaled to the part's box.

    Parameters
    ----------
    vertices : (N, 3) float
    axes : (int, int)
        The axes giving s and t (default x and y: a front projection).
    """
    v = np.asarray(vertices, float)[:, list(axes)]
    lo, hi = v.min(axis=0), v.max(axis=0)
    return 0.02 + 0.96 * (v - lo) / np.maximum(hi - lo, 1e-12)
