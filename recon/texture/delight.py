"""The light taken out of a photo of the fitted head: an albedo image for the texture.

Each photo carries its own lighting, and the light moves with the camera: skin one photo
sees head-on, the other sees at a grazing angle and far darker, so one lit texture cannot
match both photos. :func:`delight_photo` fits, per photo, a low-order lighting model to the
skin — second-order spherical harmonics of the surface normal (nine coefficients), as
Ramamoorthi and Hanrahan showed suffice for a Lambertian surface under any distant light —
assuming that the skin's albedo is smooth and near-constant at low frequency, and divides
the photo by the fitted shading.

* The normals come from the fitted head rendered with the photo's fitted camera
  (:func:`normal_image`), in the camera's frame; that render's depth is the one the
  texture's visibility test needs, so :func:`recon.texture.texture_skin` renders each photo's
  view once. Only the head's box is worked on, and the skin to fit is rendered at the fitted
  pixels only (:func:`skin_weight`).
* The fit is a robust (iteratively reweighted, Tukey biweight) least-squares fit of the
  photo's luma to the nine harmonics over the skin the feature points tell from the eyes,
  brows, lips, nostrils and hair (:func:`fit_mask`); what is left of the hair, lashes and
  shadows falls to the robust weights. Photos are used as they are encoded: a power-law
  encoding keeps albedo × shading a product, so the division holds either way.
* The fit knows only the scale of albedo × light intensity, not each. The shading is
  scaled so that the albedo's median brightness over the fitted skin that faces the camera
  (within 45°, above the chin: the cheeks, the forehead; not the neck, in the chin's
  shadow) is the photo's: the albedo keeps the photo's skin colour, and only the light's
  variation over the face is taken out. (A shading of mean 1 keeps it only under an even
  light: under a strong one the lit cheeks came out dark and grey, 10 ΔE off the photo.
  Scaling it to its brightest value instead would make the albedo the colour facing the
  light squarely, but one bright spot — a highlight on glasses, a shiny forehead — then
  brightens the whole face: a dark skin came out pale.)
* The result is judged before it is used (:func:`judge`): an implausible light (most of
  the skin in deep shadow) or an albedo that leaves the photo's range (skin burnt out to
  white where the photo was not) falls back to the photo as it is, with the reason.
* Where the shading falls below :data:`MIN_SHADING` of that (grazing light, deep shadow)
  it is held there, so that noise is not blown up; :attr:`Lighting.trust` says where the
  division is to be trusted.

References
----------
R. Ramamoorthi and P. Hanrahan, "An efficient representation for irradiance environment
maps", SIGGRAPH 2001.
R. Basri and D. W. Jacobs, "Lambertian reflectance and linear subspaces", IEEE PAMI 25(2),
2003.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

from mpeg4.camera import Camera
from mpeg4.errors import InputError
from mpeg4.head import Head
from mpeg4.render import RenderMesh, vertex_normals
from mpeg4.unlit import render_unlit

__all__ = ["Lighting", "MIN_SHADING", "MIN_MEAN_SHADING", "MAX_BURNT", "EDGE_BAND", "sh_basis", "normal_image",
           "decode_normals", "skin_weight", "fit_mask", "fit_lighting", "judge", "delight_photo", "burnt_pixels"]

#: Shading (share of its brightest) below which the division is not trusted and held.
MIN_SHADING = 0.25
#: The fitted shading's mean over the skin, as a share of its brightest, below which the
#: light is implausible (most of the face in deep shadow: the fit followed dark skin or
#: hair, not light).
MIN_MEAN_SHADING = 0.3
#: Largest share of the skin that de-lighting may burn out to white where the photo was not.
MAX_BURNT = 0.02
#: Width of the band inside the person's outline in which :func:`burnt_pixels` looks, as a
#: share of the outline's bounding box's smaller side (the neck's overhang is a few
#: percent of the head).
EDGE_BAND = 0.06

_LUMA = np.array([0.299, 0.587, 0.114])
_DECODE = (np.arange(256, dtype=np.float32) / np.float32(127.5) - np.float32(1.0)).reshape(1, 256)  # byte → n
_STRIDE = 3  # pixels: the fit takes every third pixel each way
_SMOOTH_PX = 2.0  # the shading's blur, pixels


@dataclass
class Lighting:
    """A photo's fitted lighting.

    Attributes
    ----------
    coefficients : (9,) float64
        Of :func:`sh_basis` for the photo's luma (grey levels), camera frame.
    peak : float
        The brightest fitted luma over the fitted skin.
    shading : (H, W) float32
        The shading at every pixel of the head (1 elsewhere): the harmonics over ``peak``,
        clamped to [:data:`MIN_SHADING`, 1.25], then scaled so that the photo's skin facing
        the camera divided by it keeps its median brightness.
    mean : float
        The clamped shading's mean over the fitted skin, as a share of ``peak``.
    trust : (H, W) bool
        Pixels of the head whose shading is at least :data:`MIN_SHADING` (unclamped).
    fit_pixels : int
        Pixels the fit used, and ``inlier_share`` the share of them the robust weights kept.
    """

    coefficients: np.ndarray
    peak: float
    shading: np.ndarray
    trust: np.ndarray
    fit_pixels: int
    inlier_share: float
    mean: float = 1.0
    fallback: str | None = None

    @property
    def direction(self) -> np.ndarray:
        """(3,) unit direction (camera frame) of the fitted light's first-order part."""
        d = self.coefficients[1:4]
        n = np.linalg.norm(d)
        return d / n if n > 0 else d


