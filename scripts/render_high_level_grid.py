"""Render the generic head's 15 visemes and 7 expressions into labelled grids, one per route.

Usage: ``python3 scripts/render_high_level_grid.py [--method shapes|muscles|both] [--docs docs]``
writes ``docs/high_level_grid.png`` (from the sculpted shapes) and
``docs/high_level_grid_muscles.png`` (from the muscle model, the shapes unused).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fmc.high_level import author_high_level  # noqa: E402
from fmc.muscles import MuscleRig, author_from_muscles, author_high_level_from_muscles  # noqa: E402
from mpeg4 import EXPRESSIONS, VISEMES, apply_fat  # noqa: E402
from mpeg4.camera import Camera  # noqa: E402
from mpeg4.generic_head import load_generic_head  # noqa: E402
from mpeg4.io.atomic import atomic_write  # noqa: E402
from mpeg4.preview import head_meshes  # noqa: E402
from mpeg4.render import render  # noqa: E402


def _high_level(method: str):
    head = load_generic_head()
    if method == "shapes":
        head.fat = author_high_level(head)
    else:
        head.morph_targets = {}  # the model needs the feature points only
        rig = MuscleRig.from_head(head)
        author_from_muscles(head, rig=rig)
        head.fat = author_high_level_from_muscles(rig)
    return head


def render_grid(method: str, cell: int) -> np.ndarray:
    """BGR image of the 22 high-level poses authored by ``method``."""
    head = _high_level(method)
    neutral = {n: p.vertices for n, p in head.parts.items()}
    _, fps = head.fp_array([i for i in head.feature_points if i.split(".")[0] in ("2", "3", "4", "8", "9")])
    h, w = cell, int(cell * 0.85)
    cam = Camera.fit(fps, w, h, yaw_deg=20, pitch_deg=5, margin=0.12, focal_px=3.0 * h)
    keys = [((1, v), f"viseme {v} {VISEMES[v].name}") for v in range(15)]
    keys += [((2, e), f"expression {e} {EXPRESSIONS[e].name}") for e in range(7)]
    cells = []
    for key, label in keys:
        moved = apply_fat(head.fat, neutral, {key: 63.0}, head.fapu)
        image = np.ascontiguousarray(render(head_meshes(head, moved), cam)[..., ::-1])
        cv2.putText(image, label, (6, h - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (30, 30, 30), 1, cv2.LINE_AA)
        cv2.putText(image, method, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (90, 90, 160), 1, cv2.LINE_AA)
        cells.append(image)
    cols = 6
    while len(cells) % cols:
        cells.append(np.full_like(cells[0], 255))
    rows = [np.concatenate(cells[r:r + cols], axis=1) for r in range(0, len(cells), cols)]
    return np.concatenate(rows, axis=0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", choices=("shapes", "muscles", "both"), default="both")
    ap.add_argument("--docs", type=Path, default=ROOT / "docs", help="folder the grids go to")
    ap.add_argument("--cell", type=int, default=260, help="cell height in pixels")
    args = ap.parse_args(argv)
    names = {"shapes": "high_level_grid.png", "muscles": "high_level_grid_muscles.png"}
    for method in (("shapes", "muscles") if args.method == "both" else (args.method,)):
        ok, data = cv2.imencode(".png", render_grid(method, args.cell), [cv2.IMWRITE_PNG_COMPRESSION, 9])
        path = args.docs / names[method]
        with atomic_write(path, "wb") as f:
            f.write(data.tobytes())
        print(f"written: {path} ({len(data) / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
