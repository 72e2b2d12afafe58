"""The eye, the mouth's corner and the ear in a side photo, near where they are expected.

The profile fit (:mod:`recon.landmarks.profile`) puts the points off the profile where the
front photo's face mesh says they are, and the mesh's depth is its weakest part: a whole
eye, mouth or ear comes out a few millimetres too far forward or back, each by its own
amount. These functions look for the part itself in the photo, in a window around where
it is expected, so that its points can be moved together:

- the eye: the white of the eye, brighter and greyer than the skin around it
  (:func:`eye_white`);
- the mouth: the lips, redder than the skin (:func:`lip_region`), whose rearmost point is
  the corner of the mouth;
- the ear: the ear's rim, the strongest edges of the skin between the cheek and the hair
  (:func:`ear_box`).

All work on the photo turned nose-left, and on its colours from
:func:`recon.landmarks.colour.to_lab` (chroma divided by lightness, so that shade matters
less).
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["eye_white", "lip_region", "ear_box"]


def _window(shape, centre, half_w: float, half_h: float) -> tuple[slice, slice]:
    h, w = shape[:2]
    x0, x1 = int(max(0, centre[0] - half_w)), int(min(w, centre[0] + half_w + 1))
    y0, y1 = int(max(0, centre[1] - half_h)), int(min(h, centre[1] + half_h + 1))
    return slice(y0, y1), slice(x0, x1)


def _skin_window(lab: np.ndarray, mask: np.ndarray, centre, half_w: float, half_h: float):
    """A window of the photo about ``centre``: its rows and columns (slices), colours, the
    silhouette's pixels in it and their median colour (the skin's); None when the window
    holds fewer than 20 of the silhouette's pixels."""
    rows, cols = _window(lab.shape, centre, half_w, half_h)
    win = lab[rows, cols]
    inside = mask[rows, cols]
    if inside.sum() < 20:
        return None
    return rows, cols, win, inside, np.median(win[inside], axis=0)


def _components(flags: np.ndarray):
    from scipy import ndimage as ndi

    lab, n = ndi.label(flags, structure=np.ones((3, 3)))
    return lab, n


def eye_white(lab: np.ndarray, mask: np.ndarray, centre: np.ndarray, ipd: float) -> dict | None:
    """The white of the eye seen from the side, or None.

    Parameters
    ----------
    lab : (H, W, 3) float
        The photo's colours (:func:`recon.landmarks.colour.to_lab`), nose to the left.
    mask : (H, W) bool
        The head's silhouette.
    centre : (2,) float
        Where the eye is expected (between the pupil and the outer corner), pixels.
    ipd : float
        Distance between the pupils at the side photo's scale, pixels.

    Returns
    -------
    dict or None
        ``front``, ``back``: the white's most forward and rearmost pixels (x, y) — the
        iris's edge and the outer corner of the eye; ``centre``; ``area`` in pixels.
        None when no patch bright and grey enough, and large enough, is there.
    """
    from scipy import ndimage as ndi

    found = _skin_window(lab, ndi.binary_erosion(mask, iterations=max(1, int(0.02 * ipd))), centre,
                         0.4 * ipd, 0.2 * ipd)
    if found is None:
        return None
    rows, cols, win, inside, skin = found
    chroma = np.hypot(win[..., 1], win[..., 2])
    skin_chroma = float(np.hypot(skin[1], skin[2]))
    white = inside & (win[..., 0] > skin[0] + 4.0) & (chroma < 0.6 * skin_chroma)
    lab_c, n = _components(white)
    if n == 0:
        return None
    sizes = np.bincount(lab_c.ravel())
    sizes[0] = 0
    k = int(np.argmax(sizes))
    if sizes[k] < (0.02 * ipd) ** 2 * 3:
        return None
    ys, xs = np.nonzero(lab_c == k)
    xs = xs + cols.start
    ys = ys + rows.start
    f, b = np.argmin(xs), np.argmax(xs)
    return {"front": np.array([xs[f], ys[f]], float), "back": np.array([xs[b], ys[b]], float),
            "centre": np.array([xs.mean(), ys.mean()]), "area": int(sizes[k])}


def lip_region(lab: np.ndarray, mask: np.ndarray, centre: np.ndarray, ipd: float) -> dict | None:
    """The lips seen from the side, or None.

    Parameters
    ----------
    lab : (H, W, 3) float
        The photo's colours (:func:`recon.landmarks.colour.to_lab`), nose to the left.
    mask : (H, W) bool
        The head's silhouette.
    centre : (2,) float
        Where the corner of the mouth is expected, pixels.
    ipd : float
        Distance between the pupils at the side photo's scale, pixels.

    Returns
    -------
    dict or None
        ``corner``: the lips' rearmost pixel (x, y), the corner of the mouth; ``area``.
        None when no patch clearly redder than the skin around it touches the profile.
    """
    for _ in range(2):
        found = _skin_window(lab, mask, centre, 0.45 * ipd, 0.25 * ipd)
        if found is None:
            return None
        rows, cols, win, inside, skin = found
        red = inside & (win[..., 1] > skin[1] + 8.0)
        lab_c, n = _components(red)
        # The lips reach the profile: keep the patch nearest to the window's front.
        best, best_x = None, np.inf
        for k in range(1, n + 1):
            ys, xs = np.nonzero(lab_c == k)
            if len(xs) < (0.03 * ipd) ** 2 * 3:
                continue
            if xs.min() < best_x:
                best, best_x = (ys, xs), xs.min()
        if best is None:
            return None
        ys, xs = best
        # A patch the window's top or bottom cuts is looked at again, centred on it (the
        # mouth was expected a little off).
        if 0 < ys.min() and ys.max() < win.shape[0] - 1:
            break
        centre = np.array([centre[0], rows.start + 0.5 * (ys.min() + ys.max())])
    b = np.argmax(xs)
    return {"corner": np.array([xs[b] + cols.start, ys[b] + rows.start], float), "area": len(xs)}


