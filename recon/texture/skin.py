"""A seamless texture from a front and a side photo, and texture coordinates for the head.

Texture generation and fitting after Lee and Magnenat-Thalmann (sections 2.2.1–2.2.2):

1. The front photo is kept as it is. Its frame (front-photo pixels) is the *composite*
   frame every layer is brought to.
2. The side photo is deformed so that its **feature line** — the feature points from the
   top of the skull down to the chin, :data:`FEATURE_LINE` — lands on the same line in the
   front photo, and what lies behind the line unrolls outwards at the front photo's scale
   (:class:`FeatureLineWarp`, a piecewise-affine warp over a triangulation of the feature
   points and of points placed behind and in front of them). The flipped side photo,
   deformed the same way along the mirrored line, stands for the other side of the head.
3. The three layers are merged by a Burt–Adelson multiresolution spline
   (:func:`blend_multiband`): each layer's Laplacian pyramid is blended with the Gaussian
   pyramid of its mask and the result collapsed, so that the seams along the feature
   lines vanish at every scale instead of showing as an edge or a ghost.
4. Every skin vertex is projected onto the front, seen-side or mirrored-side plane,
   chosen by the **view lines** (:func:`~recon.texture.lines.view_line`: the feature
   line above the brow's end, below it the line where the two photos see the skin
   equally squarely, so that the cheek the front photo sees edge-on comes from the side
   photo; the feature lines themselves with a front photo alone) — inside the polygon
   they bound and seen by the front camera: front; elsewhere by the side of the midline
   it lies on — carried into the
   composite frame by the same warp and made a texture coordinate
   (:func:`texture_skin`). Triangles take the region of most of their corners; vertices
   shared by triangles of different regions are duplicated, so that each corner samples its
   own layer. Vertices neither photo can see inside the face (the mouth and eye sockets)
   sample a small patch painted as the inside of the mouth.

The photos' cameras come from the head's 3D feature points and the marked pixels
(:mod:`recon.texture.cameras`); what the head covers in each photo from rendering it
(:mod:`mpeg4.render`), which also tells which vertices each camera sees. A shirt over the
neck is painted as the skin around it (:mod:`recon.texture.clothes`) before the light is
fitted (a shirt in the fit skews the light found for the face); once the light is taken
out, the side photo is brought to the front photo's colour (:mod:`recon.texture.exposure`)
and the frames of glasses are inpainted out of the skin (:mod:`recon.texture.glasses`).

References
----------
W.-S. Lee and N. Magnenat-Thalmann, "Fast head modeling for animation", Image and Vision
Computing 18(4), 2000, sections 2.2.1–2.2.2.
P. J. Burt and E. H. Adelson, "A multiresolution spline with application to image
mosaics", ACM Transactions on Graphics 2(4), 1983.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head
from mpeg4.render import vertex_normals

from .bake import fill_empty
from .blend import blend_multiband
from .cameras import FittedCamera
from .clothes import remove_clothes
from .delight import fit_mask
from .exposure import apply_gain, side_gain
from .glasses import remove_glasses
from .lines import feature_line, line_depth, view_line
from .regions import (FOLD, FRONT, HIDDEN, MIRRORED, REGIONS, SEEN, _depth, _folds, _head_meshes, _seen_from_around,
                      _seen_in_box, _visible, feature_polygon, split_by_region, triangle_regions, vertex_regions)
from .warp import FeatureLineWarp

__all__ = ["SkinTexture", "photo_background", "texture_skin", "textured_head"]

_HIDDEN_RGB = (96, 40, 44)  # the inside of the mouth
#: How well feature points are placed in a photo, as a share of the eye separation (the
#: automatic points' accuracy on the clean and hard synthetic sets, 1.5–2 %).
LANDMARK_ACCURACY = 0.02

@dataclass
class SkinTexture:
    """The skin's texture and its layout.

    Attributes
    ----------
    texture : (S, S, 3) uint8
        Row 0 at the top.
    uv : (V', 2) float64
        Texture coordinates of the split skin's vertices (t = 0 at the bottom).
    source : (V',) int64
        Original skin vertex of each split vertex (the first N are the originals).
    triangles : (M, 3) int64
        The skin's triangles over the split vertices.
    triangle_region, vertex_region : (M,), (V',) int8
        :data:`REGIONS` index of each triangle and split vertex.
    cameras : dict of str to FittedCamera
        ``front``, ``side`` and ``mirrored`` (the flipped side photo's).
    layers, masks : list of (S, S, 3) uint8, list of (S, S) bool
        The front, seen-side and mirrored-side layers in texture space and where each is
        used (for the seam measurements).
    timings : dict of str to float
        Seconds per step.
    seen_sign : float
        +1 if the side photo shows the face's left, -1 its right.
    lighting : dict of str to recon.texture.delight.Lighting
        The lighting fitted to the ``front`` and ``side`` photos and taken out of them
        (empty when the texture keeps the photos' light).
    side_gain : (3,) float
        The per-channel gains the side photo was scaled by to match the front photo's skin
        (:mod:`recon.texture.exposure`; ones with a front photo alone, and when both photos
        keep their light).
    registration_m : (float, float)
        How far the front and the side photo's pixels may land from the skin they belong to
        (:meth:`recon.texture.cameras.FittedCamera.registration_m`), metres: the view lines
        weigh the photos by it. NaN with a front photo alone.
    glasses : dict of str to recon.texture.glasses.Glasses
        The frames of glasses inpainted out of each photo (empty: no glasses).
    """

    texture: np.ndarray
    uv: np.ndarray
    source: np.ndarray
    triangles: np.ndarray
    triangle_region: np.ndarray
    vertex_region: np.ndarray
    cameras: dict[str, FittedCamera]
    layers: list[np.ndarray] = field(repr=False, default_factory=list)
    masks: list[np.ndarray] = field(repr=False, default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    seen_sign: float = 1.0
    lighting: dict = field(repr=False, default_factory=dict)
    side_gain: np.ndarray = field(default_factory=lambda: np.ones(3))
    registration_m: tuple[float, float] = (float("nan"), float("nan"))
    glasses: dict = field(repr=False, default_factory=dict)


def photo_background(photo: np.ndarray, tol: float = 14.0, border: int = 6) -> np.ndarray:
    """(H, W) bool: the plain backdrop of a photo, connected to its left and right borders.

    Each row's backdrop colour is the median of its ``border`` outermost pixels on both
    sides (a wall that darkens towards the floor still counts); a pixel within ``tol``
    (RGB distance) of its row's colour belongs to the backdrop when it is connected to
    the border through such pixels, so a face of a similar tone is never taken for it.
    Busy backgrounds yield little backdrop; then the head's rendered silhouette alone
    bounds what the texture takes from the photo.
    """
    img = np.asarray(photo)
    h, w = img.shape[:2]
    b = max(1, min(border, w // 4))
    edge = np.concatenate([img[:, :b], img[:, -b:]], axis=1)
    ref = np.median(edge, axis=1).astype(np.float32)  # (H, 3)
    # Channel by channel on contiguous planes (a row's colour broadcast along it): several
    # times faster than broadcasting over (H, W, 3).
    dist2 = np.zeros((h, w), np.float32)
    for k, plane in enumerate(cv2.split(np.ascontiguousarray(img))):
        d = plane.astype(np.float32)
        d -= ref[:, k:k + 1]
        d *= d
        dist2 += d
    close = dist2 < tol * tol
    n, labels = cv2.connectedComponents(close.astype(np.uint8), connectivity=4)
    touching = np.zeros(n, bool)  # a look-up per label (np.isin sorts the whole image)
    touching[np.r_[labels[:, 0], labels[:, -1]]] = True
    touching[0] = False
    return touching[labels] & close


def _fill_outside(photo: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The photo with what lies outside ``valid`` filled from inside (push–pull at half
    resolution, which is all a smooth fill needs; the valid pixels keep their values)."""
    h, w = valid.shape
    half = cv2.resize(photo, ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA)
    vhalf = cv2.resize(valid.astype(np.uint8), ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_NEAREST) > 0
    filled = cv2.resize(fill_empty(half, vhalf), (w, h), interpolation=cv2.INTER_LINEAR)
    return cv2.copyTo(photo, valid.astype(np.uint8), filled)  # (numpy's masked copy is far slower)


def texture_skin(head: Head, front_photo: np.ndarray, side_photo: np.ndarray | None, front: FittedCamera,
                 side: FittedCamera | None, size: int = 2048, blend: str = "opencv", levels: int | None = None,
                 delight: bool = True, progress: Callable[[str], None] | None = None) -> SkinTexture:
    """Build the skin's texture from the two photos and give every skin vertex a texture
    coordinate.

    Parameters
    ----------
    head : Head
        The head fitted to the person (its feature points give the feature lines).
    front_photo, side_photo : (H, W, 3) uint8
        The photos, RGB, row 0 at the top. Without a side photo (None) the sides come from
        a skin model fitted to the face (:mod:`recon.texture.skin_model`).
    front, side : FittedCamera
        Their cameras (:func:`recon.texture.cameras.fit_camera` on the head's feature
        points); ``side`` is None with no side photo.
    size : int
        Texture size in pixels (square).
    blend : {"opencv", "opencv-detail", "skimage"}
        Implementation of the multiresolution spline (:func:`blend_multiband`).
    levels : int, optional
        Pyramid levels of the blend.
    delight : bool
        Take each photo's lighting out before texturing (:func:`recon.texture.delight.delight_photo`):
        the texture is then the skin's albedo, to be lit by whoever renders it. False keeps
        the photos' light in the texture.
    progress : callable, optional
        Called with a short message before each step.

    Returns
    -------
    SkinTexture
    """
    say = progress or (lambda m: None)
    times = {}
    t0 = time.perf_counter()
    for name, photo in (("front", front_photo), ("side", side_photo)):
        if photo is None and name == "side":
            continue
        if photo.ndim != 3 or photo.shape[2] != 3 or photo.dtype != np.uint8:
            raise InputError(f"the {name} photo is {photo.shape} {photo.dtype}, expected (H, W, 3) uint8",
                             where="texture", fix="load it as RGB")
    if size < 64:
        raise InputError(f"texture size {size} is too small", where="texture", fix="use at least 256")
    skin = head.skin
    V = skin.vertices
    pts = head.fp_positions()
    skin_normals = vertex_normals(V, skin.triangles)
    skin_to_fit = fit_mask(head)  # the skin whose colour is skin (no hair, brows, lips, eyes)
    front_only = side_photo is None
    if front_only:
        from .skin_model import virtual_side_camera

        side = virtual_side_camera(V, front.camera.width, front.camera.height)
    mirrored = side.flipped()
    cams = {"front": front, "side": side, "mirrored": mirrored}
    # Which side of the face the side photo shows: the side its camera stands on.
    c = side.camera
    toward = c.centre if c.perspective else c.rotation[2]
    seen_sign = 1.0 if toward[0] >= 0 else -1.0

    say("finding what each photo shows of the head")
    photos = {"front": front_photo} if front_only else {"front": front_photo, "side": side_photo}
    meshes = _head_meshes(head)
    normals = {}
    if delight:  # the de-lighting's normal images carry the depth: one render per photo
        from .delight import normal_image

        normals = {key: normal_image(head, cams[key].camera) for key in photos}
    depth = {k: normals[k][1] if k in normals else _depth(meshes, cams[k].camera) for k in photos}
    seen = {k: _visible(V, cams[k].camera, depth[k]) if k in depth else _seen_in_box(V, meshes, cams[k].camera)
            for k in cams}  # no photo, no image: the depth over the head's box only
    anywhere = seen["front"] | seen["side"] | seen["mirrored"]
    anywhere[~anywhere] = _seen_from_around(head, V[~anywhere])
    times["visibility"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    registration = (float("nan"), float("nan"))
    if front_only:  # the front photo gives all it can, up to the ears
        lines = {k: feature_line(pts, V, skin.triangles, k) for k in ("L", "R")}
    else:
        # A side photo registered worse than the front one gives less of the cheek. The
        # points are placed to about 2 % of the eye separation (benchmarks/
        # landmark_accuracy.py): residuals below that say nothing of either camera.
        centre = V.mean(axis=0)
        floor = LANDMARK_ACCURACY * (head.fapu.ES0 if head.fapu is not None else 0.063)
        registration = (front.registration_m(centre, floor), side.registration_m(centre, floor))
        lines = {k: view_line(pts, V, skin.triangles, k, *d, normals=skin_normals, registration=registration)
                 for k, d in _towards(V, front, side).items()}
    polygon = feature_polygon(front, lines["L"][0], lines["R"][0])
    front_px = front.project(V)
    depth_of_line = line_depth(lines["L"][0], lines["R"][0], V[:, 1])
    vregion = vertex_regions(V, polygon, front_px, depth_of_line, anywhere, seen_sign)
    tregion = triangle_regions(vregion, skin.triangles)
    tregion = _folds(V, skin.triangles, tregion, vregion)
    source, tris, region = split_by_region(skin.triangles, tregion, vregion, len(V))
    seen_line = lines["L" if seen_sign > 0 else "R"]
    other_line = lines["R" if seen_sign > 0 else "L"]
    outline = (V, skin.triangles)
    warps = {SEEN: FeatureLineWarp(side, front, *seen_line, seen_sign, outline),
             MIRRORED: FeatureLineWarp(mirrored, front, *other_line, -seen_sign, outline)}
    comp = np.zeros((len(source), 2))
    sv = V[source]
    m = region == FRONT
    comp[m] = front.project(sv[m])
    for r, cam in ((SEEN, side), (MIRRORED, mirrored)):
        m = region == r
        if m.any():
            comp[m] = warps[r].forward(cam.project(sv[m]))
    # Folds take the place of the nearest skin of the front region (the lids' creases, the
    # lips' inner rims and the nostrils are all in the face).
    fold = region == FOLD
    if fold.any():
        from scipy.spatial import cKDTree

        donors = np.flatnonzero(region == FRONT)
        donors = donors if len(donors) else np.flatnonzero(~fold & (region != HIDDEN))
        _, near = cKDTree(sv[donors]).query(sv[fold])
        comp[fold] = comp[donors[near]]
    hidden = region == HIDDEN
    # The texture frame: every coordinate in use, plus a margin, scaled into the square.
    used = comp[~hidden] if (~hidden).any() else comp
    lo, hi = used.min(axis=0), used.max(axis=0)
    pad = 0.03 * (hi - lo).max()
    lo, hi = lo - pad, hi + pad
    scale = (size - 1) / (hi - lo)
    A = np.array([[scale[0], 0, -lo[0] * scale[0]], [0, scale[1], -lo[1] * scale[1]], [0, 0, 1.0]])
    tex_px = comp * scale + A[:2, 2]
    patch = max(4, size // 64)  # the hidden vertices' patch, in the bottom-left corner
    tex_px[hidden] = (patch / 2.0, size - 1 - patch / 2.0)
    uv = np.c_[(tex_px[:, 0] + 0.5) / size, 1.0 - (tex_px[:, 1] + 0.5) / size]
    times["layout"] = time.perf_counter() - t1

    head_masks = {}
    for key, photo in photos.items():
        d = depth[key]
        if d.shape != photo.shape[:2]:
            raise InputError(f"the {key} photo is {photo.shape[1]}x{photo.shape[0]} but its camera is "
                             f"{d.shape[1]}x{d.shape[0]}", where="texture", fix="fit the camera to this photo")
        # The backdrop is found in the photo as taken (de-lit, it would no longer match its
        # border); where the selfie segmentation runs, only the person counts (a block wall's
        # mortar lines or a busy room beside a skull the fitted head overhangs is not hair).
        head_mask = _person(photo, np.isfinite(d) & ~photo_background(photo))
        head_masks[key] = cv2.erode(head_mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        if not head_masks[key].any():
            raise InputError(f"the head does not show in the {key} photo", where="texture",
                             fix="check the feature points of that photo")
    # The neck under the collar, not the shirt: filled before the light is fitted, so that
    # a shirt does not weigh on the fit (the fill carries the neck's own shading down).
    for key in list(photos):
        photos[key], covered = remove_clothes(head, photos[key], head_masks[key], cams[key].camera, seen[key],
                                              normals=skin_normals, skin=skin_to_fit > 0, depth=depth[key])
        if covered > 0.01:
            say(f"the {key} photo shows clothes over {100 * covered:.0f} % of the head: filled from the neck's "
                f"skin around them")
    lighting = {}
    if delight:
        from .delight import burnt_pixels, delight_photo

        say("taking the photos' lighting out (spherical-harmonic shading fit)")
        t = time.perf_counter()
        for key, photo in list(photos.items()):
            photos[key], lighting[key] = delight_photo(head, photo, cams[key].camera, skin_to_fit, normals[key])
            if lighting[key].fallback:
                say(f"warning: the {key} photo keeps its light: {lighting[key].fallback}")
            else:  # filled below as the backdrop is, not spread along the outline
                head_masks[key] &= ~burnt_pixels(photo, photos[key], head_masks[key])
        times["delight"] = time.perf_counter() - t

    gain = np.ones(3)
    # One skin tone on both sides of the seam, the front photo's: de-lit, the photos still
    # differ in exposure and white balance, and one of them may keep its light when the
    # other could be de-lit. A texture that keeps both photos' light keeps each as taken
    # (a gain between lit photos measures their shading as much as their exposure).
    if not front_only and any(light.fallback is None for light in lighting.values()):
        gain = _side_gain(V, skin_normals, skin_to_fit > 0, photos, seen, front, side, seen_sign)
        photos["side"] = apply_gain(photos["side"], gain)

    # The frames of glasses, out of the skin (the lenses cannot be: their tint stays).
    photos, glasses = remove_glasses(head, photos, {k: cams[k].camera for k in photos}, seen, skin_normals,
                                     skin_to_fit > 0)
    if glasses:
        say("warning: the photos show glasses: their frames are inpainted from the skin around them, but the "
            "lenses' tint and glare stay in the texture (photos without glasses give a cleaner one)")

    say(f"warping the photos into a {size}x{size} texture")
    t2 = time.perf_counter()
    fill = {key: _fill_outside(photos[key], head_masks[key]) for key in photos}
    layers = [cv2.warpAffine(fill["front"], A[:2], (size, size), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_REPLICATE)]
    grid = max(1, size // 256)  # the warps are piecewise affine: a coarse map, linearly refined
    coarse = (int(np.ceil(size / grid)) + 1,) * 2
    G = np.linalg.inv(A) @ np.diag([grid, grid, 1.0])  # coarse grid pixel → composite pixel
    for photo in () if front_only else (fill["side"], cv2.flip(fill["side"], 1)):
        warp = warps[SEEN] if len(layers) == 1 else warps[MIRRORED]
        cmap = warp.inverse_map(G, coarse)
        # Texel (x, y) sits at (x / grid, y / grid) on the coarse map: an affine resampling
        # (the same bilinear weights as a remap, without building its two full-size maps),
        # the two coordinates apart (OpenCV is far faster on one channel than on two).
        fine = np.array([[1.0 / grid, 0.0, 0.0], [0.0, 1.0 / grid, 0.0]])
        fx, fy = (cv2.warpAffine(np.ascontiguousarray(cmap[..., k]), fine, (size, size),
                                 flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP) for k in range(2))
        layers.append(cv2.remap(photo, fx, fy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))
    times["warp"] = time.perf_counter() - t2

    say("blending the three layers (multiresolution spline)")
    t3 = time.perf_counter()
    masks = _layer_masks(A, polygon, pts, front, size, seen_sign)
    if front_only:
        layers += _skin_model_layers(layers[0], masks, front_photo, head_masks["front"], front, pts, A)
    texture = blend_multiband(layers, masks, levels=levels, method=blend)
    texture[size - patch:, :patch] = _HIDDEN_RGB
    times["blend"] = time.perf_counter() - t3
    times["total"] = time.perf_counter() - t0
    return SkinTexture(texture, uv, source, tris, tregion, region, cams, layers, masks, times, seen_sign, lighting,
                       gain, registration, glasses)


def _side_gain(V: np.ndarray, n: np.ndarray, skin: np.ndarray, photos: dict, seen: dict, front: FittedCamera,
               side: FittedCamera, seen_sign: float) -> np.ndarray:
    """(3,) gains for the side photo (:func:`recon.texture.exposure.side_gain`) from the skin
    vertices ``V`` (normals ``n``; ``skin``: those whose colour is skin) on its side of the
    face that both cameras see within 60° of their normal and about equally squarely: along
    the seam, where a light that stands by each camera (a flash, a lamp behind the
    photographer) also falls alike, so the gain is the photos' exposure and not their
    shading."""
    toward_front, toward_side = _towards(V, front, side)["L" if seen_sign > 0 else "R"]
    square = np.cos(np.radians(60.0))
    usable = (skin & seen["front"] & seen["side"] & (V[:, 0] * seen_sign > 0)
              & (n @ toward_front >= square) & (n @ toward_side >= square)
              & (np.abs(n @ toward_front - n @ toward_side) <= 0.2))
    return side_gain(photos["front"], photos["side"], front.project(V), side.project(V), usable)


def _towards(vertices: np.ndarray, front: FittedCamera, side: FittedCamera) -> dict[str, tuple]:
    """For each side of the face (``"L"``: x > 0), the unit directions from the head towards
    the front camera and towards the side camera on that side (the side photo's, or its
    mirror image for the other side)."""
    centre = vertices.mean(axis=0, keepdims=True)
    f, s = front.camera.towards(centre)[0], side.camera.towards(centre)[0]
    return {key: (f, s if s[0] * sign > 0 else s * (-1.0, 1.0, 1.0)) for key, sign in (("L", 1.0), ("R", -1.0))}


def _skin_model_layers(front_layer, masks, photo, head_mask, front: FittedCamera, pts, A) -> list[np.ndarray]:
    """The two side layers of a texture from a front photo alone, painted by the skin model
    (:mod:`recon.texture.skin_model`); ``masks`` change in place: what the photo does not
    show of the person (``head_mask``: past its edge, the backdrop beside an overhanging
    skull) goes to the skin model too."""
    from .skin_model import fit_skin_model, skin_model_layer

    size = front_layer.shape[0]
    # Where the photo shows the person, in texture space: nothing past the photo's edge
    # (its border row repeated would streak), no wall (it is not skin).
    seen = cv2.warpAffine(head_mask.astype(np.uint8), A[:2], (size, size),
                          flags=cv2.INTER_NEAREST, borderValue=0) > 0
    masks[1] |= masks[0] & ~seen
    masks[0] &= seen

    def row(ids):
        found = [i for i in ids if i in pts]
        if not found:
            return None
        px = front.project(np.array([pts[i] for i in found]))
        return float(np.mean(px[:, 1]) * A[1, 1] + A[1, 2])

    model = fit_skin_model(front_layer, masks[0], seen, hair_row=row(("10.9", "10.10")), chin_row=row(("2.1",)))
    layer = skin_model_layer(model)
    return [layer, layer]


def _person(photo: np.ndarray, head_mask: np.ndarray) -> np.ndarray:
    """Where the photo shows the head: the rendered head less the backdrop, and, where the
    selfie segmentation can run, only the person (a busy wall beside a head the fitted
    skull overhangs is not hair)."""
    from recon.landmarks.models import mediapipe_available

    if not mediapipe_available():
        return head_mask
    from recon.landmarks.models import person_mask

    return head_mask & (person_mask(photo) > 0.5)


def _layer_masks(A: np.ndarray, polygon: np.ndarray, pts, front: FittedCamera, size: int,
                 seen_sign: float) -> list[np.ndarray]:
    """Front inside the feature polygon; outside it, the seen side's layer on its half of the
    frame (split by the line through the top of the skull and the chin), the mirrored
    layer on the other."""
    poly = (np.c_[polygon, np.ones(len(polygon))] @ A.T)[:, :2]
    front_mask = np.zeros((size, size), np.uint8)
    cv2.fillPoly(front_mask, [np.round(poly * 256).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=8)
    front_mask = front_mask > 0
    top, chin = (np.r_[front.project(np.asarray(pts[i])[None])[0], 1.0] @ A.T for i in ("11.4", "2.1"))
    slope = (top[0] - chin[0]) / (top[1] - chin[1]) if abs(top[1] - chin[1]) > 1e-9 else 0.0
    # Front photos show the face's left on the image's right.
    rows = np.arange(size, dtype=np.float64)
    right_half = np.arange(size)[None, :] > (chin[0] + (rows - chin[1]) * slope)[:, None]
    seen_mask = ~front_mask & (right_half if seen_sign > 0 else ~right_half)
    mirrored_mask = ~front_mask & ~seen_mask
    return [front_mask, seen_mask, mirrored_mask]


def textured_head(head: Head, skin: SkinTexture, front_photo: np.ndarray, seed: int = 0) -> Head:
    """The head with the skin's texture applied and the other parts given textures of
    their own: the eyes with the iris and sclera colours of the front photo (sampled at the
    pupils 3.5 and 3.6 and towards the eyes' corners, the photo's shading taken out),
    teeth, gums and tongue made by :mod:`recon.texture.materials` and lit as the open
    mouth lets light in (:mod:`recon.texture.mouth`).

    Parameters
    ----------
    head : Head
        The head the texture was built for, or another head of the same topology (shape
        from one photo pair, texture from another).
    skin : SkinTexture
    front_photo : (H, W, 3) uint8
    seed : int
        For the mottles of the mouth's textures.
    """
    from mpeg4.seams import split_vertices

    from . import materials, mouth

    if head.skin.n_vertices != len(skin.vertex_region) - (len(skin.source) - len(np.unique(skin.source))) \
            or skin.source.max() >= head.skin.n_vertices:
        raise InputError(f"the texture was laid out for a skin of {int(skin.source.max()) + 1} vertices, "
                         f"this head's has {head.skin.n_vertices}", where="texture",
                         fix="texture a head of the same topology")
    out = split_vertices(head, "skin", skin.source, skin.triangles, uv=skin.uv, texture=skin.texture)
    out.parts["skin"].colour = (1.0, 1.0, 1.0)
    for name, (pupil, iris, white) in _eye_colours(out, skin, front_photo).items():
        part = out.parts[name]
        gaze = pupil - part.centre if part.centre is not None else np.array([0.0, 0.0, 1.0])
        centre = part.centre if part.centre is not None else part.vertices.mean(axis=0)
        part.uv = materials.eye_uv(part.vertices, centre, gaze)
        part.texture = materials.eye_texture(256, tuple(np.clip(iris, 0, 255)), tuple(np.clip(white, 0, 255)))
        part.colour = (1.0, 1.0, 1.0)
    # The mouth's parts are lit as the open mouth lets light in, found on the head before
    # its skin was split (its topology is the generic head's, whose tables open the jaw).
    light = mouth.brightest_light([mouth.open_pose(head), mouth.bared_pose(head)],
                                  {name: p.triangles for name, p in head.parts.items()})
    out = mouth.mouth_textures(out, light, seed)
    out.metadata = dict(out.metadata, texture={"regions": {r: int((skin.triangle_region == k).sum())
                                                           for k, r in enumerate(REGIONS)},
                                               "size": int(skin.texture.shape[0]),
                                               "seams_duplicated_vertices": int(len(skin.source)
                                                                                - head.skin.n_vertices)})
    return out


def _eye_colours(head: Head, skin: SkinTexture, front_photo: np.ndarray) -> dict:
    """``{eye part: (pupil (3,) metres, iris RGB (3,), white RGB (3,))}`` from the front photo.

    The photo's colours with its light taken out as the skin's was (its shading), so the
    eyes sit in the skin as the photo has them: a fixed paper-white sclera stared out of
    darker real faces. Both eyes get one white: where a lowered lid hides one, the other's.
    """
    from . import materials

    front = skin.cameras["front"]
    light = skin.lighting.get("front") if skin.lighting else None
    shading = (light.shading if light is not None and light.fallback is None
               and light.shading.shape == front_photo.shape[:2] else None)
    eye_pts = {"eye_l": ("3.5", "3.7", "3.11"), "eye_r": ("3.6", "3.8", "3.12")}
    found = {}
    for name, (fp, *corners) in eye_pts.items():
        if name not in head.parts or fp not in head.feature_points:
            continue
        pupil = head.fp_position(fp)
        at = front.project(pupil[None])[0]
        px_per_m = np.linalg.norm(front.project((pupil + [0.001, 0, 0])[None])[0] - at) / 0.001
        lit = 1.0 if shading is None else float(shading[int(np.clip(at[1], 0, shading.shape[0] - 1)),
                                                        int(np.clip(at[0], 0, shading.shape[1] - 1))])
        ends = [front.project(head.fp_position(c)[None])[0] for c in corners if c in head.feature_points]
        white = materials.sclera_colour(front_photo, at, ends, 0.0058 * px_per_m)
        found[name] = (pupil, materials.iris_colour(front_photo, at, 0.0058 * px_per_m) / lit,
                       None if white is None else white / lit)
    whites = [w for _, _, w in found.values() if w is not None]
    white = np.mean(whites, axis=0) if whites else np.asarray(materials.SCLERA_RGB, float)
    return {name: (pupil, iris, white) for name, (pupil, iris, _) in found.items()}
