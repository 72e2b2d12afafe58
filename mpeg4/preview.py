"""Preview pictures of a head: front, side and three-quarter renders with labelled feature points.

The renders come from :mod:`mpeg4.render`; each feature point is drawn where the same
camera model projects it, as a dot coloured by its FP group with its id beside it. Points
hidden behind the surface in a view (compared with the rendered depth) are drawn as rings
without a label, so the labels one reads are those one sees.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from .camera import Camera
from .catalogue import FEATURE_POINTS
from .head import Head
from .io.atomic import atomic_write
from .render import RenderMesh, render

__all__ = ["VIEWS", "GROUP_COLOURS", "head_meshes", "render_views", "preview_image", "save_preview"]

#: (name, yaw in degrees, pitch in degrees): yaw 90 shows the face's left side.
VIEWS: tuple[tuple[str, float, float], ...] = (("front", 0.0, 0.0), ("side", 90.0, 0.0),
                                               ("three-quarter", 35.0, 10.0))

#: RGB colour per FP group, distinct enough to tell groups apart at a glance.
GROUP_COLOURS: dict[int, tuple[int, int, int]] = {
    2: (230, 25, 75), 3: (0, 130, 200), 4: (245, 130, 48), 5: (145, 30, 180), 6: (240, 50, 230),
    7: (60, 60, 60), 8: (220, 0, 0), 9: (0, 150, 60), 10: (128, 80, 0), 11: (0, 0, 128),
}


def head_meshes(head: Head, vertices: Mapping[str, np.ndarray] | None = None) -> list[RenderMesh]:
    """The head's parts as render meshes (optionally with deformed vertices per part)."""
    out = []
    for name, p in head.parts.items():
        v = p.vertices if vertices is None or name not in vertices else vertices[name]
        out.append(RenderMesh(v, p.triangles, uv=p.uv if p.texture is not None else None,
                              texture=p.texture, colour=p.colour))
    return out


def render_views(head: Head, size: int = 720, views: Sequence[tuple[str, float, float]] = VIEWS,
                 focal_px: float | None = None, frame_points: np.ndarray | None = None
                 ) -> list[tuple[str, np.ndarray, np.ndarray, Camera]]:
    """Render the head from several directions.

    Parameters
    ----------
    head : Head
    size : int
        Height of each view in pixels; views are 4:5 (width:height) portraits.
    views : sequence of (name, yaw_deg, pitch_deg)
    focal_px : float, optional
        Perspective focal length in pixels; orthographic when None.
    frame_points : (K, 3) array, optional
        Points the views are framed on (metres); the feature points by default, else
        the whole head.

    Returns
    -------
    list of (name, image (H, W, 3) uint8, depth (H, W) float64, Camera)
    """
    meshes = head_meshes(head)
    if frame_points is None:
        _, frame_points = head.fp_array()
        if len(frame_points) < 4:
            frame_points = np.concatenate([p.vertices for p in head.parts.values()])
    width = int(round(size * 0.8))
    out = []
    for name, yaw, pitch in views:
        cam = Camera.fit(frame_points, width, size, yaw_deg=yaw, pitch_deg=pitch, margin=0.12, focal_px=focal_px)
        image, depth = render(meshes, cam, return_depth=True)
        out.append((name, image, depth, cam))
    return out


def _label(image: np.ndarray, depth: np.ndarray, cam: Camera, points: Mapping[str, np.ndarray],
           centre_u: float) -> None:
    ids = list(points)
    if not ids:
        return
    xyz = np.array([points[i] for i in ids])
    uv = cam.project(xyz)
    z = cam.depth(xyz)
    h, w = depth.shape
    scale = max(0.32, h / 1600)
    for i, (u, v), d in zip(ids, uv, z):
        if not (0 <= u < w and 0 <= v < h):
            continue
        colour = GROUP_COLOURS[FEATURE_POINTS[i].group][::-1]  # OpenCV draws BGR
        ui, vi = int(round(u)), int(round(v))
        # Visible when nothing rendered lies clearly in front of the point (2 mm slack).
        visible = d <= depth[vi, ui] + 2e-3
        centre = (int(round(u * 4)), int(round(v * 4)))  # shift=2: quarter-pixel precision
        if not visible:
            cv2.circle(image, centre, 12, colour, 1, cv2.LINE_AA, shift=2)
            continue
        cv2.circle(image, centre, 14, (255, 255, 255), -1, cv2.LINE_AA, shift=2)
        cv2.circle(image, centre, 10, colour, -1, cv2.LINE_AA, shift=2)
        (tw, th), _ = cv2.getTextSize(i, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
        tx = ui + 5 if u >= centre_u else ui - 5 - tw
        ty = vi + th // 2
        cv2.putText(image, i, (tx, ty), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 3, cv2.LINE_AA)
        cv2.putText(image, i, (tx, ty), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_AA)


def preview_image(head: Head, size: int = 720, labels: bool = True, title: str | None = None,
                  focal_px: float | None = None) -> np.ndarray:
    """Front, side and three-quarter renders side by side, FPs labelled, with a caption.

    Parameters
    ----------
    head : Head
    size : int
        Height of each view in pixels.
    labels : bool
        Draw the feature points.
    title : str, optional
        Caption; by default the FAPU in millimetres when the head has the points for them.
    focal_px : float, optional
        Perspective focal length in pixels; orthographic when None.

    Returns
    -------
    (H, W, 3) uint8 RGB
    """
    points = head.fp_positions()
    panels = []
    for name, image, depth, cam in render_views(head, size=size, focal_px=focal_px):
        image = np.ascontiguousarray(image[..., ::-1])  # to BGR for OpenCV drawing
        if labels:
            centre_u = float(cam.project(np.zeros((1, 3)))[0, 0])
            _label(image, depth, cam, points, centre_u)
        cv2.putText(image, name, (12, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (40, 40, 40), 2, cv2.LINE_AA)
        panels.append(image)
    sheet = np.concatenate(panels, axis=1)
    if title is None:
        try:
            f = head.fapu
            title = "FAPU (mm): " + "  ".join(f"{k} {v * 1000:.1f}" for k, v in f.as_dict().items())
        except ValueError:
            title = ""
    caption = np.full((44, sheet.shape[1], 3), 255, np.uint8)
    cv2.putText(caption, f"{len(points)} feature points. {title}", (12, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.7,
                (40, 40, 40), 1, cv2.LINE_AA)
    x = sheet.shape[1] - 12
    for g in sorted(GROUP_COLOURS, reverse=True):
        text = f"{g}"
        (tw, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 2)
        x -= tw + 26
        cv2.circle(caption, (x, 24), 7, GROUP_COLOURS[g][::-1], -1, cv2.LINE_AA)
        cv2.putText(caption, text, (x + 11, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.6, GROUP_COLOURS[g][::-1], 2, cv2.LINE_AA)
    return np.ascontiguousarray(np.concatenate([sheet, caption], axis=0)[..., ::-1])


def save_preview(head: Head, path: str | os.PathLike, **kwargs) -> str:
    """Write :func:`preview_image` to a PNG (atomically) and return the path."""
    image = preview_image(head, **kwargs)
    ok, data = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    with atomic_write(path, "wb") as f:
        f.write(data.tobytes())
    return os.fspath(path)
