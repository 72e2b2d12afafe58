"""The open mouth: does it read as a mouth (teeth in front, a dark cavity behind)?

On a head built from the embedded example's photos (or on the head GLBs given), the jaw
is opened (FAP 3 at 600 MNS, by the head's own tables or the generic head's) and the mouth
rendered from the front and from 30° to the side (:func:`recon.evaluate.mouth.opening_figures`).
Printed per head and view:

- ``opening_over_lips``: the opening's mean luminance over the lips' (between the inner and
  outer contours, 8.x): a cavity reads darker than the lips around it;
- ``teeth_over_tongue``: the mean luminance of teeth pixels over that of tongue pixels
  in the opening: teeth read lighter than the tongue behind them;
- ``teeth_share`` / ``tongue_share``: what share of the opening each covers;
- for the built head, the baked light (:func:`recon.texture.mouth.brightest_light` over the
  open and the bared poses, as the build finds it): its time,
  its mean over the tongue's front and back thirds, its median and largest value per part.

Run: ``python3 benchmarks/mouth_inside.py [HEAD.glb ...]``
Prints ``name: value`` lines (issue 22, item 4).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

VIEWS = (("front", 0.0, 0.0), ("three_quarter", 30.0, 5.0))


def example_head():
    """The example's head as ``recon example`` builds it (no tables: the generic head's open it)."""
    from recon.build import build_head, load_pair
    from recon.example import EXAMPLE_FDP, example_camera

    cam = example_camera()
    return build_head(load_pair(EXAMPLE_FDP), ipd_mm=cam["ipd_mm"], focal_px=cam["focal_px"],
                      texture_size=1024).head


def measure(head, label: str) -> None:
    from recon.evaluate.mouth import opening_figures

    for view, yaw, pitch in VIEWS:
        f = opening_figures(head, 600.0, yaw, pitch)
        name = f"{label}_{view}"
        print(f"{name}_opening_over_lips: {f.opening_over_lips:.3f}")
        print(f"{name}_teeth_over_tongue: {f.teeth_over_tongue:.2f}")
        print(f"{name}_teeth_share: {f.teeth_share:.3f}")
        print(f"{name}_tongue_share: {f.tongue_share:.3f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("heads", nargs="*", help="head GLBs (tables from <stem>_fat.npz beside them too)")
    args = ap.parse_args(argv)
    if args.heads:
        from fmc.heads import animated_head

        for path in args.heads:
            measure(animated_head(path), Path(path).parent.name or Path(path).stem)
        return 0
    from recon.texture.mouth import bared_pose, brightest_light, cavity_light, open_pose

    head = textured = example_head()
    triangles = {n: p.triangles for n, p in head.parts.items()}
    poses = [open_pose(head), bared_pose(head)]
    cavity_light(poses[0], triangles)  # warm-up (GL context)
    t0 = time.perf_counter()
    light = brightest_light(poses, triangles)
    print(f"mouth_light_seconds: {time.perf_counter() - t0:.3f}")
    z = head.parts["tongue"].vertices[:, 2]
    front, back = z >= np.quantile(z, 2 / 3), z <= np.quantile(z, 1 / 3)
    print(f"light_tongue_front_third_mean: {light['tongue'][front].mean():.4f}")
    print(f"light_tongue_back_third_mean: {light['tongue'][back].mean():.4f}")
    for n, v in light.items():
        print(f"light_{n}_median: {np.median(v):.3f}")
        print(f"light_{n}_max: {v.max():.3f}")
    measure(textured, "example")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
