"""Offscreen rendering speed: context creation, a 50k-triangle sheet at 720x900, the generic
head at preview size, and the whole preview sheet.

Run: ``python3 benchmarks/render_speed.py``. Prints ``name: value unit`` lines, the last one
a summary.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def _median_ms(fn, repeats: int = 5) -> float:
    fn()  # warm-up: shader variants and driver caches
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)) * 1000


def _wavy_sheet(n_side: int):
    """A bumpy (n_side+1)^2-vertex sheet of 2 n_side^2 triangles, 0.2 m across."""
    g = np.linspace(0.0, 1.0, n_side + 1)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    v = np.c_[0.2 * gx.ravel() - 0.1, 0.25 * gy.ravel() - 0.125,
              0.03 * np.sin(9 * gx.ravel()) * np.cos(7 * gy.ravel())]
    q = (np.arange(n_side)[:, None] * (n_side + 1) + np.arange(n_side)).ravel()
    tris = np.r_[np.c_[q, q + 1, q + n_side + 2], np.c_[q, q + n_side + 2, q + n_side + 1]]
    return v, tris


def main() -> int:
    t0 = time.perf_counter()
    from mpeg4.camera import Camera
    from mpeg4.render import RenderMesh, _gl, render

    t1 = time.perf_counter()
    gl = _gl()
    t2 = time.perf_counter()
    print(f"import_render_module: {(t1 - t0) * 1000:.0f} ms")
    print(f"egl_context_creation: {(t2 - t1) * 1000:.0f} ms")
    print(f"gl_renderer: {gl.renderer}")

    v, tris = _wavy_sheet(158)  # 49,928 triangles
    sheet = [RenderMesh(v, tris)]
    cam = Camera.fit(v, 720, 900, yaw_deg=35, pitch_deg=10, focal_px=2000.0)
    colour_ms = _median_ms(lambda: render(sheet, cam))
    depth_ms = _median_ms(lambda: render(sheet, cam, return_depth=True))
    plain_ms = _median_ms(lambda: render(sheet, cam, samples=1))
    print(f"sheet_triangles: {len(tris)}")
    print(f"sheet_720x900_colour_msaa4_median: {colour_ms:.0f} ms")
    print(f"sheet_720x900_colour_depth_msaa4_median: {depth_ms:.0f} ms")
    print(f"sheet_720x900_colour_no_msaa_median: {plain_ms:.0f} ms")

    from mpeg4.generic_head import load_generic_head
    from mpeg4.preview import head_meshes, preview_image

    head = load_generic_head()
    meshes = head_meshes(head)
    n_tri = sum(len(m.triangles) for m in meshes)
    cam = Camera.fit(np.concatenate([m.vertices for m in meshes]), 576, 720, yaw_deg=35, pitch_deg=10)
    head_ms = _median_ms(lambda: render(meshes, cam, return_depth=True))
    print(f"generic_head_triangles: {n_tri}")
    print(f"generic_head_576x720_colour_depth_median: {head_ms:.0f} ms")
    t = time.perf_counter()
    preview_image(head)
    sheet_s = time.perf_counter() - t
    print(f"preview_sheet_3_views: {sheet_s:.2f} s")
    print(f"summary: context {(t2 - t1) * 1000:.0f} ms; {len(tris)} triangles at 720x900 in {colour_ms:.0f} ms "
          f"(colour) / {depth_ms:.0f} ms (colour + depth); generic head {head_ms:.0f} ms per view; "
          f"labelled 3-view preview {sheet_s:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
