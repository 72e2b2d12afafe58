"""The neck below the collar and under hanging hair: found in a photo and filled from the
skin around it.

The head's mesh runs down the neck to the top of the chest; a photo shows a shirt there,
and long hair hanging over the nape. Textured as they are, the collar, the shirt and the
strands are painted onto the neck. Here the skin's colours are learnt from the face (a
Gaussian in CIELAB over the pixels of skin vertices the photo sees, grown from the cheeks:
:func:`face_skin_model`). Below the chin the pixels that are not skin by that model and
that rise from the bottom of the head's region — the shirt comes up from below — are taken
for clothes; under the ears behind the jaw (:func:`nape_zone`) whatever is not skin is taken
for hair. Both are painted as the skin around them (:func:`fill_from_skin`): the
skin's colour carried smoothly in from all round (a harmonic membrane), with the skin's own
grain.
"""

from __future__ import annotations

import cv2
import numpy as np

from mpeg4.camera import Camera
from mpeg4.head import Head
from mpeg4.render import vertex_normals

from .delight import fit_mask

__all__ = ["SKIN_CHI2", "skin_model", "face_skin_model", "cheek_vertices", "skin_pixels", "clothes_mask",
           "nape_zone", "collar_bands", "fill_from_skin", "remove_clothes"]

#: Squared Mahalanobis distance (3 degrees of freedom) beyond which a colour is not skin:
#: the 99.9th percentile of the chi-squared law, so that the skin itself is almost never
#: taken for clothes.
SKIN_CHI2 = 16.27
#: Cells across the grid on which :func:`fill_from_skin` finds the skin's shading: the
#: neck's shading is smooth on that scale, and the solve stays at a few milliseconds.
FILL_GRID = 96


def _lab(pixels: np.ndarray) -> np.ndarray:
    """(..., 3) float32 CIELAB (L 0–100) of RGB uint8 pixels."""
    p = np.asarray(pixels, np.uint8)
    flat = p.reshape(-1, 1, 3).astype(np.float32) / 255.0
    return cv2.cvtColor(flat, cv2.COLOR_RGB2LAB).reshape(p.shape[:-1] + (3,))


