"""The mesh drawn from the front and the side, and the 2D detectors that read the drawings.

:func:`render_views` renders orthographic front and left views framed on the head;
:func:`landmark_detector` runs the photo annotation's detector on them, and
:func:`untextured_guesses` names the points a grey render can only guess.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import Head
from mpeg4.io.fdp_json import FdpFile

__all__ = ["Views", "render_views", "landmark_detector", "untextured_guesses"]

# Points a photo shows by colour or the face's oval, not by the shape a render shows.
_TEXTURE_POINTS = ("2.10", "2.11", "2.12", "2.13", "2.14", "11.1", "11.2", "11.3", "11.5")

# How far the generic head's shape may overrule recon.landmarks' points on a render
# (template_fit.fit_generic's give): best of 1e-4, 1e-3, 1e-2 on ICT identities 20-27,
# which the benchmark (0-19) does not use.
_LANDMARK_GIVE = 1e-3
_SKIN, _WHITE, _PINK = (0.86, 0.68, 0.56), (0.92, 0.92, 0.9), (0.75, 0.4, 0.42)


@dataclass
class Views:
    """The front and left-side renders of a head in the neutral frame.

    Attributes
    ----------
    images : dict of str to (H, W, 3) uint8
    depth : dict of str to (H, W) float64
    cameras : dict of str to Camera
        Orthographic: each pixel is a ray along the view axis.
    paths : dict of str to Path
        The images as PNG files (what a photo detector reads).
    frame : (4, 4) float64
        File → render-world (neutral) similarity, so that points known in the file's
        coordinates can be projected (:func:`recon.evaluate.synthetic.perfect_detector`).
    """

    images: dict
    depth: dict
    cameras: dict
    paths: dict
    frame: np.ndarray


def render_views(head: Head, folder, size: int = 1024, frame: np.ndarray | None = None,
                 focus: np.ndarray | None = None) -> Views:
    """Front and left-side renders of a head in the neutral frame, written as PNGs to ``folder``.

    Orthographic, lit from above the viewer's left shoulder; untextured parts in the
    default grey are drawn in a skin tone (eyes and teeth white).

    Parameters
    ----------
    head : Head
        In the neutral frame, metres.
    folder : path
        Where ``front.png`` and ``side.png`` go.
    size : int
        Image height in pixels (the width is 4/5 of it, like a portrait photo).
    frame : (4, 4) float, optional
        File → neutral similarity the head was moved by (kept in the result).
    focus : (3,) float, optional
        The nose tip, neutral frame: the views frame the head from 13 cm below it to 15 cm
        above (not the shoulders); everything when None.
    """
    from PIL import Image

    from mpeg4.camera import Camera
    from mpeg4.preview import head_meshes
    from mpeg4.render import render

    folder = Path(folder)
    meshes = head_meshes(head)
    # An untextured mesh in the renderer's default grey is drawn in a skin tone (eyes and
    # teeth white, the tongue pink): photo detectors look for skin.
    for name, m in zip(head.parts, meshes):
        if m.texture is None and np.allclose(m.colour, 0.8):
            m.colour = (_WHITE if name.startswith(("eye", "teeth")) else _PINK if name.startswith("tongue")
                        else _SKIN)
    allv = np.concatenate([p.vertices for p in head.parts.values()])
    if focus is not None:
        near = allv[(allv[:, 1] > focus[1] - 0.13) & (allv[:, 1] < focus[1] + 0.15)]
        allv = near if len(near) >= 100 else allv
    out = Views({}, {}, {}, {}, np.eye(4) if frame is None else np.asarray(frame, dtype=np.float64))
    w = int(round(size * 0.8))
    for name, yaw in (("front", 0.0), ("side", 90.0)):
        cam = Camera.fit(allv, w, size, yaw_deg=yaw, margin=0.04)
        img, depth = render(meshes, cam, background=(0.86, 0.87, 0.89), return_depth=True, samples=4,
                            ambient=0.42, light=(-0.35, 0.45, 1.0))
        path = folder / f"{name}.png"
        Image.fromarray(img).save(path)
        out.images[name], out.depth[name], out.cameras[name], out.paths[name] = img, depth, cam, path
    return out


def landmark_detector() -> Callable[[Views], FdpFile]:
    """The photo annotation's detector (:func:`recon.landmarks.detect`) applied to the renders.

    The detector carries ``guessed`` (:func:`untextured_guesses`) and ``give`` (how far
    the generic head fitted to the surface may smooth its points; measured on ICT
    identities that ``benchmarks/mark3d_accuracy.py`` does not use) for :func:`mark`.

    Raises
    ------
    InputError
        When recon.landmarks is not installed, or the models it runs (mediapipe) are not.
    """
    from recon.landmarks import detector

    detect, why = detector()
    if detect is None:
        raise InputError(f"no 2D landmark detector: {why}", where="fmc mark",
                         fix="run bash install.sh, or place the points by hand: recon annotate MESH")

    def run(views: Views) -> FdpFile:
        # The side render is taken from the face's left (yaw 90): the nose points to the
        # image's left, which the photo detector need not guess from a grey render.
        return detect(os.fspath(views.paths["front"]), os.fspath(views.paths["side"]), side_facing="left")

    run.__name__ = "recon.landmarks.detect"
    run.guessed = untextured_guesses
    run.give = _LANDMARK_GIVE
    return run


def untextured_guesses(found: FdpFile) -> set[str]:
    """The points a photo detector can only guess on the render of an untextured mesh.

    Those a photo shows by colour, which a grey render does not have: the eyebrows (4.x),
    the hairline and the hair (11.1-11.3, 11.5); those the face mesh guesses from the
    face's oval, not from anything it sees (the chin boss and corners, the jaw angles
    2.10-2.14, the cheeks 5.x); and whatever :func:`recon.landmarks.detect` found in the
    front view by the silhouette or by rule rather than by its face mesh (the ears, the top
    of the skull), and the ear points it found so in the side view (with their right
    partners). :func:`fitted_points` places them from the shape instead
    (:func:`recon.mark.ears.ears_by_outline` then the ears from their rim).
    """
    sources = (found.metadata.get("landmarks") or {}).get("source", {})
    out = {i for i in FP_IDS if FEATURE_POINTS[i].group in (4, 5) or i in _TEXTURE_POINTS}
    out |= {i for i, s in sources.get("front", {}).items() if s != "model"}
    # The side render shows an ear inside the head's outline, not on it: the side view's
    # ear points by the outline or by rule are guesses too (10.3, which the front view
    # cannot show, came out 7.6 mm off on MakeHuman's head), and so are their partners,
    # mirrored from them.
    ears = {i for i, s in sources.get("side", {}).items() if FEATURE_POINTS[i].group == 10 and s != "model"}
    return out | ears | {FEATURE_POINTS[i].mirror for i in ears if FEATURE_POINTS[i].mirror}
