"""The main job on the embedded example.

The whole chain as far as the project reaches: the example's front and side photos and
their feature points (``data/example/``, made by ``scripts/make_example_photos.py``) →
the generic head deformed to the person and textured from both photos (``recon build``)
→ the generic head's Facial Animation Tables cloned onto it (``fmc clone``) → the head
saying a sentence (``fmc say``: audio, FAP stream, animated GLB, preview GIF and MP4).
Each stage that lands joins this same function, so ``recon example`` always runs
everything the project can do.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from pathlib import Path

__all__ = ["run_example", "scaled_example", "example_camera", "EXAMPLE_SENTENCE", "EXAMPLE_DIR", "EXAMPLE_FDP"]

#: What the example head says.
EXAMPLE_SENTENCE = "Hello! I am a talking head, and I speak MPEG-4."

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


def run_example(out_dir: str | os.PathLike, progress: Callable[[str], None] | None = None,
                speak: bool = True, texture_size: int = 2048) -> dict[str, Path]:
    """Run the main job on the embedded example and write its files to ``out_dir``.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created if needed). Existing files of the same names are
        replaced atomically.
    progress : callable, optional
        Called with a short message before each step.
    speak : bool
        Also make the head say :data:`EXAMPLE_SENTENCE` (needs espeak-ng).
    texture_size : int
        Side of the skin texture, pixels.

    Returns
    -------
    dict of str to Path
        The ``recon build`` bundle (``head`` — here with the cloned animation tables —,
        ``obj``, ``mtl``, ``texture``, ``fdp``, ``preview``, the parts' textures) and with
        ``speak`` the ``say/`` files: ``audio``, ``stream``, ``animation``,
        ``speech_preview`` (GIF), ``speech_video`` (MP4 with the sound).
    """
    from fmc.animate import say as say_text
    from fmc.clone import clone
    from mpeg4.errors import InputError
    from mpeg4.generic_head import load_generic_head
    from mpeg4.io import save_head

    from .build import run_build

    say = progress or (lambda msg: None)
    if not EXAMPLE_FDP.exists():
        raise InputError("the embedded example is missing", where=str(EXAMPLE_DIR),
                         fix="run: python3 scripts/make_example_photos.py (it needs ../shared/data/ict_facekit)")
    out = Path(out_dir)
    t0 = time.perf_counter()
    cam = example_camera()
    say(f"building the head from {EXAMPLE_DIR / 'front.jpg'} and {EXAMPLE_DIR / 'side.jpg'}")
    built = []
    paths = run_build(None, None, EXAMPLE_FDP, out, ipd_mm=cam["ipd_mm"], focal_px=cam["focal_px"],
                      texture_size=texture_size, progress=lambda m: say(f"  {m}"), result=built)
    t1 = time.perf_counter()
    say("cloning the generic head's animation tables onto it (66 FAPs, 15 visemes, 7 expressions)")
    source = load_generic_head(with_fat=True)
    head, warnings = clone(source, built[0].head)
    for w in warnings:
        say(f"  warning: {w}")
    say(f"writing {paths['head']} (with the animation tables, {time.perf_counter() - t1:.1f} s)")
    save_head(head, paths["head"])
    if speak:
        say(f"speaking: {EXAMPLE_SENTENCE!r}")
        spoken = say_text(paths["head"], EXAMPLE_SENTENCE, out / "say", progress=lambda m: say(f"  {m}"))
        paths.update(audio=spoken["audio"], stream=spoken["stream"], animation=spoken["animation"],
                     speech_preview=spoken["preview"], speech_video=spoken["video"])
    say(f"done in {time.perf_counter() - t0:.1f} s")
    return paths
