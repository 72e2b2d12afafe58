"""How faithfully a built head gives back its photo: re-projection PSNR and SSIM, and the
seams' smoothness.

:func:`reprojection` renders the textured head with the front photo's camera, unlit (the
texture already holds the photo's light), and compares it with the photo inside the face
— the front region's outline (:func:`recon.texture.feature_polygon`), where both the
render and the photo show the head, shrunk by a few pixels so that silhouettes do not
count. :func:`side_reprojection` does the same with the side photo's camera over all the
skin the side photo sees, and gives the mean colour difference over the skin in front of
the ear that the texture takes from the front photo (which sees it at a grazing angle).
:func:`seam_smoothness` measures the mean gradient in a band across the borders
between the texture's layers for the multiresolution spline and for the two blends it
replaces (a hard cut and a feathered edge).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head
from recon.texture.cameras import FittedCamera

__all__ = ["Fidelity", "SideFidelity", "AlbedoError", "albedo_error", "cheek_vertices", "face_mask", "psnr",
           "reprojection", "side_reprojection", "seam_smoothness"]


@dataclass
class Fidelity:
    """Re-projection figures of one head.

    Attributes
    ----------
    psnr_db : float
        Peak signal-to-noise ratio inside the face (RGB, 8 bits).
    ssim : float
        Mean structural similarity inside the face (grey levels, 7 x 7 windows).
    pixels : int
        Size of the face region compared.
    """

    psnr_db: float
    ssim: float
    pixels: int


def face_mask(head: Head, front: FittedCamera, shape: tuple[int, int], shrink: int = 4) -> np.ndarray:
    """(H, W) bool: inside the front region's outline in the photo, shrunk by ``shrink``
    pixels."""
    from recon.texture import feature_line, feature_polygon

    pts = head.fp_positions()
    skin = head.skin
    lines = [feature_line(pts, skin.vertices, skin.triangles, s)[0] for s in ("L", "R")]
    poly = feature_polygon(front, *lines)
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round(poly * 256).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=8)
    if shrink:
        mask = cv2.erode(mask, np.ones((2 * shrink + 1, 2 * shrink + 1), np.uint8))
    return mask > 0


def reprojection(head: Head, photo: np.ndarray, front: FittedCamera, photo_mask: np.ndarray | None = None,
                 shrink: int = 4, light: tuple | None = None) -> Fidelity:
    """Render ``head`` with the front camera and compare it with ``photo`` in the face,
    where the skin is what the camera sees.

    Parameters
    ----------
    head : Head
        Textured.
    photo : (H, W, 3) uint8
        The front photo the texture came from.
    front : FittedCamera
    photo_mask : (H, W) bool, optional
        Where the head is in the photo (all of it when None).
    shrink : int
        Pixels taken off the region's rim.
    light : (direction, ambient), optional
        Render lit so (:func:`mpeg4.render.render`'s ``light`` and ``ambient``): the
        photo's light, for a de-lit (albedo) texture. Unlit (ambient 1) when None, for a
        texture that keeps the photo's light.
    """
    image, skin_seen = _render_skin(head, front, light=light)
    region = face_mask(head, front, photo.shape[:2], shrink) & skin_seen
    if photo_mask is not None:
        region &= cv2.erode(photo_mask.astype(np.uint8), np.ones((2 * shrink + 1,) * 2, np.uint8)) > 0
    if light is not None:
        image = matched_gain(image, photo, region)
    db, ssim = _compare(image, photo, region)
    return Fidelity(db, ssim, int(region.sum()))


def _render_skin(head: Head, cam: FittedCamera, vertex_colours: np.ndarray | None = None,
                 light: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The head rendered unlit or with ``light`` = (direction, ambient) (or its skin with
    vertex colours, unlit), and (H, W) bool where the surface seen is the skin, shrunk by
    a pixel."""
    from mpeg4.preview import head_meshes
    from mpeg4.render import render

    meshes = head_meshes(head)
    names = list(head.parts)
    skin = [m for m, n in zip(meshes, names) if n == "skin"]
    if vertex_colours is not None:
        skin[0].vertex_colours = vertex_colours
        skin[0].texture = None
        skin[0].colour = (1.0, 1.0, 1.0)
    lit = {"ambient": 1.0} if light is None or vertex_colours is not None else \
        {"light": light[0], "ambient": float(light[1])}
    image, depth = render(meshes, cam.camera, return_depth=True, samples=4, **lit)
    # Only where the skin is the surface seen (the eyes and teeth have textures of their own).
    skin_only = render(skin, cam.camera, return_depth=True, samples=0)[1]
    both = np.isfinite(depth) & np.isfinite(skin_only)
    gap = np.full(depth.shape, np.inf)
    gap[both] = np.abs(skin_only[both] - depth[both])
    skin_seen = gap < 1e-4
    return image, cv2.erode(skin_seen.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0


def matched_gain(image: np.ndarray, photo: np.ndarray, region: np.ndarray) -> np.ndarray:
    """``image`` times the one gain that brings its luma to the photo's over ``region``
    (the median ratio).

    A de-lit texture is the albedo up to the light's intensity, which no photo tells (the
    de-lighting keeps the photo's mean skin colour): re-lit with the photo's known light it
    matches the photo up to that one number, and only what is left is the texture's error.
    """
    luma = np.array([0.299, 0.587, 0.114])
    a = image[region].astype(np.float64) @ luma
    b = photo[region].astype(np.float64) @ luma
    ok = a > 4
    gain = float(np.median(b[ok] / a[ok])) if ok.any() else 1.0
    return np.clip(np.round(image.astype(np.float64) * gain), 0, 255).astype(np.uint8)


def psnr(image: np.ndarray, photo: np.ndarray, region: np.ndarray) -> float:
    """PSNR (dB, RGB, 8 bits) of an image against a photo over a region ((H, W) bool)."""
    diff = image[region].astype(np.float64) - photo[region].astype(np.float64)
    return float(10 * np.log10(255.0 ** 2 / max(float(np.mean(diff ** 2)), 1e-12)))


def _compare(image: np.ndarray, photo: np.ndarray, region: np.ndarray) -> tuple[float, float]:
    """PSNR (dB, RGB) and mean SSIM (grey, 7 x 7 windows) of an image against a photo in a region."""
    from skimage.metrics import structural_similarity

    value = psnr(image, photo, region)
    ys, xs = np.nonzero(region)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    a = cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_RGB2GRAY)
    b = cv2.cvtColor(np.ascontiguousarray(photo[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    _, smap = structural_similarity(a, b, data_range=255, win_size=7, full=True)
    return value, float(smap[region[y0:y1, x0:x1]].mean())


@dataclass
class SideFidelity:
    """Re-projection figures of one head in its side photo.

    Attributes
    ----------
    psnr_db, ssim : float
        Over all the skin the side photo sees.
    pixels : int
        Size of that region.
    side_layer_psnr_db : float
        Over the skin the texture takes from the side photo (its seen-side layer).
    cheek_rgb : (3,) float
        Mean colour of the render minus the photo (grey levels, RGB) over the cheek
        (:func:`cheek_vertices`), whichever photo the texture takes it from.
    cheek_pixels : int
    cheek_gradient : (2,) float
        Mean squared horizontal and vertical intensity gradients (Sobel, grey levels²) of the
        render over the cheek, each divided by the photo's own there. Skin the front photo
        sees edge-on smears into horizontal streaks: the vertical gradient above the photo's,
        the horizontal one below it.
    """

    psnr_db: float
    ssim: float
    pixels: int
    side_layer_psnr_db: float
    cheek_rgb: np.ndarray
    cheek_pixels: int
    cheek_gradient: np.ndarray

    @property
    def cheek_grey(self) -> float:
        """The cheek's mean difference in grey levels (Rec. 601 luma of ``cheek_rgb``)."""
        return float(np.dot(self.cheek_rgb, (0.299, 0.587, 0.114)))

    @property
    def cheek_streaks(self) -> float:
        """How much more the render's cheek varies along the vertical than along the
        horizontal than the photo's does: ``cheek_gradient[1] / cheek_gradient[0]``; 1 when
        the texture keeps the photo's texture, above 1 for horizontal streaks."""
        return float(self.cheek_gradient[1] / self.cheek_gradient[0])


def cheek_vertices(head: Head, side: FittedCamera, facing_deg: float = 45.0) -> np.ndarray:
    """(N,) bool over the head's skin vertices: the cheek and jaw in front of the ear, which
    the front photo sees at a grazing angle.

    Skin ahead of the feature lines down the front of the ears
    (:func:`recon.texture.lines.feature_line`), outside the outer eye corners (3.7, 3.12:
    not the side of the nose), between their height and that of the jaw's angles (2.13,
    2.14), whose normal is within ``facing_deg`` of the direction to the side camera
    (either side of the face). Defined by the head's shape alone, so that textures laid out
    differently are compared over the same skin.
    """
    from recon.texture.lines import feature_line, line_depth

    part = head.parts["skin"]
    pts = head.fp_positions()
    v = part.vertices
    missing = [k for k in ("3.7", "3.12", "2.13", "2.14") if k not in pts]
    if missing:
        raise InputError(f"the head has no feature point {', '.join(missing)}", where="cheek_vertices",
                         fix="give a head with the eye corners and the jaw's angles marked")
    lines = [feature_line(pts, v, part.triangles, k)[0] for k in ("L", "R")]
    ahead = v[:, 2] >= line_depth(lines[0], lines[1], v[:, 1])
    top = 0.5 * (pts["3.7"][1] + pts["3.12"][1])
    bottom = 0.5 * (pts["2.13"][1] + pts["2.14"][1])
    outside = np.abs(v[:, 0]) > 0.5 * (abs(pts["3.7"][0]) + abs(pts["3.12"][0]))
    return ahead & outside & (v[:, 1] < top) & (v[:, 1] > bottom) & _facing(part, side, facing_deg)


def side_reprojection(head: Head, skin, photo: np.ndarray, side: FittedCamera, photo_mask: np.ndarray | None = None,
                      shrink: int = 4, facing_deg: float = 45.0, light: tuple | None = None) -> SideFidelity:
    """Render ``head`` with the side camera and compare it with the side photo over the
    skin the photo sees, and over the cheek in front of the ear (:func:`cheek_vertices`).

    Parameters
    ----------
    head : Head
        Textured with ``skin``.
    skin : recon.texture.SkinTexture
        Its texture's layout (which region each skin vertex samples).
    photo : (H, W, 3) uint8
        The side photo the texture came from.
    side : FittedCamera
    photo_mask : (H, W) bool, optional
        Where the head is in the photo (all of it when None).
    shrink : int
        Pixels taken off the regions' rims.
    facing_deg : float
        The cheek's skin faces the side camera within this angle.
    light : (direction, ambient), optional
        Render lit so, as :func:`reprojection`.
    """
    from recon.texture import SEEN

    part = head.parts["skin"]
    if len(part.vertices) != len(skin.vertex_region):
        raise InputError(f"the head's skin has {len(part.vertices)} vertices, the texture was laid out for "
                         f"{len(skin.vertex_region)}", where="side_reprojection",
                         fix="give the head textured with this texture (recon.texture.textured_head)")
    image, skin_seen = _render_skin(head, side, light=light)
    region = skin_seen.copy()
    if photo_mask is not None:
        region &= cv2.erode(photo_mask.astype(np.uint8), np.ones((2 * shrink + 1,) * 2, np.uint8)) > 0
    if light is not None:
        image = matched_gain(image, photo, region)
    db, ssim = _compare(image, photo, region)
    # The cheek and the side layer: rendered as white patches on black, shrunk off their rims.
    patches = {}
    for name, sel in (("cheek", cheek_vertices(head, side, facing_deg)), ("side", skin.vertex_region == SEEN)):
        image_sel, _ = _render_skin(head, side, np.repeat(sel.astype(np.float64)[:, None], 3, axis=1))
        k = np.ones((2 * shrink + 1,) * 2, np.uint8)
        patches[name] = (cv2.erode((image_sel[..., 0] > 250).astype(np.uint8), k) > 0) & region
    cheek_px = patches["cheek"]
    if cheek_px.any():
        d = (image[cheek_px].astype(np.float64) - photo[cheek_px].astype(np.float64)).mean(axis=0)
        gradient = _gradient_energy(image, cheek_px) / _gradient_energy(photo, cheek_px)
    else:
        d, gradient = np.full(3, np.nan), np.full(2, np.nan)
    side_psnr = psnr(image, photo, patches["side"]) if patches["side"].any() else float("nan")
    return SideFidelity(db, ssim, int(region.sum()), side_psnr, d, int(cheek_px.sum()), gradient)


def _gradient_energy(image: np.ndarray, region: np.ndarray) -> np.ndarray:
    """(2,) mean squared horizontal and vertical Sobel gradients of the image's grey levels
    over the region (grey levels² per pixel²)."""
    g = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
    return np.array([float(np.mean(cv2.Sobel(g, cv2.CV_32F, dx, 1 - dx, ksize=3)[region] ** 2)) for dx in (1, 0)])


def _facing(part, cam: FittedCamera, facing_deg: float) -> np.ndarray:
    """(N,) bool: the part's vertices whose normal is within ``facing_deg`` of the direction
    to the camera (either side)."""
    from mpeg4.render import vertex_normals

    v = part.vertices
    n = vertex_normals(v, part.triangles)
    return np.abs(np.sum(n * cam.camera.towards(v), axis=1)) >= np.cos(np.radians(facing_deg))


@dataclass
class AlbedoError:
    """How far a built texture's colours are from the skin's true albedo.

    Attributes
    ----------
    mae : dict of str to float
        Mean absolute colour error (grey levels, mean over RGB) per region: ``face`` (all
        the skin compared), ``front`` (the front region but the cheek), ``cheek``
        (:func:`cheek_vertices`, whichever photo the texture takes it from), ``side`` (the
        seen side's layer), ``mirrored``.
    bias : dict of str to float
        Mean luma of texture minus truth per region (negative: darker than the albedo).
    cheek_minus_front : float
        ``bias["cheek"] - bias["front"]``: the step in brightness the texture makes
        between the face's front and its cheek that the albedo does not.
    left_right : float
        Mean absolute luma error of the face's left-right difference: over front-region
        vertex pairs mirrored across the midline, |(texture_L − texture_R) − (truth_L −
        truth_R)|.
    vertices : dict of str to int
        Vertices compared per region.
    """

    mae: dict
    bias: dict
    cheek_minus_front: float
    left_right: float
    vertices: dict


def albedo_error(head: Head, skin, truth: np.ndarray, side: FittedCamera, blur_px: float | None = None,
                 skin_tone: np.ndarray | None = None, tone_tol: float = 45.0, albedo_gain: bool = False) -> AlbedoError:
    """Compare a built skin texture with the skin's true albedo at its vertices.

    Parameters
    ----------
    head : Head
        Textured with ``skin`` (its skin's first vertices are the originals).
    skin : recon.texture.SkinTexture
    truth : (N, 3) float
        True albedo (RGB, 0–255) per original skin vertex (:func:`recon.evaluate.synthetic.skin_albedo`).
    side : FittedCamera
        The side photo's camera (for the cheek: see :func:`cheek_vertices`).
    blur_px : float, optional
        Gaussian blur of the texture before sampling, texels (size / 512 by default: the
        truth's blur at the scale of the face).
    skin_tone : (3,) float, optional
        Only vertices whose true colour is within ``tone_tol`` (RGB distance) of it are
        compared: the skin, not the hair, brows, lips or lashes.
    albedo_gain : bool
        Compare up to one gain (the median luma ratio over the face), for a de-lit texture:
        its level is the photo's mean skin colour, the albedo's only up to the light's
        intensity (see :func:`matched_gain`).
    """
    from scipy.ndimage import map_coordinates
    from scipy.spatial import cKDTree

    from recon.texture import FRONT, MIRRORED, SEEN

    part = head.parts["skin"]
    tex = part.texture.astype(np.float32)
    size = tex.shape[0]
    blur = size / 512 if blur_px is None else blur_px
    if blur:
        tex = cv2.GaussianBlur(tex, (0, 0), blur)
    uv = skin.uv
    x = (uv[:, 0] * size - 0.5).astype(np.float32)
    y = ((1.0 - uv[:, 1]) * size - 0.5).astype(np.float32)
    got = np.stack([map_coordinates(tex[..., c], [y, x], order=1, mode="nearest") for c in range(3)],
                   axis=1).astype(np.float64)
    want = np.asarray(truth, np.float64)[skin.source]
    ok = np.all(np.isfinite(want), axis=1)
    if skin_tone is not None:
        ok &= np.linalg.norm(want - np.asarray(skin_tone, float), axis=1) < tone_tol
    cheek = cheek_vertices(head, side)
    r = skin.vertex_region
    face = ok & np.isin(r, (FRONT, SEEN, MIRRORED))
    regions = {"face": face, "front": ok & (r == FRONT) & ~cheek, "cheek": face & cheek, "side": ok & (r == SEEN),
               "mirrored": ok & (r == MIRRORED)}
    luma = np.array([0.299, 0.587, 0.114])
    if albedo_gain and regions["face"].any():
        a, b = got[regions["face"]] @ luma, want[regions["face"]] @ luma
        keep = a > 4
        got = got * (float(np.median(b[keep] / a[keep])) if keep.any() else 1.0)
    d = got - want
    mae = {k: float(np.abs(d[m]).mean()) if m.any() else float("nan") for k, m in regions.items()}
    bias = {k: float((d[m] @ luma).mean()) if m.any() else float("nan") for k, m in regions.items()}
    # Left-right: front-region originals paired with the vertex nearest their mirror image.
    n0 = len(truth)
    orig = np.flatnonzero((ok & (r == FRONT))[:n0])
    v = part.vertices[orig]
    left = orig[v[:, 0] > 0.005]
    right = orig[v[:, 0] < -0.005]
    lr = float("nan")
    if len(left) and len(right):
        dist, k = cKDTree(part.vertices[right]).query(part.vertices[left] * [-1.0, 1.0, 1.0])
        pair = dist < 0.002
        a, b = left[pair], right[k[pair]]
        lr = float(np.abs((got[a] - got[b]) @ luma - (want[a] - want[b]) @ luma).mean())
    return AlbedoError(mae, bias, bias["cheek"] - bias["front"], lr, {k: int(m.sum()) for k, m in regions.items()})


def seam_smoothness(layers, masks, band: int = 8) -> dict[str, float]:
    """Mean gradient magnitude (grey levels per pixel) across the layers' borders, for the
    multiresolution spline, a hard cut and a feathered edge (16 px), on the same layers."""
    from recon.texture.blend import blend_feather, blend_hard, blend_multiband, seam_band, seam_gradient

    where = seam_band(masks, band)
    return {"multiband": seam_gradient(blend_multiband(layers, masks), where),
            "hard": seam_gradient(blend_hard(layers, masks), where),
            "feather": seam_gradient(blend_feather(layers, masks), where)}
