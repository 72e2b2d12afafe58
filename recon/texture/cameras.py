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

from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from mpeg4.errors import InputError
from mpeg4.render import Camera

__all__ = ["FittedCamera", "fit_camera"]

_STAND_OFF = 3.0  # metres: where an orthographic camera stands in front of the head


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
