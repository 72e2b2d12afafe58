"""The photos' cameras, recovered from 3D feature points and the pixels they were marked at.

Calibration (:mod:`recon.shape.calibrate`) turns marked pixels into 3D points; texturing needs
the way back, from any point of the head to a pixel of each photo. :func:`fit_camera`
finds the camera that best maps the head's 3D feature points onto the pixels marked in a
photo: a scaled orthographic camera (least-squares affine camera made orthonormal) or,
with a focal length, a pinhole camera posed by OpenCV's PnP solver with the principal
point at the image centre. The camera of the mirrored photo
(the side photo flipped to show the other side of the face) is :meth:`FittedCamera.flipped`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from mpeg4.camera import Camera
from mpeg4.errors import InputError

__all__ = ["FittedCamera", "fit_camera", "fit_view_camera", "check_view_cameras"]

_STAND_OFF = 3.0  # metres: where an orthographic camera stands in front of the head
# How far (degrees) a fitted camera may look away from the direction its photo should show.
_MAX_VIEW_ERROR_DEG = 35.0
# Largest RMS distance between marked points and the fitted camera's projection, as a
# share of the interpupillary distance in that photo.
_MAX_RESIDUAL_SHARE = 0.12


@dataclass
class FittedCamera:
    """A camera fitted to feature points, and how well it fits.

    Attributes
    ----------
    camera : Camera
    residual_px : dict of str to float
        FP id → distance between the marked pixel and the projection of its 3D point.
    """

    camera: Camera
    residual_px: dict[str, float]

    def project(self, points: np.ndarray) -> np.ndarray:
        """(K, 2) pixels of (K, 3) points of the head (metres)."""
        return self.camera.project(points)

    def registration_m(self, at: np.ndarray, floor_m: float = 0.0) -> float:
        """How far (metres, on the head near ``at``) the photo's pixels may land from the
        skin they belong to: the median of the feature points' residuals, one pixel's
        footprint (a camera that fits its points exactly still samples a pixel's width)
        and ``floor_m`` (how well the points themselves are placed: residuals below it say
        nothing of the camera), added in quadrature."""
        at = np.asarray(at, dtype=np.float64).reshape(1, 3)
        step = 1e-3 * self.camera.rotation[0]  # a millimetre along the image's rows
        px_per_m = float(np.linalg.norm(self.camera.project(at + step) - self.camera.project(at))) / 1e-3
        r = np.array(list(self.residual_px.values()), dtype=np.float64)
        median = float(np.median(r)) if len(r) else 0.0
        return float(np.hypot(np.hypot(median, 1.0) / max(px_per_m, 1e-9), floor_m))

    @property
    def rms_px(self) -> float:
        r = np.array(list(self.residual_px.values()))
        return float(np.sqrt(np.mean(r ** 2))) if len(r) else 0.0

    def flipped(self) -> FittedCamera:
        """The camera of this photo flipped left–right.

        A flipped side photo shows the mirror image of the side it was taken of, which is
        what a camera at the mirrored position would see of a symmetric head: a point X
        of the other side lands where its mirror image was, flipped.
        """
        c = self.camera
        flip = np.diag([-1.0, 1.0, 1.0])
        # Mirroring the world through x = 0 and the image through its vertical centre line:
        # rows of the rotation act on mirrored points, the right axis reverses.
        rot = np.diag([-1.0, 1.0, 1.0]) @ c.rotation @ flip
        cx, cy = c.principal
        cam = Camera(c.width, c.height, rot, flip @ c.centre, focal_px=c.focal_px, scale_px=c.scale_px,
                     principal=(c.width - 1 - cx, cy), near=c.near, far=c.far)
        return FittedCamera(cam, dict(self.residual_px))


def fit_camera(points3d: Mapping[str, np.ndarray], pixels: Mapping[str, np.ndarray], width: int, height: int,
               focal_px: float | None = None, where: str = "photo") -> FittedCamera:
    """The camera that maps 3D feature points onto the pixels marked in a photo.

    Parameters
    ----------
    points3d : mapping of str to (3,) float
        FP id → position on the head, metres.
    pixels : mapping of str to (2,) float
        FP id → marked pixel (x right, y down). Ids without a 3D point are ignored.
    width, height : int
        The photo's size.
    focal_px : float, optional
        Pinhole focal length in pixels (square pixels, principal point at the image
        centre); a scaled orthographic camera when None.
    where : str
        Name of the photo, for error messages.

    Returns
    -------
    FittedCamera
    """
    ids = [i for i in pixels if i in points3d]
    need = 6 if focal_px is not None else 4
    if len(ids) < need:
        raise InputError(f"only {len(ids)} marked feature points have 3D positions; a camera needs {need}",
                         where=where, fix="mark more feature points on this photo")
    X = np.array([np.asarray(points3d[i], float).reshape(3) for i in ids])
    u = np.array([np.asarray(pixels[i], float).reshape(2) for i in ids])
    if np.linalg.matrix_rank(X - X.mean(axis=0), tol=1e-6) < 3:
        raise InputError("the feature points with 3D positions lie in a plane or on a line", where=where,
                         fix="mark points spread over the face (eyes, nose, mouth, ears)")
    if focal_px is None:
        cam = _orthographic(X, u, width, height)
    else:
        cam = _pinhole(X, u, width, height, float(focal_px), where)
    res = np.linalg.norm(cam.project(X) - u, axis=1)
    return FittedCamera(cam, {i: float(r) for i, r in zip(ids, res)})


def _orthographic(X: np.ndarray, u: np.ndarray, width: int, height: int) -> Camera:
    # Affine camera u = M X + t by least squares, then the nearest scaled orthonormal
    # pair of rows (the image y axis points down, the camera's up axis up).
    A = np.c_[X, np.ones(len(X))]
    sol, *_ = np.linalg.lstsq(A, u, rcond=None)
    M = sol[:3].T * np.array([[1.0], [-1.0]])  # rows: s * right, s * up
    U, S, Vt = np.linalg.svd(M, full_matrices=False)
    rows = U @ Vt
    scale = float(S.mean())
    right, up = rows
    back = np.cross(right, up)
    rot = np.stack([right, up, back])
    # Refit the principal point with the rotation and scale fixed.
    proj = X @ rot[:2].T * scale
    t = (u - np.c_[proj[:, 0], -proj[:, 1]]).mean(axis=0)
    depth_max = float((X @ back).max())
    centre = back * (depth_max + _STAND_OFF)
    return Camera(width, height, rot, centre, scale_px=scale, principal=(float(t[0]), float(t[1])),
                  near=0.01, far=2 * _STAND_OFF + 10.0)


def _pinhole(X: np.ndarray, u: np.ndarray, width: int, height: int, f: float, where: str) -> Camera:
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    K = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
    ok, rvec, tvec = cv2.solvePnP(X.astype(np.float64), u.astype(np.float64), K, None,
                                  flags=cv2.SOLVEPNP_EPNP)
    if ok:
        ok, rvec, tvec = cv2.solvePnP(X, u, K, None, rvec, tvec, useExtrinsicGuess=True,
                                      flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise InputError("no camera pose explains the marked feature points", where=where,
                         fix="check the points' labels and the focal length (--focal)")
    R_cv, _ = cv2.Rodrigues(rvec)
    rot = np.diag([1.0, -1.0, -1.0]) @ R_cv  # OpenCV's rows are right, down, forward
    centre = -R_cv.T @ tvec.reshape(3)
    cam = Camera(width, height, rot, centre, focal_px=f, principal=(cx, cy), near=0.01, far=100.0)
    if (cam.depth(X) <= 0).any():
        raise InputError("the fitted camera sees some feature points from behind", where=where,
                         fix="check the points' labels and the focal length (--focal)")
    return cam


def fit_view_camera(points3d: Mapping[str, np.ndarray], view, name: str, focal_px: float | None, where: str, cal,
                    unreviewed: bool, say: Callable[[str], None]) -> FittedCamera:
    """A photo's camera from its points (``view``: its :class:`~mpeg4.io.fdp_json.ViewAnnotation`,
    ``name`` "front" or "side"), without those the calibration ``cal`` dropped from it.

    For unreviewed (detected) points, a point the camera cannot explain (off by more than
    the share of the IPD :func:`check_view_cameras` allows) is dropped too, the worst first,
    unless it is one of the face's core points, said (``say``) and listed in ``cal.dropped``.
    """
    from mpeg4.catalogue import FEATURE_POINTS
    from recon.shape.core_points import is_core

    gone = {i for i, d in cal.dropped.items() if d["view"] in (name, "both")}
    own = {(FEATURE_POINTS[i].mirror or i) if name == "side" and i not in view.points else i for i in gone}
    pixels = {i: p for i, p in view.points.items() if i not in gone and i not in own}
    while True:
        cam = fit_camera(points3d, pixels, view.width, view.height, focal_px=focal_px, where=where)
        if not unreviewed:
            return cam
        limit = _MAX_RESIDUAL_SHARE * _view_scale(view)
        worst = max((i for i in cam.residual_px
                     if not is_core(i)),
                    key=lambda i: cam.residual_px[i], default=None)
        if cam.rms_px <= limit or worst is None or cam.residual_px[worst] <= limit:
            return cam
        say(f"left out {worst} on the {name} photo: the camera misses it by {cam.residual_px[worst]:.0f} px")
        cal.dropped[worst] = {"view": name, "camera_px": round(float(cam.residual_px[worst]), 1)}
        del pixels[worst]


def _view_scale(view) -> float:
    """Pixels of the IPD a photo shows (the pupils apart, or the eye to the ear in a profile)."""
    pts = [view.points[i] for i in ("3.5", "3.6") if i in view.points]
    if len(pts) == 2:
        return float(np.linalg.norm(pts[0] - pts[1]))
    b = [view.points[i] for i in ("10.9", "10.10", "10.7", "10.8") if i in view.points]
    return float(np.linalg.norm(pts[0] - b[0])) if pts and b else max(view.width or 1, view.height or 1) * 0.1


def check_view_cameras(cams: Mapping[str, FittedCamera], views: Mapping, where: str) -> None:
    """Refuse annotations that no plausible front/side camera explains (a profile passed
    as the front photo, points labelled on the wrong photo); ``views``: the annotations'
    views by name, ``where`` the annotation file, for the message."""
    for name, want, what in (("front", np.array([0.0, 0.0, 1.0]), "from the front"),
                             ("side", None, "from the side")):
        if name not in cams:
            continue
        cam = cams[name].camera
        toward = cam.rotation[2]  # from the head towards the camera
        if want is None:
            angle = np.degrees(np.arccos(np.clip(abs(toward[0]), 0, 1)))
        else:
            angle = np.degrees(np.arccos(np.clip(toward @ want, -1, 1)))
        if angle > _MAX_VIEW_ERROR_DEG:
            raise InputError(f"the points marked on the {name} photo fit a camera {angle:.0f} degrees away from "
                             f"looking {what}", where=f"{where}, views.{name}",
                             fix=f"check that the {name} photo shows the face {what} and that its points are "
                                 f"marked on it (not on the other photo)")
        scale = _view_scale(views[name])
        rms = cams[name].rms_px
        if rms > _MAX_RESIDUAL_SHARE * scale:
            worst = sorted(cams[name].residual_px.items(), key=lambda kv: -kv[1])[:3]
            raise InputError(f"the points marked on the {name} photo do not fit one camera (off by {rms:.0f} px on "
                             f"average; worst " + ", ".join(f"{i} by {r:.0f} px" for i, r in worst) + ")",
                             where=f"{where}, views.{name}",
                             fix="move those points to where the catalogue describes them (recon annotate)")
