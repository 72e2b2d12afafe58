"""Texture speed: composite + blend + texture coordinates at 1024² and 2048², both blends.

On the embedded example (its photos and feature points, the head fitted to them), times
:func:`recon.texture.texture_skin` — what each photo sees of the head, the layout of every
skin vertex, the side photo warped along the feature lines (and flipped), the three layers
blended — at two texture sizes with OpenCV's multi-band blender, keeping the photos' light
(``delight=False``), then with the photos de-lit first (the default, :mod:`recon.texture.delight`,
which costs the same at any texture size; its normal renders double as the visibility step's
depth renders, so they count there), and the blend alone at the larger size: OpenCV's 16-bit
spline band by band (the default), OpenCV's own blender (the same bytes) and the scikit-image
pyramids, in one run. Best of ``--repeat`` runs.

Run: ``python3 benchmarks/texture_speed.py [--repeat 3]``
Prints ``name: value unit`` lines; the last line is a summary. Target: the de-lit default at
2048² in ≤ 1.0 s on 2 cores (issue 22).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    from recon.build import load_pair
    from recon.texture.cameras import fit_camera
    from recon.example import EXAMPLE_FDP, example_camera
    from recon.shape.fit import fit_head
    from recon.texture.blend import blend_multiband
    from recon.texture import texture_skin

    cam = example_camera()
    pair = load_pair(EXAMPLE_FDP)
    head, _ = fit_head(pair.fdp, ipd_mm=cam["ipd_mm"], focal_px=cam["focal_px"])
    pts = head.fp_positions()
    cams = {n: fit_camera(pts, pair.fdp.views[n].points, pair.fdp.views[n].width, pair.fdp.views[n].height,
                          focal_px=cam["focal_px"]) for n in ("front", "side")}
    texture_skin(head, pair.front, pair.side, cams["front"], cams["side"], size=512)  # warm-up (GL context)
    results = {}
    for size, delight in ((1024, False), (2048, False), (2048, True)):
        best = None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            st = texture_skin(head, pair.front, pair.side, cams["front"], cams["side"], size=size, delight=delight)
            dt = time.perf_counter() - t0
            if best is None or dt < best[0]:
                best = (dt, st.timings)
        results[size, delight] = best
        dt, tm = best
        name = f"texture_{size}" + ("_delit" if delight else "")
        print(f"{name}_total: {dt:.3f} s")
        for step in ("visibility", "layout") + (("delight",) if delight else ()) + ("warp", "blend"):
            print(f"{name}_{step}: {tm[step]:.3f} s")
    # The two blend implementations on the same layers, in one run.
    layers, masks = st.layers, st.masks
    times = {}
    for method in ("opencv", "opencv-detail", "skimage"):
        best = float("inf")
        for _ in range(args.repeat if method != "skimage" else 1):
            t0 = time.perf_counter()
            blend_multiband(layers, masks, method=method)
            best = min(best, time.perf_counter() - t0)
        times[method] = best
        print(f"blend_2048_{method.replace('-', '_')}: {best:.3f} s")
    print(f"blend_2048_skimage_over_opencv: {times['skimage'] / times['opencv']:.1f} x")
    total = results[2048, False][0]
    delit = results[2048, True]
    met = "met" if delit[0] <= 1.0 else "not met"
    print(f"summary: de-lit texture at 2048² in {delit[0]:.2f} s (target 1.0 s: {met}; "
          f"de-lighting {delit[1]['delight']:.2f} s), keeping the light {total:.2f} s; "
          f"OpenCV's spline {times['opencv']:.2f} s (its blender {times['opencv-detail']:.2f} s), "
          f"scikit-image {times['skimage']:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
