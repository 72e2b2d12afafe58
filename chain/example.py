"""The main job on the embedded example.

The whole chain as far as the project reaches: the example's front and side photos and
their feature points → the generic head deformed to the person and textured from both
photos (:func:`recon.example.build_example`, as ``recon build``) → the generic head's Facial
Animation Tables cloned onto it (:func:`fmc.clone.clone`, as ``fmc clone``) → the head
saying a sentence (:func:`fmc.animate.say`, as ``fmc say``: audio, FAP stream, animated
GLB, preview GIF and MP4). Each stage that lands joins this same function, so
``recon example`` always runs everything the project can do.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

__all__ = ["run_example", "EXAMPLE_SENTENCE"]

#: What the example head says.
EXAMPLE_SENTENCE = "Hello! I am a talking head, and I speak MPEG-4."


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
    from mpeg4.generic_head import load_generic_head
    from mpeg4.io import save_head
    from recon.example import build_example

    say = progress or (lambda msg: None)
    out = Path(out_dir)
    t0 = time.perf_counter()
    built = []
    paths = build_example(out, progress=say, texture_size=texture_size, result=built)
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
