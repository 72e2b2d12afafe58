"""The main job on the embedded example.

The chain runs as far as the project reaches today: the generic head is loaded, its
Facial Animation Tables are authored from its sculpted shapes, it is exported ready for
cloning (GLB + feature points + FAPU) and previewed, and it speaks a sentence (audio,
FAP stream, animated GLB, preview GIF). Each stage that lands (photos → points → head →
texture → cloned FATs) joins this same function, so ``recon example`` always runs
everything the project can do.
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
                speak: bool = True) -> dict[str, Path]:
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

    Returns
    -------
    dict of str to Path
        ``head`` (GLB with animation tables), ``fdp`` (feature points and FAPU),
        ``preview`` (PNG), and with ``speak`` the ``say/`` files: ``audio``, ``stream``,
        ``animation``, ``speech_preview`` (GIF), ``speech_video`` (MP4 with the sound).
    """
    from fmc.animate import say as say_text
    from fmc.author import author_from_shapes, author_high_level
    from mpeg4.generic_head import load_generic_head
    from mpeg4.io import fdp_from_head, save_head, write_fdp_json
    from mpeg4.preview import save_preview

    say = progress or (lambda msg: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    say("loading the generic head")
    head = load_generic_head()
    say("authoring its animation tables from its sculpted shapes (66 FAPs, 15 visemes, 7 expressions)")
    fat, report = author_from_shapes(head)
    fat.update(author_high_level(head))
    head.fat = fat
    paths = {"head": out / "head.glb", "fdp": out / "head.fdp.json", "preview": out / "preview.png"}
    say(f"writing {paths['head']}")
    save_head(head, paths["head"])
    write_fdp_json(paths["fdp"], fdp_from_head(head))
    say(f"rendering {paths['preview']} (front, side, three-quarter)")
    save_preview(head, paths["preview"])
    if speak:
        say(f"speaking: {EXAMPLE_SENTENCE!r}")
        spoken = say_text(paths["head"], EXAMPLE_SENTENCE, out / "say", progress=lambda m: say(f"  {m}"))
        paths.update(audio=spoken["audio"], stream=spoken["stream"], animation=spoken["animation"],
                     speech_preview=spoken["preview"], speech_video=spoken["video"])
    say(f"done in {time.perf_counter() - t0:.1f} s")
    return paths
