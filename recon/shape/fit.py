"""Fit the generic head to a person: annotated photos → 3D feature points → deformed head.

:func:`fit_head` is the computation (annotations in, head out); :func:`run_fit` is what
``recon fit`` runs: it reads the photos' sizes and the ``fdp.json``, fits, and writes the
head bundle (``head.glb``, ``head.fdp.json``, ``preview.png``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head

from .calibrate import DEFAULT_IPD_MM, Calibration, calibrate
from .deform import deform_head
from .identity import POINT_SD_MM

#: Spread (mm) of detected 3D points about what the identity model can express.
DETECTED_SD_MM = 4.0

__all__ = ["fit_head", "fit_head_front", "has_side", "under_hair", "run_fit", "image_size", "attach_photo_sizes",
           "require_views"]


def image_size(path: str | os.PathLike) -> tuple[int, int]:
    """(width, height) in pixels of a photo as displayed (EXIF orientation applied)."""
    from recon.photos import photo_size

    return photo_size(path)


def require_views(fdp, where: str, names=("front", "side")) -> dict:
    """The ``front`` and ``side`` views (or those ``names``) of an annotation file, refusing
    one with no points."""
    views = {}
    for name in names:
        view = fdp.views.get(name)
        if view is None or not view.points:
            raise InputError(f"no feature points for the {name} photo", where=f"{where}, views",
                             fix=f"annotate the {name} photo (recon annotate)")
        views[name] = view
    return views


def attach_photo_sizes(fdp, sizes: dict[str, tuple[int, int]], where: str, photos: dict[str, str] | None = None):
    """Check that each view's annotations were made on a photo of this size, and record it.

    Parameters
    ----------
    fdp : mpeg4.io.fdp_json.FdpFile
        Changed in place: each view's ``width`` and ``height`` are set.
    sizes : dict of str to (width, height)
        ``front`` and ``side`` photo sizes.
    where : str
        The annotation file's name, for errors.
    photos : dict of str to str, optional
        The photos' paths, for errors.
    """
    for name, (w, h) in sizes.items():
        view = fdp.views.get(name)
        if view is None:
            continue
        if view.width and view.height and (view.width, view.height) != (w, h):
            photo = (photos or {}).get(name, f"the {name} photo")
            raise InputError(f"the {name} annotations were made on a {view.width}x{view.height} image but "
                             f"{photo} is {w}x{h}", where=where,
                             fix="annotate this photo, or give the photo the annotations were made on")
        view.width, view.height = w, h


def fit_head(fdp, generic: Head | None = None, ipd_mm: float = DEFAULT_IPD_MM, focal_px: float | None = None,
             method: str = "dffd", where: str = "fdp.json", height_tol_mm: float = 8.0,
             drop_outliers: bool | None = None, identity_prior: bool = True,
             neutral_lids: bool = True) -> tuple[Head, Calibration]:
    """The generic head deformed to the feature points annotated on two photos.

    Parameters
    ----------
    fdp : mpeg4.io.fdp_json.FdpFile
        With ``front`` and ``side`` views (pixels; image sizes when known).
    generic : Head, optional
        The head to deform; the shipped generic head by default.
    ipd_mm, focal_px, height_tol_mm
        See :func:`recon.shape.calibrate.calibrate`.
    method : {"dffd", "rbf"}
        See :func:`recon.shape.deform.deform_head`.
    where : str
        Name of the annotation file, for error messages.
    drop_outliers : bool, optional
        Leave out points whose heights disagree (see :func:`recon.shape.calibrate.calibrate`)
        instead of failing; by default when the points are unreviewed (``fdp.metadata
        ["reviewed"]`` is False: automatic detection nobody has checked), weighted by
        their confidences.
    identity_prior : bool
        Start the deformation from the identity model's head fitted to the 3D points
        (:func:`identity_start`) rather than from the generic head itself.
    neutral_lids : bool
        Pose the start's lids as open as the photos show them
        (:func:`recon.shape.lids.neutral_lids`) before the deformation; recorded in
        ``metadata["fit"]["lids"]``.

    Returns
    -------
    head : Head
        The person's head; ``metadata["fit"]`` records the assumptions.
    calibration : Calibration
    """
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    views = require_views(fdp, where)
    size = {n: (v.width, v.height) if v.width and v.height else None for n, v in views.items()}
    try:
        if drop_outliers is None:
            drop_outliers = fdp.metadata.get("reviewed") is False
        cal = calibrate(views["front"].points, views["side"].points, generic, ipd_mm=ipd_mm, focal_px=focal_px,
                        front_size=size["front"], side_size=size["side"], height_tol_mm=height_tol_mm,
                        confidence={n: v.confidence for n, v in views.items()}, drop_outliers=drop_outliers,
                        under_hair=under_hair(fdp))
    except InputError as e:
        raise InputError(e.what, where=f"{where}, {e.where}" if e.where else where, fix=e.fix) from None
    goal = {i: p for i, p in cal.points.items() if cal.source[i] != "generic"}
    # Detected points nobody checked spread wider than marked ones (a few millimetres).
    spread = DETECTED_SD_MM if drop_outliers else POINT_SD_MM
    start, coefficients = identity_start(generic, goal, spread) if identity_prior else (generic, None)
    start, pinned, lids = _pose_lids(start, goal, views["front"].points, neutral_lids)
    head = _settle_lids(deform_head(start, pinned, method=method), goal, lids)
    head.metadata = dict(head.metadata, fit=dict(
        cal.assumptions, start="identity model" if coefficients is not None else "generic head",
        roll_deg=round(cal.roll_deg, 3), yaw_deg=round(cal.yaw_deg, 3), side_facing=cal.side_facing,
        visible_side=cal.visible_side, point_sources=cal.source,
        height_residual_mm={k: round(v, 3) for k, v in cal.height_residual_mm.items()}, dropped_points=cal.dropped,
        lids=_lids_built(head, lids)))
    return head, cal


def under_hair(fdp) -> set[str]:
    """The skull points whose outline the detection found to be hair in either photo
    (``metadata["landmarks"]["under_hair"]``, see :mod:`recon.shape.hair`)."""
    found = (fdp.metadata.get("landmarks") or {}).get("under_hair") or {}
    return {i for view in ("front", "side") for i in (found.get(view) or ())}


def _pose_lids(start: Head, goal: dict, front: dict, pose: bool) -> tuple[Head, dict, dict | None]:
    """The start with its lids posed as the front photo's points show them
    (:func:`recon.shape.lids.neutral_lids`) when ``pose``; the goal the deformation then
    pins; what was done."""
    if not pose:
        return start, goal, None
    from .lids import neutral_lids

    return neutral_lids(start, goal, front)


def _settle_lids(head: Head, goal: dict, record: dict | None) -> Head:
    """:func:`recon.shape.lids.settle_lids` after a deformation that started from posed lids."""
    if not record:
        return head
    from .lids import settle_lids

    return settle_lids(head, goal, record)


def _lids_built(head: Head, record: dict | None) -> dict:
    """``metadata["fit"]["lids"]``: per eye, what :func:`recon.shape.lids.neutral_lids` did,
    with the built head's lid heights (``built``, in eye widths, as the photo's are
    measured) and the margins' distance in height (``opening_mm``, IRISD0 for the left eye)."""
    from .lids import lid_heights, lid_opening_mm

    heights, opening = lid_heights(head.fp_positions()), lid_opening_mm(head)
    out = {"posed": bool(record)}
    for eye, mm in opening.items():
        r = dict((record or {}).get(eye, {}))
        if eye in heights:
            r["built"] = {"upper": round(float(heights[eye][0]), 4), "lower": round(float(heights[eye][1]), 4)}
        r["opening_mm"] = round(mm, 3)
        out[eye] = r
    return out