SCALES_X = (0.9, 1.0, 1.1)
SCALES_Y = (0.9, 1.0, 1.1, 1.2, 1.3, 1.4)

#: The ear's points in order around its outline: the upper join, the top, the back, the
#: lobe and the lower join (the left ear's ids, whichever ear a photo shows).
EAR_OUTLINE = ("10.9", "10.1", "10.3", "10.5", "10.7")


def _edges(lab: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int], ipd: float, skin, hair) -> np.ndarray:
    """Lightness gradient's size in a box (x0, y0, x1, y1), zero on the hair, near its edge
    and near the silhouette's edge."""
    from scipy import ndimage as ndi

    from .colour import FAR

    x0, y0, x1, y1 = box
    win = lab[y0:y1, x0:x1]
    inside = ndi.binary_erosion(mask, iterations=max(1, int(0.04 * ipd)))[y0:y1, x0:x1]
    ds = skin.distance2(win)
    foreign = (hair.distance2(win) < ds) & (ds > 0.25 * FAR) if hair is not None else ds > FAR
    foreign = ndi.binary_opening(foreign, iterations=1)
    allowed = inside & ~ndi.binary_dilation(foreign, iterations=max(1, int(0.04 * ipd)))
    light = ndi.gaussian_filter(win[..., 0], max(1.0, 0.01 * ipd))
    return np.hypot(ndi.sobel(light, 0), ndi.sobel(light, 1)) * allowed


def ear_box(lab: np.ndarray, mask: np.ndarray, expected: dict[str, np.ndarray], ipd: float,
            skin, hair=None) -> dict | None:
    """The ear seen from the side: where its expected outline lies on the strongest edges.

    The ear's outline — the closed curve through its five points (:data:`EAR_OUTLINE`) where
    they are expected — is slid over the photo (up to 0.35 IPD back and forth, 0.1 IPD up
    and down, 10 % larger or smaller) to where the lightness' gradient along it is
    strongest: the rim of an ear stands out in shading from the head behind it. The hair,
    its edge and the silhouette's edge are left out of the gradient.

    Parameters
    ----------
    lab : (H, W, 3) float
        The photo's colours (:func:`recon.landmarks.colour.to_lab`), nose to the left.
    mask : (H, W) bool
        The head's silhouette.
    expected : dict of str to (2,) float
        Where the ear's points (:data:`EAR_OUTLINE`) are expected, pixels.
    ipd : float
        Distance between the pupils at the side photo's scale, pixels.
    skin, hair : ColourModel
        The skin's and the hair's colours in this photo (hair None: no hair).

    Returns
    -------
    dict or None
        The ear's points moved; ``shift`` (2,) and ``scale`` of the move; ``contrast``, the
        gradient along the outline there over its median in the window (1: no better than
        anywhere). None when the window is empty or off the photo.
    """
    from scipy import ndimage as ndi
    from scipy.interpolate import splev, splprep

    pts = np.array([expected[i] for i in EAR_OUTLINE], float)
    centre = pts.mean(axis=0)
    reach = np.array([0.35 * ipd, 0.1 * ipd])
    span = np.ptp(pts, axis=0) * 0.55 * np.array([max(SCALES_X), max(SCALES_Y)])
    h, w = mask.shape
    x0, y0 = (np.maximum(0, centre - span - reach - 3)).astype(int)
    x1, y1 = (np.minimum([w, h], centre + span + reach + 3)).astype(int)
    if x1 - x0 < 10 or y1 - y0 < 10:
        return None
    grad = _edges(lab, mask, (x0, y0, x1, y1), ipd, skin, hair)
    ring = np.r_[pts, pts[:1]]
    try:
        tck, _ = splprep(ring.T, s=0, per=True)
    except (ValueError, TypeError):
        return None
    curve = np.array(splev(np.linspace(0, 1, 120, endpoint=False), tck)).T - centre
    step = max(1.0, 0.01 * ipd)
    best = (-1.0, None)
    for scale in itertools.product(SCALES_X, SCALES_Y):
        c = curve * scale
        for dy in np.arange(-reach[1], reach[1] + 1e-9, step):
            xs = np.arange(-reach[0], reach[0] + 1e-9, step)
            px = centre[0] + xs[:, None] + c[None, :, 0] - x0
            py = np.broadcast_to(centre[1] + dy + c[None, :, 1] - y0, px.shape)
            vals = ndi.map_coordinates(grad, [py.ravel(), px.ravel()], order=1, mode="constant").reshape(px.shape)
            score = vals.mean(axis=1)
            k = int(np.argmax(score))
            if score[k] > best[0]:
                best = (float(score[k]), (xs[k], dy, scale))
    if best[1] is None:
        return None
    dx, dy, scale = best[1]
    moved = {i: centre + np.array([dx, dy]) + np.asarray(scale) * (expected[i] - centre) for i in EAR_OUTLINE}
    background = float(np.median(grad[grad > 0])) if np.any(grad > 0) else 0.0
    moved.update(shift=np.array([dx, dy]), scale=scale, contrast=best[0] / max(background, 1e-9))
    return moved