def sh_basis(normals: np.ndarray) -> np.ndarray:
    """(K, 9) real spherical harmonics up to order 2 (unnormalised) at (K, 3) unit normals:
    1, x, y, z, xy, xz, yz, x² − y², 3z² − 1."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    x, y, z = n.T
    return np.stack([np.ones_like(x), x, y, z, x * y, x * z, y * z, x * x - y * y, 3 * z * z - 1], axis=1)


def normal_image(head: Head, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """The head's surface normals at every pixel of a camera's image, and its depth, from
    one render.

    Parameters
    ----------
    head : Head
    camera : Camera

    Returns
    -------
    encoded : (H, W, 3) uint8
        Unit normals in the camera's frame (x right, y up, z towards the viewer) as colours
        127.5 (n + 1) (:func:`decode_normals`).
    depth : (H, W) float64
        Metres, inf where the head is not drawn: the depth image of a plain depth render
        of the head, so that the texture's visibility test can use this render too.
    """
    meshes = []
    R = camera.rotation
    for p in head.parts.values():
        n = vertex_normals(p.vertices, p.triangles)
        # Unlit: the normals given only spare the renderer computing them again.
        meshes.append(RenderMesh(p.vertices, p.triangles, normals=n, vertex_colours=0.5 + 0.5 * (n @ R.T),
                                 colour=(1.0, 1.0, 1.0)))
    return render_unlit(meshes, camera, background=(0.5, 0.5, 0.5), return_depth=True)


def decode_normals(encoded: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 unit normals from :func:`normal_image`'s (H, W, 3) uint8 colours,
    zero outside the (H, W) bool ``mask``."""
    return cv2.merge(_normal_planes(encoded, mask))


def _normal_planes(encoded: np.ndarray, mask: np.ndarray) -> list[np.ndarray]:
    """:func:`decode_normals` as its three (H, W) float32 planes x, y, z."""
    # A look-up table per byte, then each plane scaled by the inverse length (zero off the
    # mask): OpenCV on contiguous planes, several times faster than numpy's broadcasting.
    x, y, z = cv2.split(cv2.LUT(np.asarray(encoded, np.uint8), _DECODE))
    length = cv2.sqrt(x * x + y * y + z * z)
    inverse = np.divide(np.float32(1.0), np.maximum(length, np.float32(1e-6)))
    inverse[~np.asarray(mask, bool)] = 0.0
    return [x * inverse, y * inverse, z * inverse]


