"""``recon build``: shape, texture and export of one head from two annotated photos, or one.

:func:`build_head` is the computation: the generic head fitted to the feature points
(:func:`recon.shape.fit.fit_head`), the photos' cameras recovered from them
(:func:`recon.texture.cameras.fit_camera`), the skin textured from both photos
(:func:`recon.texture.texture_skin`), the other parts given textures of their own, and
optionally the whole re-packed into a clean atlas (:func:`recon.texture.atlas.repack`). Shape and
texture may come from different photo pairs (Lee et al. 2.3.1): the texture is laid out on
the head fitted to its own pair, and carried to the shape's head, which has the same
topology. From a front photo alone the depth comes from the identity model
(:func:`recon.shape.fit.fit_head_front`) and the sides of the texture from a skin model
(:mod:`recon.texture.skin_model`); ``head.fdp.json`` records that the depth is estimated.

:func:`run_build` is what the command runs: it reads the photos and annotations, builds,
and writes the bundle (:mod:`recon.bundle`) — ``head.glb``, ``head.obj`` + ``head.mtl`` +
``texture.png``, ``head.fdp.json`` (3D feature points, their texture coordinates, FAPU, the
annotations and the provenance: inputs, options, version) and ``preview.png`` (renders
beside the input photos). The bundle appears whole or not at all (:func:`recon.publish.publish`): written in
a hidden folder, which then takes the output folder's place in one step, or, where the
output folder holds other files, is moved in once complete (a run killed meanwhile is
completed by the next); a failed or interrupted run leaves the previous bundle as it was.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head
from mpeg4.io import read_fdp_json

from .shape.calibrate import DEFAULT_IPD_MM
from .texture.cameras import FittedCamera, check_view_cameras, fit_camera, fit_view_camera
from .shape.fit import attach_photo_sizes, fit_head, fit_head_front, has_side, require_views
from .publish import publish
from .bundle import BuildResult, PhotoPair, _write_bundle
from .detection import DETECTED_NAME, correction_hint, detect_for_build
from .photos import (MAX_PHOTO_PIXELS, check_photo, photo_focal_px, photo_scale, photo_size, photos_focal_px,
                     read_photo, view_at_size)

# PhotoPair and BuildResult live in recon.bundle (which writes them) and are re-exported here.
__all__ = ["PhotoPair", "BuildResult", "load_pair", "build_head", "follow_side_outline", "run_build",
           "DEFAULT_TEXTURE_SIZE"]

#: Texture size (pixels, square) unless asked otherwise.
DEFAULT_TEXTURE_SIZE = 2048


def load_pair(fdp_path: str | os.PathLike, front: str | os.PathLike | None = None,
              side: str | os.PathLike | None = None, max_pixels: int = MAX_PHOTO_PIXELS) -> PhotoPair:
    """Read an annotation file and its two photos.

    Parameters
    ----------
    fdp_path : path
        The ``*.fdp.json`` with ``front`` and ``side`` views, or a ``front`` view alone.
    front, side : path, optional
        The photos; by default the ``image`` each view records, relative to the file. A
        side photo given needs points marked on it.
    max_pixels : int
        Photos larger than this are read smaller, both by one factor
        (:func:`recon.photos.photo_scale`), and the points with them.
    """

    fdp_path = os.fspath(fdp_path)
    fdp = read_fdp_json(fdp_path)
    given = {"front": front, "side": side}
    names = ("front", "side") if side is not None or has_side(fdp) else ("front",)
    paths = {}
    for name, view in require_views(fdp, fdp_path, names).items():
        p = given[name]
        if p is None:
            if not view.image:
                raise InputError(f"the {name} view names no photo", where=f"{fdp_path}, views.{name}.image",
                                 fix=f"give the {name} photo on the command line")
            p = Path(view.image)
            if not p.is_absolute():
                p = Path(fdp_path).resolve().parent / p
        paths[name] = os.fspath(p)
    sizes = {n: photo_size(p, f"{n} photo") for n, p in paths.items()}
    for n, size in sizes.items():
        check_photo(size, paths[n])
    attach_photo_sizes(fdp, sizes, fdp_path, paths)
    scale = photo_scale(sizes.values(), max_pixels)
    images = {n: read_photo(p, f"{n} photo", scale) for n, p in paths.items()}
    given = None
    if scale < 1:
        given = dict(fdp.views)
        for n, im in images.items():
            fdp.views[n] = view_at_size(fdp.views[n], im.shape[1], im.shape[0])
    paths["fdp"] = fdp_path
    return PhotoPair(images["front"], images.get("side"), fdp, paths, scale, given)


def build_head(shape: PhotoPair, texture: PhotoPair | None = None, ipd_mm: float = DEFAULT_IPD_MM,
               focal_px: float | None = None, method: str = "dffd", texture_size: int = DEFAULT_TEXTURE_SIZE,
               atlas: bool = False, blend: str = "opencv", generic: Head | None = None,
               keep_lighting: bool = False, progress: Callable[[str], None] | None = None,
               height_tol_mm: float = 8.0, follow_profile: bool = True) -> BuildResult:
    """A textured head from annotated photos.

    Parameters
    ----------
    shape : PhotoPair
        The photos and annotations the head's shape comes from.
    texture : PhotoPair, optional
        Those the texture comes from (the same pair by default).
    ipd_mm, focal_px, method
        See :func:`recon.shape.fit.fit_head` (they apply to both pairs; ``focal_px`` in the
        photo files' pixels, scaled with each pair's photos).
    texture_size : int
        Side of the square skin texture, pixels.
    atlas : bool
        Re-pack the texture into a non-overlapping atlas (:func:`recon.texture.atlas.repack`).
    blend : {"opencv", "opencv-detail", "skimage"}
        Implementation of the multiresolution spline (:func:`recon.texture.blend.blend_multiband`).
    generic : Head, optional
        The head to deform (the shipped generic head by default).
    keep_lighting : bool
        Keep the photos' light in the texture. By default it is taken out of each photo
        (:mod:`recon.texture.delight`) and the texture is the skin's albedo, which renderers (the
        previews, game engines) light themselves; a lit texture rendered with a light is
        shaded twice.
    progress : callable, optional
        Called with a short message before each step.
    height_tol_mm : float
        Largest disagreement of a point's height between the photos: reviewed points
        beyond it are an error, unreviewed (detected) ones are left out and listed
        (:func:`recon.shape.calibrate.calibrate`).
    follow_profile : bool
        Move the face's midline between the feature points onto the side photo's outline
        from the brow to the chin (:func:`follow_side_outline`; needs the head segmentation,
        mediapipe), through the side camera the texture then uses.

    Returns
    -------
    BuildResult
    """
    from .texture import texture_skin

    say = progress or (lambda m: None)
    times = {}
    t0 = time.perf_counter()
    def focal(pair):
        return None if focal_px is None else focal_px * pair.scale

    if shape.side is None:
        if texture is not None:
            raise InputError("a texture from another pair needs a shape from two photos", where="recon build",
                             fix="build from the front photo alone without --texture-from")
        return _build_front_only(shape, focal(shape), generic, ipd_mm, method, texture_size, atlas, blend,
                                 keep_lighting, say, t0)
    say("fitting the generic head to the feature points")
    head, cal = fit_head(shape.fdp, generic=generic, ipd_mm=ipd_mm, focal_px=focal(shape), method=method,
                         where=shape.paths.get("fdp", "fdp.json"), height_tol_mm=height_tol_mm)
    if cal.dropped:
        say(f"left out {len(cal.dropped)} detected points whose heights disagree between the photos by more than "
            f"{height_tol_mm:g} mm: " + ", ".join(f"{i} ({d['disagreement_mm']:+.1f} mm, {d['view']} photo"
                                               f"{'s' if d['view'] == 'both' else ''})" for i, d in cal.dropped.items())
            + "; check them with recon annotate")
    if cal.yaw_deg:
        say(f"the face in the front photo is turned {abs(cal.yaw_deg):.0f} degrees to its "
            f"{'left' if cal.yaw_deg > 0 else 'right'}: taken out using the side photo's depths")
    side_cam = None
    if follow_profile:
        head, side_cam = follow_side_outline(head, shape.fdp, shape.side, cal, focal(shape),
                                             shape.paths.get("fdp", "fdp.json"), say)
    tex_pair = texture or shape
    tex_head = head
    if texture is not None:
        say("fitting the generic head to the texture's photos")
        tex_head, tex_cal = fit_head(texture.fdp, generic=generic, ipd_mm=ipd_mm, focal_px=focal(texture),
                                     method=method, where=texture.paths.get("fdp", "fdp.json"),
                                     height_tol_mm=height_tol_mm)
        if follow_profile:
            tex_head, side_cam = follow_side_outline(tex_head, texture.fdp, texture.side, tex_cal, focal(texture),
                                                     texture.paths.get("fdp", "fdp.json"), say)
    times["shape"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    pts = tex_head.fp_positions()
    where = tex_pair.paths.get("fdp", "fdp.json")
    tex_cal = cal if texture is None else tex_cal
    cams = {}
    for name in ("front", "side"):
        view = tex_pair.fdp.views[name]
        if name == "side" and side_cam is not None:
            # Fitted for the profile to the same points (the step moves no feature point).
            cams[name] = side_cam
            continue
        cams[name] = fit_view_camera(pts, view, name, focal(tex_pair), f"{where}, views.{name}", tex_cal,
                                      tex_pair.fdp.metadata.get("reviewed") is False, say)
    check_view_cameras(cams, tex_pair.fdp.views, where)
    skin = texture_skin(tex_head, tex_pair.front, tex_pair.side, cams["front"], cams["side"], size=texture_size,
                        blend=blend, delight=not keep_lighting, progress=say)
    return _finish(head, skin, tex_pair, cams, atlas, texture_size, keep_lighting, times, t0, t1, say)


def follow_side_outline(head: Head, fdp, side_photo: np.ndarray, cal, focal_px: float | None,
                        where: str = "fdp.json", say: Callable[[str], None] | None = None
                        ) -> tuple[Head, FittedCamera | None]:
    """The head's profile moved onto the side photo's outline
    (:func:`recon.shape.outline.match_profile`), through the side camera fitted to the
    head's points as the texture's is (:func:`recon.texture.cameras.fit_view_camera`).

    Parameters
    ----------
    head : Head
        The head fitted to ``fdp``'s points (:func:`recon.shape.fit.fit_head`).
    fdp : FdpFile
        Its annotations (the side view's points, pixels of ``side_photo``).
    side_photo : (H, W, 3) uint8
    cal : Calibration
        What the fit did (the points it dropped stay out of the camera).
    focal_px : float or None
    where : str
        The annotation file, for messages.
    say : callable, optional

    Returns
    -------
    head : Head
        As given when the segmentation (mediapipe) is not installed.
    camera : FittedCamera or None
        The side camera (None when nothing was done).
    """
    from .landmarks import mediapipe_available
    from .shape.outline import match_profile

    say = say or (lambda m: None)
    if not mediapipe_available():
        say("the profile between the feature points is the generic head's: the side photo's outline needs "
            "mediapipe (bash install.sh)")
        return head, None
    from .landmarks.silhouette import head_masks

    camera = fit_view_camera(head.fp_positions(), fdp.views["side"], "side", focal_px, f"{where}, views.side",
                             cal, fdp.metadata.get("reviewed") is False, say)
    check_view_cameras({"side": camera}, fdp.views, where)
    say("moving the profile onto the side photo's outline")
    (mask,) = head_masks([side_photo])
    return match_profile(head, mask, camera.camera, fdp.views["side"].points), camera


def _finish(head, skin, pair, cams, atlas, texture_size, keep_lighting, times, t0, t1, say) -> BuildResult:
    """The textured head, re-packed if asked, with what the build did in its metadata."""
    from .texture import textured_head

    out = textured_head(head, skin, pair.front)
    times["texture"] = time.perf_counter() - t1
    if atlas:
        from .texture.atlas import repack

        t2 = time.perf_counter()
        say("re-packing the texture into an atlas (xatlas)")
        out = repack(out, size=texture_size)
        times["atlas"] = time.perf_counter() - t2
    out.metadata = dict(out.metadata, build=dict(
        camera_residual_px={n: round(c.rms_px, 3) for n, c in cams.items()},
        texture_lighting="photo" if keep_lighting else "albedo",
        texture_side_gain=[round(float(g), 4) for g in skin.side_gain],
        texture_registration_mm=[round(1000 * float(r), 2) if np.isfinite(r) else None for r in skin.registration_m],
        texture_glasses=sorted(skin.glasses),  # the photos whose frames of glasses were inpainted
        texture_regions=out.metadata.get("texture", {}).get("regions")))
    times["total"] = time.perf_counter() - t0
    return BuildResult(out, skin.cameras, skin, times)


def _build_front_only(pair: PhotoPair, focal_px, generic, ipd_mm, method, texture_size, atlas, blend,
                      keep_lighting, say, t0) -> BuildResult:
    """:func:`build_head` for a front photo alone."""
    from .texture import texture_skin

    where = pair.paths.get("fdp", "fdp.json")
    say("fitting the identity model to the front photo's points (no side photo: the depth is estimated)")
    head, ff = fit_head_front(pair.fdp, generic=generic, ipd_mm=ipd_mm, focal_px=focal_px, method=method,
                              where=where)
    if ff.dropped:
        say(f"left out {len(ff.dropped)} detected points the fitted face misses by far: "
            + ", ".join(f"{i} ({d['miss_mm']:.0f} mm)" for i, d in ff.dropped.items()) + "; check them in the annotations")
    if ff.focal_from == "estimated":
        say(f"focal length estimated from the face: {ff.focal_px:.0f} px")
    times = {"shape": time.perf_counter() - t0}
    t1 = time.perf_counter()
    view = pair.fdp.views["front"]
    pts = head.fp_positions()
    pixels = {i: p for i, p in view.points.items() if ff.source.get(i) == "front"}
    cams = {"front": fit_camera(pts, pixels, view.width, view.height, focal_px=ff.focal_px,
                                where=f"{where}, views.front")}
    check_view_cameras(cams, pair.fdp.views, where)
    skin = texture_skin(head, pair.front, None, cams["front"], None, size=texture_size, blend=blend,
                        delight=not keep_lighting, progress=say)
    return _finish(head, skin, pair, cams, atlas, texture_size, keep_lighting, times, t0, t1, say)


def run_build(front: str | os.PathLike | None, side: str | os.PathLike | None, fdp: str | os.PathLike | None,
              out_dir: str | os.PathLike, ipd_mm: float = DEFAULT_IPD_MM, focal_px: float | None = None,
              method: str = "dffd", texture_size: int = DEFAULT_TEXTURE_SIZE, atlas: bool = False,
              shape_from: str | os.PathLike | None = None, texture_from: str | os.PathLike | None = None,
              keep_lighting: bool = False, progress: Callable[[str], None] | None = None, result: list | None = None,
              created: str | None = None, provenance: dict | None = None,
              height_tol_mm: float = 8.0, side_facing: str | None = None) -> dict[str, Path]:
    """``recon build``: write the textured head bundle.

    Parameters
    ----------
    front, side : path or None
        The photos (with ``fdp``); None to take them from the annotation file. Without a
        side photo (and no side view in ``fdp``) the head is built from the front photo
        alone, its depth estimated (:func:`build_head`).
    fdp : path or None
        Annotations of the photos. Give either ``fdp`` or ``shape_from`` (and optionally
        ``texture_from``), or neither with the photos: the points are then detected
        (:func:`recon.detection.detect_annotations`) and written to
        ``OUT/annotations.fdp.json``, kept when the build fails, for a person to correct.
        A side photo whose edge cuts the face's profile off
        (:class:`recon.landmarks.side.ProfileCutOff`) is then left out with a warning, and
        the head built from the front photo alone (``side_photo_not_used`` in the
        provenance).
    out_dir : path
        The bundle's folder (created). A previous bundle is replaced whole, only once the
        new one is complete (:func:`recon.publish.publish`); other files there are kept.
    ipd_mm, focal_px, method, texture_size, atlas, keep_lighting, height_tol_mm
        See :func:`build_head`. Without ``focal_px``, the focal length the photos record
        in their EXIF (:func:`recon.photos.photos_focal_px`), else orthographic cameras.
    shape_from, texture_from : path, optional
        Shape–texture separation: the shape from one annotated pair, the texture from
        another (each file names its photos, or ``front``/``side`` give the shape's).
    progress : callable, optional
    result : list, optional
        If given, the :class:`BuildResult` is appended to it (for callers that go on with
        the head).
    created : str, optional
        The provenance's time stamp (see :func:`recon.bundle.build_time`; set it, or
        ``SOURCE_DATE_EPOCH``, for byte-identical ``head.fdp.json`` files across runs).
    provenance : dict, optional
        More entries for the provenance (``recon batch`` adds the manifest row).
    side_facing : {"left", "right"}, optional
        Where the nose points in the side photo, for detection.

    Returns
    -------
    dict of str to Path
    """
    say = progress or (lambda m: None)
    t0 = time.perf_counter()
    if fdp is not None and shape_from is not None:
        raise InputError("both --fdp and --shape-from are given", where="recon build",
                         fix="use --fdp for one pair, or --shape-from with --texture-from for two")
    shape_path = fdp if fdp is not None else shape_from
    if side_facing not in (None, "left", "right"):
        raise InputError(f"--side-facing {side_facing!r} is neither left nor right", where="recon build",
                         fix="give --side-facing left (the nose towards the photo's left) or right")
    detected = None
    if shape_path is None:
        if front is None:
            raise InputError("no photos and no annotations given", where="recon build",
                             fix="give the photos (recon build FRONT [SIDE] -o OUT: the points are detected), or "
                                 "--fdp F.fdp.json")
        say("detecting the feature points")
        detected, side, unused = detect_for_build(front, side, Path(out_dir) / DETECTED_NAME, side_facing, say)
        shape_path = detected
        if unused is not None:
            provenance = {**(provenance or {}), "side_photo_not_used": unused}
        meta = read_fdp_json(detected).metadata.get("landmarks", {})
        for warning in meta.get("warnings", []):
            say(f"warning: {warning}")
        say(f"the detected points are in {detected} (unreviewed)")
    detect_s = time.perf_counter() - t0 if detected is not None else None
    if texture_from is not None and fdp is not None:
        raise InputError("--texture-from goes with --shape-from, not with --fdp", where="recon build",
                         fix="use --shape-from A.fdp.json --texture-from B.fdp.json")
    try:
        paths = _build_into(front, side, shape_path, out_dir, texture_from, ipd_mm, focal_px, method, texture_size,
                            atlas, keep_lighting, height_tol_mm, say, result, created, provenance, t0, detect_s)
    except InputError as e:
        if detected is None:
            raise
        raise InputError(e.what, where=e.where, fix=(e.fix + "; " if e.fix else "")
                         + "the points were detected automatically and are kept: "
                         + correction_hint(front, side, detected)) from None
    if detected is not None:
        paths["annotations"] = detected
        say(correction_hint(front, side, detected))
    return paths


def _build_into(front, side, shape_path, out_dir, texture_from, ipd_mm, focal_px, method, texture_size, atlas,
                keep_lighting, height_tol_mm, say, result, created, provenance, t0, detect_s=None) -> dict[str, Path]:
    """:func:`run_build` once the annotations are known; ``detect_s``: the seconds detection took
    (None: the points were given)."""
    say("reading the photos and annotations")
    shape = load_pair(shape_path, front, side)
    texture = load_pair(texture_from) if texture_from is not None else None
    from .landmarks.roles import check_roles

    for pair in (shape, texture) if texture is not None else (shape,):
        if pair.side is None:
            continue
        for warning in check_roles(pair.front, pair.side, pair.paths.get("front", "front photo"),
                                   pair.paths.get("side", "side photo")):
            say(f"warning: {warning}")
    focal_from = "given" if focal_px is not None else None
    if focal_px is None and shape.side is None:
        focal_px, note = photo_focal_px(shape.paths["front"])
        focal_from = "exif" if focal_px is not None else None
        say(note if focal_px is not None else "no focal length recorded in the front photo: estimated from the face")
    elif focal_px is None:
        focal_px, note = photos_focal_px(shape.paths["front"], shape.paths["side"])
        focal_from = "exif" if focal_px is not None else None
        say(note)
    res = build_head(shape, texture, ipd_mm=ipd_mm, focal_px=focal_px, method=method,
                     texture_size=texture_size, atlas=atlas, keep_lighting=keep_lighting, progress=say,
                     height_tol_mm=height_tol_mm)
    fit = res.head.metadata.get("fit", {})
    if shape.side is None and focal_from is None:
        focal_px, focal_from = fit.get("focal_px"), fit.get("focal_from")
    options = {"ipd_mm": ipd_mm, "focal_px": focal_px, "focal_from": focal_from, "method": method,
               "photos": "front and side" if shape.side is not None else "front only (depth estimated)",
               "height_tol_mm": height_tol_mm,
               "texture_size": texture_size, "keep_lighting": keep_lighting,
               "atlas": atlas, "shape_texture_separation": texture is not None}
    def write(folder: Path) -> dict[str, Path]:
        written = _write_bundle(res, shape, texture, options, folder, say, created, provenance)
        return {key: p for key, p in written.items() if p.exists()}

    t_export = time.perf_counter()
    final = publish(out_dir, write)
    res.timings["export"] = time.perf_counter() - t_export
    if detect_s is not None:
        res.timings["detection"] = detect_s
    res.timings["total"] = time.perf_counter() - t0
    if result is not None:
        result.append(res)
    split = ", ".join(f"{k} {res.timings[k]:.1f} s" for k in ("detection", "shape", "texture", "atlas", "export")
                      if k in res.timings)
    say(f"done in {res.timings['total']:.1f} s ({split})")
    return final
