"""The embedded example, photo side.

The example's front and side photos and their feature points (``data/example/``, made by
``scripts/make_example_photos.py``), the camera they were taken with, and the generic head
deformed to the person and textured from both photos (:func:`build_example`, as
``recon build``). ``recon example`` goes on from there (:func:`chain.example.run_example`:
motion cloned onto the head, then speech).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

__all__ = ["build_example", "scaled_example", "example_camera", "EXAMPLE_DIR", "EXAMPLE_FDP"]

#: The embedded example: two photos and their feature points.
EXAMPLE_DIR = Path(__file__).resolve().parents[1] / "data" / "example"
EXAMPLE_FDP = EXAMPLE_DIR / "example.fdp.json"


def example_camera() -> dict:
    """What the example's photos were taken with: ``focal_px`` and ``ipd_mm``."""
    meta = json.loads(EXAMPLE_FDP.read_text(encoding="utf-8")).get("metadata", {}).get("synthetic", {})
    return {"focal_px": meta.get("focal_px"), "ipd_mm": meta.get("ipd_mm", 63.0)}


def scaled_example(folder: str | os.PathLike, pid: str, scale: float) -> dict:
    """The embedded example resized, as one more person for ``recon batch``.

    Writes ``<pid>_front.png``, ``<pid>_side.png`` (the photos scaled by ``scale``) and
    ``<pid>.fdp.json`` (the points scaled with them) into ``folder``.

    Returns
    -------
    dict
        The person's manifest row: ``id``, ``front``, ``side``, ``fdp`` (names in
        ``folder``), ``ipd`` (mm) and ``focal`` (pixels, scaled with the photos).
    """
    from PIL import Image

    from mpeg4.io import read_fdp_json, write_fdp_json

    folder = Path(folder)
    cam = example_camera()
    fdp = read_fdp_json(EXAMPLE_FDP)
    for name, view in fdp.views.items():
        w, h = round(view.width * scale), round(view.height * scale)
        Image.open(EXAMPLE_DIR / view.image).resize((w, h), Image.LANCZOS).save(folder / f"{pid}_{name}.png")
        view.points = {i: p * [w / view.width, h / view.height] for i, p in view.points.items()}
        view.image, view.width, view.height = f"{pid}_{name}.png", w, h
    write_fdp_json(folder / f"{pid}.fdp.json", fdp)
    return {"id": pid, "front": f"{pid}_front.png", "side": f"{pid}_side.png", "fdp": f"{pid}.fdp.json",
            "ipd": cam["ipd_mm"], "focal": round(cam["focal_px"] * scale, 6)}


def build_example(out_dir: str | os.PathLike, progress: Callable[[str], None] | None = None,
                  texture_size: int = 2048, result: list | None = None) -> dict[str, Path]:
    """Build the embedded example's head from its photos into ``out_dir``.

    :func:`recon.build.run_build` on the example's photos and points, with the camera they
    were taken with (:func:`example_camera`).

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created if needed). Existing files of the same names are
        replaced atomically.
    progress : callable, optional
        Called with a short message before each step.
    texture_size : int
        Side of the skin texture, pixels.
    result : list, optional
        If given, the :class:`recon.build.BuildResult` is appended to it.

    Returns
    -------
    dict of str to Path
        The ``recon build`` bundle: ``head``, ``obj``, ``mtl``, ``texture``, ``fdp``,
        ``preview``, the parts' textures.
    """
    from mpeg4.errors import InputError

    from .build import run_build

    say = progress or (lambda msg: None)
    if not EXAMPLE_FDP.exists():
        raise InputError("the embedded example is missing", where=str(EXAMPLE_DIR),
                         fix="run: python3 scripts/make_example_photos.py (it needs ../shared/data/ict_facekit)")
    cam = example_camera()
    say(f"building the head from {EXAMPLE_DIR / 'front.jpg'} and {EXAMPLE_DIR / 'side.jpg'}")
    return run_build(None, None, EXAMPLE_FDP, out_dir, ipd_mm=cam["ipd_mm"], focal_px=cam["focal_px"],
                     texture_size=texture_size, progress=lambda m: say(f"  {m}"), result=result)
