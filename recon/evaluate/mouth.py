"""Does an open mouth read as a mouth: teeth in front, a dark cavity behind?

:func:`opening_figures` opens a head's jaw (its own tables, else the generic head's), renders
the mouth, and tells the pixels inside the inner lip contour (the projected feature points
2.2–2.9) apart by which part drew them (a second render, one flat colour per part).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mpeg4.head import Head

__all__ = ["INNER_LIP", "OUTER_LIP", "OpeningFigures", "opening_figures"]

#: Feature points round the inner and the outer lip contour, in order.
INNER_LIP = ("2.2", "2.6", "2.4", "2.8", "2.3", "2.9", "2.5", "2.7")
OUTER_LIP = ("8.1", "8.5", "8.3", "8.7", "8.2", "8.8", "8.4", "8.6")


@dataclass(frozen=True)
class OpeningFigures:
    """What a render of the open mouth shows.

    Attributes
    ----------
    opening_over_lips : float
        Mean luminance inside the inner lip contour over that of the lips (between the
        inner and outer contours): below 1, the opening reads darker than the lips.
    teeth_over_tongue : float
        Mean luminance of the teeth's pixels in the opening over the tongue's (nan when
        either shows none).
    teeth_share, tongue_share : float
        Share of the opening's pixels each covers.
    image : (H, W, 3) uint8
        The render.
    """

    opening_over_lips: float
    teeth_over_tongue: float
    teeth_share: float
    tongue_share: float
    image: np.ndarray


def _luminance(image: np.ndarray) -> np.ndarray:
    return image.astype(np.float64) @ [0.2126, 0.7152, 0.0722]


def opening_figures(head: Head, value: float = 600.0, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
                    size: tuple[int, int] = (400, 320), focal_px: float = 2000.0) -> OpeningFigures:
    """Render ``head`` with its jaw open by ``value`` (FAP 3, MNS) and measure the opening.

    Parameters
    ----------
    head : Head
        With the lip feature points; its own tables open it, else the generic head's
        (:func:`recon.texture.mouth.open_pose`).
    value : float
    yaw_deg, pitch_deg : float
        The view (:meth:`mpeg4.camera.Camera.fit`).
    size : (width, height)
    focal_px : float
        The camera is framed on the lips.
    """
    import cv2

    from mpeg4.camera import Camera
    from mpeg4.preview import head_meshes
    from mpeg4.render import RenderMesh, render
    from mpeg4.unlit import render_unlit
    from recon.texture.mouth import open_pose

    posed = open_pose(head, value=value)
    names = list(head.parts)
    # One flat colour per part, far apart in every channel from the others'.
    palette = {n: np.array([40 + 25 * k, 230 - 25 * k, (40 + 90 * k) % 256]) for k, n in enumerate(names)}
    fp = {k: head.fp_position(k, posed) for k in INNER_LIP + OUTER_LIP}
    cam = Camera.fit(np.array(list(fp.values())), size[0], size[1], yaw_deg=yaw_deg, pitch_deg=pitch_deg,
                     margin=0.15, focal_px=focal_px)
    image = render(head_meshes(head, posed), cam)
    flat = render_unlit([RenderMesh(posed[n], head.parts[n].triangles, colour=tuple(palette[n] / 255.0))
                         for n in names], cam)

    def polygon(keys):
        mask = np.zeros(image.shape[:2], np.uint8)
        cv2.fillPoly(mask, [np.round(cam.project(np.array([fp[k] for k in keys]))).astype(np.int32)], 1)
        return mask.astype(bool)

    inner = polygon(INNER_LIP)
    lips = polygon(OUTER_LIP) & ~inner
    lum = _luminance(image)

    def drawn_by(*parts):
        hit = np.zeros(image.shape[:2], bool)
        for n in parts:
            if n in palette:
                hit |= np.abs(flat.astype(np.int64) - palette[n]).max(axis=2) <= 2
        return inner & hit

    teeth, tongue = drawn_by("teeth_upper", "teeth_lower"), drawn_by("tongue")
    n_inner = max(int(inner.sum()), 1)
    ratio = float(lum[teeth].mean() / lum[tongue].mean()) if teeth.any() and tongue.any() else float("nan")
    return OpeningFigures(float(lum[inner].mean() / lum[lips].mean()) if inner.any() and lips.any() else float("nan"),
                          ratio, teeth.sum() / n_inner, tongue.sum() / n_inner, image)