def identity_start(generic: Head, points, point_sd_mm: float = POINT_SD_MM) -> tuple[Head, np.ndarray | None]:
    """The identity model's head nearest 3D feature points (:func:`recon.shape.identity.fit_to_points`),
    where the deformation onto them starts; the generic head itself (and None) when the
    shipped model does not fit it (another generic head, ``MPEG4_GENERIC_HEAD``).
    ``point_sd_mm``: the points' spread about what the model can express (larger for
    detected points nobody checked)."""
    from .identity import fit_to_points, load_identity_model

    try:
        model = load_identity_model()
        model.check(generic)
    except InputError:
        return generic, None
    c = fit_to_points(model, generic, points, point_sd_mm=point_sd_mm)
    return model.head(generic, c), c


def has_side(fdp) -> bool:
    """Whether an annotation file has points on a side photo (else the head comes from the
    front photo alone, :func:`fit_head_front`)."""
    view = fdp.views.get("side")
    return view is not None and bool(view.points)


def fit_head_front(fdp, generic: Head | None = None, ipd_mm: float = DEFAULT_IPD_MM, focal_px: float | None = None,
                   method: str = "dffd", where: str = "fdp.json", estimate_focal: bool = True,
                   neutral_lids: bool = True):
    """The generic head deformed to the feature points of a front photo alone.

    The identity model fitted to the front photo's points gives their depth and the rest
    of the head (:func:`recon.shape.from_front.fit_front`); its head is then moved onto the
    3D points by the same deformation as the two-photo route's (:func:`deform_head`).

    Parameters
    ----------
    fdp : mpeg4.io.fdp_json.FdpFile
        With a ``front`` view (pixels; the photo's size).
    generic, ipd_mm, method, where
        See :func:`fit_head`.
    focal_px : float, optional
        The photo's focal length, pixels; estimated from the face when None and
        ``estimate_focal`` (see :func:`recon.shape.from_front.fit_front`).
    neutral_lids : bool
        See :func:`fit_head`.

    Returns
    -------
    head : Head
        ``metadata["fit"]`` records that the depth is estimated, the focal length and where
        it came from, and each point's source.
    front_fit : recon.shape.from_front.FrontFit
    """
    from .from_front import fit_front

    view = require_views(fdp, where, ("front",))["front"]
    if not (view.width and view.height):
        raise InputError("the front view records no photo size", where=f"{where}, views.front",
                         fix="give the front photo, whose size the points were marked on")
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    try:
        ff = fit_front(view.points, view.width, view.height, generic, ipd_mm=ipd_mm, focal_px=focal_px,
                       estimate_focal=estimate_focal, confidence=view.confidence or None,
                       drop_outliers=fdp.metadata.get("reviewed") is False,
                       under_hair=under_hair(fdp) if fdp.metadata.get("reviewed") is False else ())
    except InputError as e:
        raise InputError(e.what, where=f"{where}, views.front", fix=e.fix) from None
    start, pinned, lids = _pose_lids(ff.head, ff.points, view.points, neutral_lids)
    head = _settle_lids(deform_head(start, pinned, method=method), ff.points, lids)
    head.metadata = dict(head.metadata, fit=dict(
        depth="estimated: identity model fitted to the front photo (no side photo)",
        ipd_mm=ipd_mm, camera="orthographic" if ff.focal_px is None else "pinhole",
        focal_px=None if ff.focal_px is None else round(ff.focal_px, 1), focal_from=ff.focal_from,
        focal_costs=ff.candidates, model_rms_px=round(ff.rms_px, 2),
        model_coefficients=[round(float(c), 3) for c in ff.coefficients], point_sources=ff.source,
        dropped_points=ff.dropped, lids=_lids_built(head, lids)))
    return head, ff