def skin_weight(head: Head, camera: Camera, weights: np.ndarray, stride: int = 1,
                box: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """A value per skin vertex interpolated over the skin in a camera's image (0 elsewhere,
    the other parts hiding it), at every ``stride``-th pixel each way.

    Parameters
    ----------
    head : Head
    camera : Camera
    weights : (N,) float in [0, 1]
        One per skin vertex (e.g. :func:`fit_mask`).
    stride : int
    box : (x0, y0, x1, y1), optional
        The part of the image to render, pixels (the whole image by default).

    Returns
    -------
    (⌈(y1 − y0) / stride⌉, ⌈(x1 − x0) / stride⌉) float32
        Element (i, j) is the image's pixel (x0 + stride j, y0 + stride i): rendered with a
        camera whose pixel centres are those pixels', not sampled from a full-size render.
    """
    x0, y0, x1, y1 = box if box is not None else (0, 0, camera.width, camera.height)
    cx, cy = camera.principal
    sub = dataclasses.replace(camera, width=-(-(x1 - x0) // stride), height=-(-(y1 - y0) // stride),
                              principal=((cx - x0) / stride, (cy - y0) / stride),
                              focal_px=None if camera.focal_px is None else camera.focal_px / stride,
                              scale_px=None if camera.scale_px is None else camera.scale_px / stride)
    meshes = []
    for name, p in head.parts.items():
        w = np.asarray(weights, float) if name == "skin" else np.zeros(len(p.vertices))
        # Unlit, so any normal will do (given, so that the renderer need not compute them).
        meshes.append(RenderMesh(p.vertices, p.triangles, normals=np.broadcast_to([0.0, 0.0, 1.0], p.vertices.shape),
                                 vertex_colours=np.repeat(w[:, None], 3, axis=1), colour=(1.0, 1.0, 1.0)))
    img = render_unlit(meshes, sub, background=(0.0, 0.0, 0.0))
    return img[..., 0].astype(np.float32) / 255.0


def fit_mask(head: Head) -> np.ndarray:
    """(N,) float: 1 on the skin vertices whose colour is skin to the fit, 0 elsewhere.

    From the feature points: below the hairline (11.1–11.3) and in front of the ears (10.x,
    so not the back of the head and its hair), away from the eyes and lids (3.5, 3.6), the
    brows (4.x), the lips (8.x) and the nostrils (9.1, 9.2, 9.15).
    """
    from scipy.spatial.distance import cdist

    v = head.skin.vertices
    fp = head.fp_positions()
    keep = np.ones(len(v), bool)
    hair = [fp[i][1] for i in ("11.1", "11.2", "11.3") if i in fp]
    if hair:
        keep &= v[:, 1] < min(hair) - 0.008
    ears = [fp[i][2] for i in ("10.9", "10.10", "10.7", "10.8") if i in fp]
    if ears:
        keep &= v[:, 2] > np.mean(ears) - 0.01
    for i in ("3.5", "3.6"):
        if i in fp:
            d = (v - fp[i]) / (0.024, 0.016, 0.03)
            keep &= np.sum(d * d, axis=1) > 1.0
    for prefix, r in (("4.", 0.01), ("8.", 0.008), ("9.", 0.007)):
        pts = [fp[i] for i in fp if i.startswith(prefix) and (prefix != "9." or i in ("9.1", "9.2", "9.15"))]
        if pts:  # a few points: all their distances at once (a tree costs more)
            keep &= cdist(v, np.array(pts)).min(axis=1) > r
    lips = [fp[i] for i in fp if i.startswith("8.")]
    if lips:  # inside the lips' box too (the contour points are sparse)
        lp = np.array(lips)
        lo, hi = lp.min(axis=0) - 0.004, lp.max(axis=0) + 0.004
        inside = np.all((v[:, :2] > lo[:2]) & (v[:, :2] < hi[:2]), axis=1) & (v[:, 2] > lo[2] - 0.01)
        keep &= ~inside
    return keep.astype(np.float64)


def fit_lighting(photo: np.ndarray, normals: np.ndarray, head_mask: np.ndarray, weight: np.ndarray,
                 stride: int = _STRIDE, iterations: int = 8, ridge: float = 1e-3,
                 smooth_px: float = _SMOOTH_PX, face: np.ndarray | None = None) -> Lighting:
    """Fit second-order spherical-harmonic lighting to a photo's skin.

    Parameters
    ----------
    photo : (H, W, 3) uint8
    normals : (H, W, 3) float32, or its three (H, W) planes
        Unit normals, camera frame (:func:`decode_normals`).
    head_mask : (H, W) bool
        Where the head is drawn.
    weight : (H, W) float, or (⌈H / stride⌉, ⌈W / stride⌉) at the fitted pixels only
        > 0.5 on the skin to fit (:func:`skin_weight`).
    stride : int
        Every ``stride``-th pixel each way is fitted (and the shading's mean over the skin
        taken there).
    iterations : int
        Reweighting passes (Tukey's biweight on the relative residual, scale 4.685 MAD).
    ridge : float
        Tikhonov damping (share of the normal matrix's trace) for the harmonics a photo
        sees over part of the sphere only.
    smooth_px : float
        Gaussian blur of the shading inside the head, pixels.
    face : (H, W) bool, optional
        The face (above the chin): where the albedo's brightness is held to the photo's.
        All the fitted skin when None.

    Returns
    -------
    Lighting
    """
    sub = (slice(None, None, stride), slice(None, None, stride))
    luma = photo[sub].astype(np.float32) @ _LUMA.astype(np.float32)
    skin = head_mask[sub] & ((weight if weight.shape == luma.shape else weight[sub]) > 0.5)
    sel = skin & (luma > 8) & (luma < 250)  # neither black nor burnt out
    if sel.sum() < 200:
        raise InputError(f"only {int(sel.sum())} pixels of skin to fit the photo's lighting to", where="de-lighting",
                         fix="check the head's fit to the photo, or keep the photo's lighting (--keep-lighting)")
    # Contiguous planes: faster arithmetic.
    nx, ny, nz = cv2.split(np.asarray(normals, np.float32)) if isinstance(normals, np.ndarray) else normals
    B = sh_basis(np.stack([nx[sub][sel], ny[sub][sel], nz[sub][sel]], axis=1))
    y = luma[sel].astype(np.float64)
    w = np.ones(len(y))
    damp = np.diag([0.0] + [1.0] * 8)
    # The 9 x 9 normal matrix is a weighted sum of the pixels' products of two harmonics:
    # the 45 distinct products once, then one (45,) sum a pass (einsum's own loop; a
    # threaded BLAS product waits on its threads whenever the cores are busy).
    iu = np.triu_indices(9)
    Bt = np.ascontiguousarray(B.T)
    products = np.empty((len(iu[0]), len(B)))  # (45, K), row by row in triu_indices' order
    start = 0
    for i in range(9):
        np.multiply(Bt[i], Bt[i:], out=products[start:start + 9 - i])
        start += 9 - i
    for _ in range(iterations):
        A = np.zeros((9, 9))
        A[iu] = np.einsum("pk,k->p", products, w)
        A = A + np.triu(A, 1).T
        c = np.linalg.solve(A + ridge * np.trace(A) / 9 * damp, np.einsum("ik,k->i", Bt, w * y))
        fit = B @ c
        r = y / np.maximum(fit, 1e-6) - 1.0
        kept = r[w > 0]
        s = 1.4826 * np.median(np.abs(kept - np.median(kept))) + 1e-6
        u = r / (4.685 * s)
        w = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
    fitted = B @ c
    peak = float(np.percentile(fitted[w > 0], 99.5))
    if not peak > 0:
        raise InputError("the fitted lighting is dark everywhere", where="de-lighting",
                         fix="keep the photo's lighting (--keep-lighting)")
    k = (c / peak).astype(np.float32)
    full = (k[0] - k[8] + nx * (k[1] + k[4] * ny + k[5] * nz + k[7] * nx) + ny * (k[2] + k[6] * nz - k[7] * ny)
            + nz * (k[3] + 3 * k[8] * nz))
    # The normals come from an 8-bit render: smooth their quantisation steps out of the
    # shading (which is smooth anyway) within the head, so that they do not band the albedo.
    full[~head_mask] = 0.0
    full = cv2.GaussianBlur(full, (0, 0), smooth_px) / \
        np.maximum(cv2.GaussianBlur(head_mask.astype(np.float32), (0, 0), smooth_px), 1e-3)
    trust = head_mask & (full >= MIN_SHADING)
    clamped = np.clip(full, MIN_SHADING, 1.25)
    mean = float(clamped[sub][skin].mean()) if skin.any() else 1.0
    # Scaled so that the albedo keeps the photo's median skin brightness where the face is
    # seen squarely (the skin the fit kept that faces the camera within 45°, above the chin:
    # the cheeks and forehead, not the sides seen edge-on nor the neck, which faces the
    # camera too but lies in the chin's shadow and under collars): a shading whose mean is
    # 1 does so only under an even light, and under a strong one the lit cheeks come out
    # dark and grey.
    kept = w > 0
    facing = kept & (nz[sub][sel] > np.cos(np.radians(45.0)))
    if face is not None:
        facing &= face[sub][sel]
    kept = facing if facing.sum() >= 100 else kept
    ratio = y[kept] / clamped[sub][sel][kept]
    level = float(np.median(ratio) / np.median(y[kept])) if kept.any() else 1.0 / mean
    shading = np.where(head_mask, clamped * level, np.float32(1.0)).astype(np.float32)
    return Lighting(c, peak, shading, trust, int(sel.sum()), float(np.mean(w > 0)), mean)


def judge(photo: np.ndarray, albedo: np.ndarray, light: Lighting, skin: np.ndarray) -> str | None:
    """Why a de-lit photo must not be used, or None when it may.

    Parameters
    ----------
    photo, albedo : (H, W, 3) uint8
        The photo and the photo divided by ``light``'s shading (or the same sample of their
        pixels, e.g. every third each way).
    light : Lighting
    skin : (H, W) bool
        The skin the light was fitted to.
    """
    if light.mean < MIN_MEAN_SHADING:
        return (f"the fitted light leaves most of the face in deep shadow (mean shading {light.mean:.2f} of its "
                "brightest), which is not a light a photo is taken in")
    if skin.any():
        burnt = (albedo[skin].max(axis=1) >= 254) & (photo[skin].max(axis=1) < 250)
        if burnt.mean() > MAX_BURNT:
            return f"taking the light out would burn {burnt.mean():.0%} of the skin out to white"
    return None


def delight_photo(head: Head, photo: np.ndarray, camera: Camera, mask: np.ndarray | None = None,
                  normals: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, Lighting]:
    """A photo of the fitted head with its lighting taken out.

    Parameters
    ----------
    head : Head
        Fitted to the person (the photo's feature points).
    photo : (H, W, 3) uint8
    camera : Camera
        The photo's fitted camera.
    mask : (N,) float, optional
        The skin vertices to fit (:func:`fit_mask` by default).
    normals : ((H, W, 3) uint8, (H, W) float64), optional
        :func:`normal_image` of the head with this camera, if already rendered.

    Returns
    -------
    albedo : (H, W, 3) uint8
        The photo divided by the fitted shading where the head is, unchanged elsewhere;
        the photo as it is when :func:`judge` refuses the result.
    lighting : Lighting
        ``fallback`` says why the photo was kept, or None.
    """
    encoded, depth = normal_image(head, camera) if normals is None else normals
    head_mask = np.isfinite(depth)
    if not head_mask.any():
        raise InputError("the head does not show in the photo", where="de-lighting",
                         fix="check the photo's camera")
    # Only the head's box and the shading blur's reach are worked on (the shading is 1
    # elsewhere), its corner on the fit's grid so that the same pixels are fitted.
    reach = int(np.ceil(4 * _SMOOTH_PX)) + 1  # OpenCV's Gaussian kernel reaches 4 σ
    bx, by, bw, bh = cv2.boundingRect(head_mask.astype(np.uint8))
    h, w = head_mask.shape
    x0, y0 = max(0, bx - reach) // _STRIDE * _STRIDE, max(0, by - reach) // _STRIDE * _STRIDE
    x1, y1 = min(w, bx + bw + reach), min(h, by + bh + reach)
    box = np.s_[y0:y1, x0:x1]
    weight = skin_weight(head, camera, fit_mask(head) if mask is None else mask, _STRIDE, (x0, y0, x1, y1))
    crop = photo[box]
    face = None
    if "2.1" in head.feature_points:
        chin = float(camera.project(head.fp_position("2.1")[None])[0, 1]) - y0
        face = np.broadcast_to((np.arange(y1 - y0) < chin)[:, None], (y1 - y0, x1 - x0))
    light = fit_lighting(crop, _normal_planes(encoded[box], head_mask[box]), head_mask[box], weight, face=face)
    # Rounded and saturated to bytes by OpenCV (the quotient is never negative, so its
    # absolute value is itself).
    albedo = cv2.convertScaleAbs(cv2.divide(crop.astype(np.float32), cv2.merge([light.shading] * 3)))
    sub = np.s_[::_STRIDE, ::_STRIDE]
    light.fallback = judge(crop[sub], albedo[sub], light, head_mask[box][sub] & (weight > 0.5))
    # Back to the photo's frame.
    shading, trust = np.ones((h, w), np.float32), np.zeros((h, w), bool)
    shading[box], trust[box] = light.shading, light.trust
    light.shading, light.trust = shading, trust
    if light.fallback is not None:
        return photo.copy(), light
    out = photo.copy()
    out[box] = albedo
    return out, light


def burnt_pixels(photo: np.ndarray, albedo: np.ndarray, person: np.ndarray, band: float = EDGE_BAND,
                 grow_px: int = 2) -> np.ndarray:
    """(H, W) bool: the pixels along the person's outline that the de-lighting burnt out to
    white (as :func:`judge` counts them: the albedo's largest channel saturated where the
    photo's was not), grown by ``grow_px`` into the glow around them.

    The fitted head's normals are the model's, not the person's: where a fitted neck
    overhangs the photo's, the shading divides skin seen at a grazing angle, or the wall
    beside it, by too little. The texture's fill beyond the outline then spread that white
    along the neck (a real profile: a glowing band down the back of the neck), so the
    caller fills these from the skin further in, as it fills what lies past the outline.
    Inside the face a burnt pixel is left as it is (a highlight: filling those changed the
    skin model a front photo alone paints the head's sides with, and its colour).

    Parameters
    ----------
    photo, albedo : (H, W, 3) uint8
        The photo and its de-lit version.
    person : (H, W) bool
        Where the photo shows the person's head.
    band : float
        Width of the band inside the outline looked at, as a share of the outline's
        bounding box's smaller side (:data:`EDGE_BAND`).
    grow_px : int
    """
    burnt = person & (albedo.max(axis=2) >= 254) & (photo.max(axis=2) < 250)
    if not burnt.any():
        return burnt
    _, _, bw, bh = cv2.boundingRect(person.astype(np.uint8))
    r = max(1, int(round(band * min(bw, bh))))
    inner = cv2.erode(person.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    burnt &= inner == 0
    if grow_px > 0 and burnt.any():
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * grow_px + 1, 2 * grow_px + 1))
        burnt = person & (cv2.dilate(burnt.astype(np.uint8), k) > 0)
    return burnt
