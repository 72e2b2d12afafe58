"""Offscreen rendering speed: the generic head at preview size, and the whole preview sheet.

Run: ``python3 benchmarks/render_speed.py``. Prints ``name: value unit`` lines.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def main() -> int:
    t0 = time.perf_counter()
    from mpeg4.render import Camera, _gl, render

    _gl()
    print(f"context_creation: {(time.perf_counter() - t0) * 1000:.0f} ms")
    from mpeg4.generic_head import load_generic_head
    from mpeg4.preview import head_meshes, preview_image

    head = load_generic_head()
    meshes = head_meshes(head)
    n_tri = sum(len(m.triangles) for m in meshes)
    cam = Camera.fit(np.concatenate([m.vertices for m in meshes]), 576, 720, yaw_deg=35, pitch_deg=10)
    times = []
    for _ in range(5):
        t = time.perf_counter()
        render(meshes, cam, return_depth=True)
        times.append(time.perf_counter() - t)
    print(f"triangles: {n_tri}")
    print(f"render_576x720_with_depth_median: {np.median(times) * 1000:.0f} ms")
    t = time.perf_counter()
    preview_image(head)
    sheet = time.perf_counter() - t
    print(f"preview_sheet_3_views: {sheet:.2f} s")
    print(f"summary: {n_tri} triangles at 576x720 in {np.median(times) * 1000:.0f} ms per view (colour + depth), "
          f"labelled 3-view preview in {sheet:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
