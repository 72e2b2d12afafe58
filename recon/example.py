"""The main job on the embedded example.

Today the chain starts and ends at the generic head: it is loaded, exported ready for
cloning (GLB + feature points + FAPU) and previewed. Each stage that lands (photos →
points → head → texture → cloned FATs → speech) joins this same function, so
``recon example`` always runs everything the project can do.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

from mpeg4.generic_head import load_generic_head
from mpeg4.io import save_head, write_fdp_json, fdp_from_head
from mpeg4.preview import save_preview

__all__ = ["run_example"]


def run_example(out_dir: str | os.PathLike, progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """Run the main job on the embedded example and write its files to ``out_dir``.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created if needed). Existing files of the same names are
        replaced atomically.
    progress : callable, optional
        Called with a short message before each step.

    Returns
    -------
    dict of str to Path
        ``head`` (GLB), ``fdp`` (feature points and FAPU), ``preview`` (PNG).
    """
    say = progress or (lambda msg: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    say("loading the generic head")
    head = load_generic_head()
    paths = {"head": out / "head.glb", "fdp": out / "head.fdp.json", "preview": out / "preview.png"}
    say(f"writing {paths['head']}")
    save_head(head, paths["head"])
    write_fdp_json(paths["fdp"], fdp_from_head(head))
    say(f"rendering {paths['preview']} (front, side, three-quarter)")
    save_preview(head, paths["preview"])
    say(f"done in {time.perf_counter() - t0:.1f} s")
    return paths