def run_fit(front_photo, side_photo, fdp_path, out_dir, ipd_mm: float = DEFAULT_IPD_MM,
            focal_px: float | None = None, method: str = "dffd",
            progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """``recon fit``: write the fitted head bundle for two annotated photos.

    Parameters
    ----------
    front_photo, side_photo : path
        The photos (their sizes check the annotations and give the principal point).
    fdp_path : path
        The annotation file with ``front`` and ``side`` views.
    out_dir : path
        Output folder (created); ``head.glb``, ``head.fdp.json`` and ``preview.png`` are
        replaced atomically.
    ipd_mm, focal_px, method
        See :func:`fit_head`. Without ``focal_px``, the focal length the photos record in
        their EXIF (:func:`recon.photos.photos_focal_px`), else orthographic cameras.

    Returns
    -------
    dict of str to Path
    """
    from mpeg4.io import fdp_from_head, read_fdp_json, save_head, write_fdp_json
    from mpeg4.preview import save_preview

    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    fdp = read_fdp_json(fdp_path)
    photos = {"front": front_photo, "side": side_photo}
    attach_photo_sizes(fdp, {n: image_size(p) for n, p in photos.items()}, os.fspath(fdp_path),
                       {n: os.fspath(p) for n, p in photos.items()})
    if focal_px is None:
        from recon.photos import photos_focal_px

        focal_px, note = photos_focal_px(front_photo, side_photo)
        say(note)
    say("fitting the generic head to the feature points")
    head, cal = fit_head(fdp, ipd_mm=ipd_mm, focal_px=focal_px, method=method, where=os.fspath(fdp_path))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"head": out / "head.glb", "fdp": out / "head.fdp.json", "preview": out / "preview.png"}
    say(f"writing {paths['head']}")
    save_head(head, paths["head"])
    bundle = fdp_from_head(head)
    bundle.views = fdp.views
    write_fdp_json(paths["fdp"], bundle)
    say(f"rendering {paths['preview']}")
    save_preview(head, paths["preview"])
    say(f"done in {time.perf_counter() - t0:.1f} s (scale from an interpupillary distance of {ipd_mm:g} mm)")
    return paths