def skin_model(photo: np.ndarray, skin_px: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The skin's colour in a photo: a Gaussian in CIELAB.

    Parameters
    ----------
    photo : (H, W, 3) uint8
        RGB.
    skin_px : (K, 2) float
        Pixels (x, y) of skin the photo shows (the face's cheeks and forehead).

    Returns
    -------
    (mean, inverse covariance) : (3,), (3, 3) float64, or None
        After one pass that leaves out the samples beyond :data:`SKIN_CHI2` (a lock of hair,
        a brow). None
        when fewer than 30 pixels are inside the photo.
    """
    h, w = photo.shape[:2]
    p = np.rint(np.asarray(skin_px, float)).astype(np.int64)
    p = p[(p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)]
    if len(p) < 30:
        return None
    lab = _lab(photo[p[:, 1], p[:, 0]]).astype(np.float64)
    keep = np.ones(len(lab), bool)
    for _ in range(2):
        mean = np.median(lab[keep], axis=0)
        cov = np.cov(lab[keep].T) + np.eye(3) * 1.0  # a floor of 1 unit²: flat synthetic skin
        d2 = np.einsum("ij,jk,ik->i", lab - mean, np.linalg.inv(cov), lab - mean)
        keep = d2 < SKIN_CHI2
        if keep.sum() < 30:
            return None
    return mean, np.linalg.inv(cov)


def skin_pixels(photo: np.ndarray, model: tuple[np.ndarray, np.ndarray], rows: slice = slice(None),
                lightness: float = 1.0) -> np.ndarray:
    """(H', W) bool over the photo's ``rows``: pixels whose colour is skin by the model
    (squared Mahalanobis distance within :data:`SKIN_CHI2`), with the model's spread in
    lightness multiplied by ``lightness`` (2 for the neck's shadow under the chin: a white,
    grey or dark shirt still differs in chroma)."""
    mean, inv = model
    s = np.diag([1.0 / lightness, 1.0, 1.0])
    d = _lab(photo[rows]) - mean.astype(np.float32)
    return np.sum((d @ (s @ inv @ s).astype(np.float32)) * d, axis=-1) <= SKIN_CHI2


def clothes_mask(photo: np.ndarray, head_mask: np.ndarray, model: tuple[np.ndarray, np.ndarray],
                 chin_row: float, open_px: int = 5) -> np.ndarray:
    """(H, W) bool: the clothes over the head's neck in a photo.

    Parameters
    ----------
    photo : (H, W, 3) uint8
    head_mask : (H, W) bool
        Where the photo shows the head (the rendered head less the backdrop).
    model : (mean, inverse covariance)
        :func:`skin_model`.
    chin_row : float
        The chin's row (2.1): nothing above it is clothes.
    open_px : int
        Not-skin specks narrower than this (stubble, a crease's shadow) are left alone.

    Returns
    -------
    (H, W) bool
        In each column, from the top of the not-skin regions that reach the bottom of the
        head's region down to that bottom.
    """
    h, w = head_mask.shape
    top = int(np.clip(np.ceil(chin_row), 0, h))
    below = np.zeros((h, w), bool)
    below[top:] = head_mask[top:]
    if not below.any():
        return below
    other = np.zeros((h, w), np.uint8)
    other[top:] = ~skin_pixels(photo, model, slice(top, h), lightness=2.0) & below[top:]
    k = np.ones((open_px, open_px), np.uint8)
    other = cv2.morphologyEx(other, cv2.MORPH_OPEN, k)
    # The clothes rise from the bottom of the head's region: keep the parts that touch it.
    _, labels = cv2.connectedComponents(other, connectivity=8)
    cols = np.flatnonzero(below.any(axis=0))
    bottom = h - 1 - np.argmax(below[::-1, cols], axis=0)  # the lowest head row per column
    touching = np.unique(labels[np.clip(bottom - open_px, 0, h - 1), cols])
    rising = np.isin(labels, touching[touching > 0])
    # Each column from its clothes' top down: the V of an open collar stays skin.
    first = np.where(rising.any(axis=0), np.argmax(rising, axis=0), h)
    return below & (np.arange(h)[:, None] >= first[None, :])


def nape_zone(head: Head, camera: Camera, depth: np.ndarray, within: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: where a photo shows the neck under the ears, behind the jaw.

    The skin there is neck and nape, not scalp: long hair hanging over it belongs to no
    part of the head's mesh, and a beard does not reach it. It lies below the ear lobes
    (the mean height of 10.5/10.6) and behind the jaw's rear edge: the line from where the
    lobes join the face (10.7/10.8) down to the jaw's angles (2.13/2.14, the gonion), then
    below the angles behind their depth (the means of each pair). Without the ears' points,
    only what lies below and behind the jaw's angles. Each pixel is judged by the surface
    point it shows (``depth``: the head's depth render through ``camera``, ``inf`` where
    it does not show), so the zone's edge is as smooth as the photo's pixels; only the
    pixels ``within`` ((H, W) bool, optional: the head's region) are looked at. Empty when
    the head lacks 2.13 or 2.14."""
    depth = np.asarray(depth, np.float64)
    h, w = depth.shape
    fps = head.feature_points
    if not all(i in fps for i in ("2.13", "2.14")):
        return np.zeros((h, w), bool)
    jaw = 0.5 * (head.fp_position("2.13") + head.fp_position("2.14"))
    top, joint = jaw[1], None
    if all(i in fps for i in ("10.5", "10.6", "10.7", "10.8")):
        top = max(jaw[1], 0.5 * (head.fp_position("10.5")[1] + head.fp_position("10.6")[1]))
        joint = 0.5 * (head.fp_position("10.7") + head.fp_position("10.8"))
        if joint[1] <= jaw[1]:
            top, joint = jaw[1], None

    def behind(p: np.ndarray) -> np.ndarray:
        """Points (K, 3) below ``top`` and behind the jaw's rear edge at their height."""
        z = np.full(len(p), jaw[2])
        if joint is not None:
            t = np.clip((p[:, 1] - jaw[1]) / (joint[1] - jaw[1]), 0.0, 1.0)
            z = jaw[2] + t * (joint[2] - jaw[2])
        return (p[:, 1] < top) & (p[:, 2] < z)

    # Rows above every skin vertex near the zone (within a centimetre, far more than a
    # triangle's size) cannot show it: only the rows below are unprojected.
    v = head.skin.vertices
    z_max = jaw[2] if joint is None else max(jaw[2], joint[2])
    near = (v[:, 1] < top + 0.01) & (v[:, 2] < z_max + 0.01)
    if not near.any():
        return np.zeros((h, w), bool)
    first = int(np.clip(np.floor(camera.project(v[near])[:, 1].min()) - 2, 0, h))
    look = np.isfinite(depth[first:]) if within is None else np.isfinite(depth[first:]) & within[first:]
    ys, xs = np.nonzero(look)
    ys += first
    p = camera.unproject(np.c_[xs, ys], depth[ys, xs])
    out = np.zeros((h, w), bool)
    out[ys, xs] = behind(p)
    return out


def collar_bands(other: np.ndarray, nape: np.ndarray, chin_row: float, min_px: int = 25) -> np.ndarray:
    """(H, W) bool: what is not skin below the chin and reaches into the nape, low on the neck.

    A collar of another colour than the shirt below it (a white undershirt's rim above a
    sweater of the skin's colour) does not rise from the bottom of the head's region as
    :func:`clothes_mask` wants, and the nape zone holds only its ends; such a band crosses
    the neck from the nape on one side. Taken: each not-skin region (``other``, 8-connected,
    of at least ``min_px`` pixels) below ``chin_row`` that reaches into ``nape`` and whose
    middle lies in the lower half of the neck, between the chin and the head region's
    bottom (a beard, under the jaw, does not), with a pixel round it.
    """
    h, w = other.shape
    top = int(np.clip(np.ceil(chin_row), 0, h))
    below = np.zeros((h, w), np.uint8)
    below[top:] = other[top:]
    n, labels, stats, centre = cv2.connectedComponentsWithStats(below, connectivity=8)
    rows = np.flatnonzero(other.any(axis=1) | nape.any(axis=1))
    if n <= 1 or not len(rows):
        return np.zeros((h, w), bool)
    half = 0.5 * (top + rows[-1])
    touching = np.zeros(n, bool)
    touching[np.unique(labels[nape & (labels > 0)])] = True
    keep = touching & (stats[:, cv2.CC_STAT_AREA] >= min_px) & (centre[:, 1] >= half)
    keep[0] = False
    # With a pixel round each, the band's blurred rim.
    return cv2.dilate(keep[labels].astype(np.uint8), np.ones((3, 3), np.uint8)) > 0


def fill_from_skin(photo: np.ndarray, mask: np.ndarray, skin: np.ndarray, grain_px: float = 0.7,
                   seed: int = 0) -> np.ndarray:
    """The photo with its masked pixels painted as the skin around them: a smooth membrane
    of the skin's colour plus grain of the skin's own strength.

    1. Shading: on a grid of about :data:`FILL_GRID` cells across, each cell with mostly
       skin holds the skin's mean colour there; the other cells take the harmonic
       interpolation of those (Laplace's equation, the skin cells fixed, no flow across
       the photo's edge), resampled bilinearly to pixels. It meets the skin round the
       mask without a step and carries the neck's shading down, where copying rows of
       skin (each column with its own band) left a stripe for every row and a step
       between columns.
    2. Grain: the skin's detail (the photo less its Gaussian blur of 3 pixels, over the
       skin only; its strongest 5 %, edges, left out) has a 3 × 3 colour covariance;
       white noise blurred by ``grain_px``, mixed by that covariance's Cholesky factor,
       matches it (pores and the camera's noise, mostly in lightness).

    Parameters
    ----------
    photo : (H, W, 3) uint8
    mask : (H, W) bool
        What to paint (:func:`clothes_mask`).
    skin : (H, W) bool
        The skin to paint it from: skin of the head (:func:`skin_pixels` within the head's
        region, below the chin; not hair lying on a shoulder).
    grain_px : float
        Gaussian blur (pixels) of the grain's white noise: a photo's grain is correlated
        over about a pixel (demosaicing, JPEG, resampling).
    seed : int
        Of the grain's noise.

    Returns
    -------
    (H, W, 3) uint8
        A copy; unmasked pixels unchanged (the photo itself when nothing is masked or no
        skin is given).
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    mask = np.asarray(mask, bool)
    skin = np.asarray(skin, bool) & ~mask
    if not mask.any() or skin.sum() < 30:
        return photo
    h, w = mask.shape
    img = photo.astype(np.float32)
    f = max(1, int(np.ceil(max(h, w) / FILL_GRID)))
    gh, gw = -(-h // f), -(-w // f)
    pad = ((0, gh * f - h), (0, gw * f - w))
    weight = np.pad(skin.astype(np.float32), pad).reshape(gh, f, gw, f).sum(axis=(1, 3))
    colour = np.stack([np.pad(img[..., c] * skin, pad).reshape(gh, f, gw, f).sum(axis=(1, 3))
                       for c in range(3)], axis=-1)
    known = weight >= 0.5 * f * f
    colour[known] /= weight[known, None]
    if not known.any():
        known = weight > 0
        colour[known] /= weight[known, None]
    # Laplace's equation over the other cells: each the mean of its neighbours in the grid.
    free = ~known
    index = -np.ones((gh, gw), np.int64)
    index[free] = np.arange(free.sum())
    rows, cols = [], []
    rhs = np.zeros((free.sum(), 3))
    degree = np.zeros(free.sum())
    fy, fx = np.nonzero(free)
    me = index[fy, fx]
    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        ny, nx = fy + dy, fx + dx
        inside = (ny >= 0) & (ny < gh) & (nx >= 0) & (nx < gw)
        a, ny, nx = me[inside], ny[inside], nx[inside]
        degree[a] += 1
        other = free[ny, nx]
        rows.append(a[other])
        cols.append(index[ny[other], nx[other]])
        np.add.at(rhs, a[~other], colour[ny[~other], nx[~other]])
    # A cell walled off from the skin drifts to the skin's mean (a weak pull, 1e-4 of a
    # neighbour's, that leaves the others as they are).
    eps = 1e-4
    rhs += eps * colour[known].mean(axis=0)
    A = sp.csr_matrix((np.r_[degree + eps, -np.ones(sum(len(r) for r in rows))],
                       (np.r_[np.arange(len(me)), np.concatenate(rows)],
                        np.r_[np.arange(len(me)), np.concatenate(cols)])), shape=(len(me), len(me)))
    colour[free] = np.asarray(spsolve(A.tocsc(), rhs)).reshape(-1, 3)
    smooth = cv2.resize(colour.astype(np.float32), (gw * f, gh * f), interpolation=cv2.INTER_LINEAR)[:h, :w]
    # The skin's grain: its detail's colour covariance, matched by mixed, blurred noise.
    s = skin.astype(np.float32)
    norm = cv2.GaussianBlur(s, (0, 0), 3.0)
    blurred = cv2.GaussianBlur(img * s[..., None], (0, 0), 3.0) / np.maximum(norm, 1e-6)[..., None]
    detail = (img - blurred)[skin & (norm > 0.5)]
    # The strongest 5 % are edges (a lock of hair, a crease, the skin's rim), not grain.
    if len(detail) > 20:
        strength = np.sum(detail * detail, axis=1)
        detail = detail[strength <= np.quantile(strength, 0.95)]
    cov = np.cov(detail.T) if len(detail) > 10 else np.zeros((3, 3))
    lower = np.linalg.cholesky(cov + 1e-6 * np.eye(3))
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((h, w, 3)).astype(np.float32)
    if grain_px > 0:
        noise = cv2.GaussianBlur(noise, (0, 0), grain_px)
        noise /= np.maximum(noise.reshape(-1, 3).std(axis=0), 1e-6)
    grain = noise @ lower.T.astype(np.float32)
    out = photo.copy()
    out[mask] = np.clip(np.rint(smooth[mask] + grain[mask]), 0, 255).astype(np.uint8)
    return out


def face_skin_model(head: Head, photo: np.ndarray, camera: Camera, seen: np.ndarray,
                    normals: np.ndarray | None = None,
                    skin: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`skin_model` of a photo from the face of the head fitted to it: the skin
    vertices (``skin``, :func:`recon.texture.delight.fit_mask` when None) the camera sees
    (``seen``, (N,) bool), above the chin (2.1) and facing the camera within 45° — not the
    neck (it may be under a collar), nor the rims and sideburns seen edge-on.

    Where the hair falls over that face (a fringe, the temples and the hair before the ear
    in a profile), the head's regions do not know it, and fair hair is near enough to skin
    to widen one Gaussian over both. So the model starts from the cheeks the camera sees
    (:func:`cheek_vertices`: below the eyes, above the mouth's corners, beside the nose),
    skin on almost everyone, and takes the rest of the face where its colour is skin by
    that start, its lightness spread doubled (the forehead and the chin lie in other
    light). None as :func:`skin_model`."""
    v = head.skin.vertices
    normals = vertex_normals(v, head.skin.triangles) if normals is None else normals
    skin = fit_mask(head) > 0 if skin is None else skin
    facing = np.sum(normals * camera.towards(v), axis=1) >= np.cos(np.radians(45.0))
    face = skin & seen & facing
    if "2.1" in head.feature_points:
        face &= v[:, 1] > head.fp_position("2.1")[1]
    px = camera.project(v[face])
    # The cheeks however squarely they face the camera: a profile sees them at 45–70°.
    core = skin_model(photo, camera.project(v[skin & seen & cheek_vertices(head)]))
    if core is not None:
        h, w = photo.shape[:2]
        q = np.rint(px).astype(np.int64)
        q = q[(q[:, 0] >= 0) & (q[:, 0] < w) & (q[:, 1] >= 0) & (q[:, 1] < h)]
        like = skin_pixels(photo[q[:, 1], q[:, 0]][None], core, lightness=2.0)[0]
        if like.sum() >= 30:
            px = q[like]
    return skin_model(photo, px)


def cheek_vertices(head: Head) -> np.ndarray:
    """(N,) bool: the skin vertices of the cheeks, between the lower lids' and the mouth's
    corners' heights, from the nose's wings out to the eyes' outer corners (their distance
    from the midline), in front of the outer corners. Hair and beards rarely reach them.
    All False when the head lacks one of those feature points."""
    v = head.skin.vertices
    need = ("3.3", "3.4", "8.3", "8.4", "9.1", "9.2", "3.7", "3.12")
    if not all(i in head.feature_points for i in need):
        return np.zeros(len(v), bool)
    p = {i: head.fp_position(i) for i in need}
    top = 0.5 * (p["3.3"][1] + p["3.4"][1])
    bottom = 0.5 * (p["8.3"][1] + p["8.4"][1])
    inner = 0.5 * (abs(p["9.1"][0]) + abs(p["9.2"][0]))
    outer = 0.5 * (abs(p["3.7"][0]) + abs(p["3.12"][0]))
    front = min(p["3.7"][2], p["3.12"][2])
    x = np.abs(v[:, 0])
    return (v[:, 1] < top) & (v[:, 1] > bottom) & (x > inner) & (x < outer) & (v[:, 2] > front)


def remove_clothes(head: Head, photo: np.ndarray, head_mask: np.ndarray, camera: Camera,
                   seen: np.ndarray, normals: np.ndarray | None = None, skin: np.ndarray | None = None,
                   depth: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """A photo of ``head`` with the clothes over its neck, and the hair hanging over its
    nape (:func:`nape_zone`), filled from the skin around them.

    Parameters
    ----------
    head : Head
        Fitted to the photo, with the chin (2.1).
    photo : (H, W, 3) uint8
        RGB, as taken (the texture fills the clothes before it fits the photo's light).
    head_mask : (H, W) bool
        Where the photo shows the head.
    camera : mpeg4.camera.Camera
        The photo's camera.
    seen : (N,) bool
        The head's skin vertices the camera sees.
    normals : (N, 3) float, optional
        The skin's vertex normals (computed when None).
    skin : (N,) bool, optional
        The skin vertices whose colour is skin (:func:`recon.texture.delight.fit_mask` when
        None).
    depth : (H, W) float, optional
        The head's depth render through ``camera`` (:func:`mpeg4.unlit.render_depth`;
        rendered when None): where the nape is (:func:`nape_zone`).

    Returns
    -------
    photo : (H, W, 3) uint8
        The photo itself when there is nothing to fill.
    share : float
        Of the head's region the clothes covered.
    """
    pts = head.fp_positions()
    if "2.1" not in pts:
        return photo, 0.0
    model = face_skin_model(head, photo, camera, seen, normals, skin)
    if model is None:
        return photo, 0.0
    chin = camera.project(np.asarray(pts["2.1"])[None])[0]
    # Only the head's region below the chin, and the nape, is looked at.
    chin_row = int(np.clip(np.ceil(chin[1]), 0, photo.shape[0]))
    if depth is None:
        from .regions import _depth, _head_meshes

        depth = _depth(_head_meshes(head), camera)
    nape_full = nape_zone(head, camera, depth, within=head_mask)
    top = min(chin_row, int(np.argmax(nape_full.any(axis=1)))) if nape_full.any() else chin_row
    cols = np.flatnonzero(head_mask[top:].any(axis=0))
    rows = np.flatnonzero(head_mask[top:].any(axis=1))
    if not len(cols):
        return photo, 0.0
    box = np.s_[top:top + rows[-1] + 1, cols[0]:cols[-1] + 1]
    crop, crop_head = photo[box], head_mask[box]
    mask = clothes_mask(crop, crop_head, model, chin_row - top)
    # Hair hanging over the neck behind the jaw: what is not skin there by the model's own
    # spread (fair hair passes the clothes' looser test; skin in the jaw's shadow that
    # fails this one is painted as the skin around it, which carries the shading in).
    nape = nape_full[box]
    strict = skin_pixels(crop, model)
    if nape.any():
        hair = (nape & ~strict).astype(np.uint8)
        # Strands are a pixel or two wide: no opening (it would take them all away), only
        # specks smaller than a 5 x 5 square left out, and each strand's fringe taken too.
        _, labels, stats, _ = cv2.connectedComponentsWithStats(hair, connectivity=8)
        big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= 25)
        hair = np.isin(labels, big[big > 0]).astype(np.uint8)
        mask |= (cv2.dilate(hair, np.ones((3, 3), np.uint8)) > 0) & nape
        mask |= collar_bands(~strict & crop_head, nape, chin_row - top) & crop_head
    if not mask.any():
        return photo, 0.0
    # Skin by the model's own spread: the looser test the clothes are found by would let
    # brown hair lying on the neck in, and pull the fill towards it.
    source = crop_head & strict & ~mask
    # The fill's work kept to what it paints and the skin round it (a tenth of the box
    # each way): a few hairs at the nape need not solve for the whole neck.
    ys, xs = np.nonzero(mask)
    m = max(8, int(0.1 * max(mask.shape)))
    near = np.s_[max(ys.min() - m, 0):ys.max() + m + 1, max(xs.min() - m, 0):xs.max() + m + 1]
    out = photo.copy()
    filled = crop.copy()
    filled[near] = fill_from_skin(crop[near], mask[near], source[near])
    out[box] = filled
    return out, float(mask.sum() / max(head_mask.sum(), 1))
