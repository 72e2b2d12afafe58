"""The renders' camera: pinhole or orthographic, with explicit conventions.

Explicit so that renders double as synthetic photos whose feature point pixels are known:
:meth:`Camera.project` gives the pixel at which :func:`mpeg4.render.render` draws a 3D point,
and :meth:`Camera.depth` the depth it returns there.

Conventions
-----------
World
    Metres, MPEG-4 neutral frame: +x the face's own left, +y up, +z towards the viewer.
Camera frame
    The camera looks along its own −z axis with +x right and +y up (OpenGL's eye space).
    ``Camera.rotation`` takes world directions into that frame; its rows are the camera's
    right, up and backward directions written in world coordinates.
Pixels
    OpenCV's: x right, y down, the centre of the top-left pixel at (0, 0), so the image
    centre is ``((W - 1) / 2, (H - 1) / 2)``. World +y appears up in the image; seen from
    the front the face's left (+x) is on the image's right.
Depth
    Distance in front of the camera along its viewing axis (−z in the camera frame), in
    metres; not the Euclidean distance to the camera centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = ["Camera", "look_rotation"]


def look_rotation(yaw_deg: float = 0.0, pitch_deg: float = 0.0) -> np.ndarray:
    """World → camera rotation for a camera looking at the origin from (yaw, pitch).

    Parameters
    ----------
    yaw_deg : float
        Rotation of the camera about world +y, degrees. 0 puts the camera on +z looking
        along −z (front view: the face's left, +x, on the image's right); 90 puts it on +x,
        where it sees the face's left side and the nose (+z) points to the image's left.
    pitch_deg : float
        Elevation, degrees; positive raises the camera so that it looks down.

    Returns
    -------
    (3, 3) float64
        Rows: camera right, up and backward (from the origin towards the camera) in world
        coordinates. Image "up" stays in the plane of world +y and the viewing direction.
    """
    y, p = np.radians(yaw_deg), np.radians(pitch_deg)
    back = np.array([np.sin(y) * np.cos(p), np.sin(p), np.cos(y) * np.cos(p)])
    right = np.array([np.cos(y), 0.0, -np.sin(y)])
    up = np.cross(back, right)
    return np.stack([right, up, back])


@dataclass
class Camera:
    """A pinhole (perspective) or orthographic camera.

    A world point ``X`` has camera coordinates ``c = rotation @ (X - centre)`` and depth
    ``-c_z``. Perspective: pixel ``(cx + f c_x / depth, cy - f c_y / depth)``.
    Orthographic: pixel ``(cx + s c_x, cy - s c_y)``. ``(cx, cy)`` is ``principal``.

    Attributes
    ----------
    width, height : int
        Image size, pixels.
    rotation : (3, 3) float64
        World → camera rotation (rows: camera right, up, backward, in world coordinates).
    centre : (3,) float64
        Camera position, metres, world frame.
    focal_px : float or None
        Perspective focal length in pixels (square pixels); None for orthographic.
    scale_px : float or None
        Orthographic scale, pixels per metre.
    principal : (cx, cy) or None
        Principal point in pixels (OpenCV convention); the image centre
        ``((W - 1) / 2, (H - 1) / 2)`` when None.
    near, far : float
        Clipping depths, metres. Orthographic cameras draw between them too, so the
        centre must stand in front of what is drawn.
    """

    width: int
    height: int
    rotation: np.ndarray
    centre: np.ndarray
    focal_px: float | None = None
    scale_px: float | None = None
    principal: tuple[float, float] | None = None
    near: float = 0.01
    far: float = 100.0

    def __post_init__(self):
        self.rotation = np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)
        self.centre = np.asarray(self.centre, dtype=np.float64).reshape(3)
        if (self.focal_px is None) == (self.scale_px is None):
            raise InputError("a camera needs exactly one of focal_px and scale_px", where="Camera",
                             fix="give focal_px for a perspective camera or scale_px for an orthographic one")
        if int(self.width) < 1 or int(self.height) < 1:
            raise InputError(f"image size {self.width}x{self.height} is empty", where="Camera",
                             fix="give a width and height of at least one pixel")
        if self.principal is None:
            self.principal = ((self.width - 1) / 2.0, (self.height - 1) / 2.0)

    @property
    def perspective(self) -> bool:
        """True for a pinhole camera, False for an orthographic one."""
        return self.focal_px is not None

    @classmethod
    def fit(cls, points, width: int, height: int, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
            margin: float = 0.1, focal_px: float | None = None) -> Camera:
        """A camera looking from direction (yaw, pitch) that frames ``points`` tightly.

        Every point projects inside the image less a border of ``margin`` times the image
        width (left and right) and height (top and bottom), and the framing is as tight as
        that allows: the points reach the border on at least one side.

        Parameters
        ----------
        points : (K, 3) float array
            What must be in view, metres.
        width, height : int
            Image size, pixels.
        yaw_deg, pitch_deg : float
            Viewing direction, degrees (see :func:`look_rotation`): yaw 0 is the front view,
            yaw 90 shows the face's left side with the nose pointing to the image's left,
            pitch > 0 looks down from above.
        margin : float
            Free border on each side as a fraction of the image size, in [0, 0.5).
        focal_px : float, optional
            Perspective focal length in pixels, the camera distance then chosen so that the
            points fit; orthographic when None, the scale chosen so that they fit.

        Returns
        -------
        Camera
            With the principal point at the image centre.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not len(points) or not np.isfinite(points).all():
            raise InputError("no finite points to frame", where="Camera.fit",
                             fix="pass the (K, 3) vertices or feature points to keep in view")
        if not 0 <= margin < 0.5:
            raise InputError(f"margin {margin} is outside [0, 0.5)", where="Camera.fit",
                             fix="give the free border as a fraction of the image, e.g. 0.1")
        rot = look_rotation(yaw_deg, pitch_deg)
        local = points @ rot.T  # camera-aligned axes, origin unchanged
        lo, hi = local.min(axis=0), local.max(axis=0)
        size = max(float((hi - lo).max()), 1e-6)
        # Half the usable span around the image centre: pixel centres run from 0 to W-1,
        # but pixels cover [-0.5, W-0.5], and the border is taken from that.
        half = 0.5 * np.array([width, height], dtype=np.float64) * (1 - 2 * margin)
        if focal_px is None:
            scale = float(min(half / np.maximum(0.5 * (hi - lo)[:2], 1e-9)))
            mid = 0.5 * (lo + hi)
            stand = hi[2] + size + 1.0  # in front of everything, so nothing is clipped
            centre = rot.T @ np.array([mid[0], mid[1], stand])
            return cls(width, height, rot, centre, scale_px=scale, near=0.01,
                       far=stand - lo[2] + 10 * size + 1.0)
        f = float(focal_px)
        # Camera at (tx, ty, d) in the aligned frame. Point i fits horizontally when
        # |f (X_i - tx)| <= half_x (d - Z_i); a tx exists for every pair (i, j) iff
        # d >= f (X_i - X_j) / (2 half_x) + (Z_i + Z_j) / 2, whose maximum separates.
        ds = []
        for axis in (0, 1):
            a = f * local[:, axis] / (2 * half[axis])
            ds.append(float((a + local[:, 2] / 2).max() + (-a + local[:, 2] / 2).max()))
        d = max(ds + [hi[2] + 1e-3 * size])
        t = []
        for axis in (0, 1):
            reach = half[axis] * (d - local[:, 2]) / f
            t.append(0.5 * ((local[:, axis] - reach).max() + (local[:, axis] + reach).min()))
        centre = rot.T @ np.array([t[0], t[1], d])
        nearest, farthest = d - hi[2], d - lo[2]
        return cls(width, height, rot, centre, focal_px=f, near=max(1e-4, 0.25 * nearest),
                   far=2.0 * farthest + 10 * size + 1.0)

    def to_camera(self, points) -> np.ndarray:
        """(K, 3) float64 camera-frame coordinates (metres) of (K, 3) world points."""
        return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.centre) @ self.rotation.T

    def towards(self, points) -> np.ndarray:
        """(K, 3) float64 unit directions from (K, 3) world points towards the camera: to
        its centre for a perspective camera, along its backward axis (the same for every
        point) for an orthographic one."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not self.perspective:
            return np.tile(self.rotation[2], (len(p), 1))
        d = self.centre - p
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def depth(self, points) -> np.ndarray:
        """(K,) float64 depth of (K, 3) world points along the viewing axis, metres.

        The quantity :func:`mpeg4.render.render` returns as depth; negative behind the camera.
        """
        return -self.to_camera(points)[:, 2]

    def project(self, points) -> np.ndarray:
        """(K, 2) float64 pixel positions (x right, y down, top-left pixel centre at (0, 0))
        of (K, 3) world points, metres."""
        c = self.to_camera(points)
        cx, cy = self.principal
        if self.perspective:
            s = self.focal_px / -c[:, 2]
            return np.stack([cx + c[:, 0] * s, cy - c[:, 1] * s], axis=1)
        return np.stack([cx + c[:, 0] * self.scale_px, cy - c[:, 1] * self.scale_px], axis=1)

    def unproject(self, pixels, depth) -> np.ndarray:
        """(K, 3) float64 world points (metres) at (K, 2) pixel positions and (K,) depths
        along the viewing axis: the inverse of :meth:`project` and :meth:`depth` (a depth
        render's pixels give the surface they show)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        d = np.asarray(depth, dtype=np.float64).reshape(-1)
        cx, cy = self.principal
        s = d / self.focal_px if self.perspective else np.full_like(d, 1.0 / self.scale_px)
        r = self.rotation  # rows: the camera's axes in the world; summed by hand, as a (K, 3)
        # by (3, 3) product through matmul is several times slower for large K
        return (((px[:, 0] - cx) * s)[:, None] * r[0] - ((px[:, 1] - cy) * s)[:, None] * r[1]
                - d[:, None] * r[2] + self.centre)

    def gl_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(4, 4) float64 view and projection matrices (row-major) matching :meth:`project`.

        GL rasterises pixel centres at normalised device x = (2 x + 1) / W − 1 with rows
        counted from the bottom, so pixel x maps to that and pixel y to
        1 − (2 y + 1) / H; the image is flipped to put row 0 on top afterwards.
        """
        view = np.eye(4)
        view[:3, :3] = self.rotation
        view[:3, 3] = -self.rotation @ self.centre
        w, h = self.width, self.height
        cx, cy = self.principal
        n, f = float(self.near), float(self.far)
        proj = np.zeros((4, 4))
        if self.perspective:
            fp = self.focal_px
            # clip w = -z_c; ndc_x = 2 fp x_c / (w_img -z_c) + (2 cx + 1) / w_img - 1.
            proj[0, 0] = 2 * fp / w
            proj[0, 2] = 1 - (2 * cx + 1) / w
            proj[1, 1] = 2 * fp / h
            proj[1, 2] = (2 * cy + 1) / h - 1
            proj[2, 2] = -(f + n) / (f - n)
            proj[2, 3] = -2 * f * n / (f - n)
            proj[3, 2] = -1.0
        else:
            s = self.scale_px
            proj[0, 0] = 2 * s / w
            proj[0, 3] = (2 * cx + 1) / w - 1
            proj[1, 1] = 2 * s / h
            proj[1, 3] = 1 - (2 * cy + 1) / h
            proj[2, 2] = -2 / (f - n)
            proj[2, 3] = -(f + n) / (f - n)
            proj[3, 3] = 1.0
        return view, proj
