"""Lowered lids in the photos, and the lids of the head built from them.

Synthetic people (:func:`recon.evaluate.synthetic.synthetic_pair`) are photographed with
their lids posed by the ICT FaceKit's ``eyeBlink`` shapes at several weights (0: the
identity's own open eyes); each pair is built by :func:`recon.shape.fit.fit_head` from the
photos' true points and from the automatically detected ones
(:func:`recon.landmarks.detect_images`, outliers dropped as ``recon build`` does), with
the neutral lids posed (:mod:`recon.shape.lids`, the default) and without. Per build, the
eyeball a front view sees between the lids on the pupil's vertical
(:func:`recon.evaluate.lids.visible_opening`) against the photographed head's, and how far
the lids go into the eyeball (:func:`recon.evaluate.lids.lid_penetration`), both eyes.

Run: ``python3 benchmarks/neutral_lids.py [--identities 3] [--blinks 0 0.3 0.6]``
Prints ``name: value unit`` lines: ``{points}_{posed|unposed}_blink{w}_opening_error_mm``
(median of |built - photographed| over eyes and people) and ``..._penetration_mm`` (the
largest).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--identities", type=int, default=3)
    ap.add_argument("--blinks", type=float, nargs="+", default=[0.0, 0.3, 0.6])
    args = ap.parse_args(argv)

    from mpeg4.errors import InputError
    from recon.evaluate.ict import default_ict_path
    from recon.evaluate.lids import lid_penetration, visible_opening
    from recon.evaluate.synthetic import synthetic_pair
    from recon.landmarks import detect_images
    from recon.shape.fit import fit_head

    if not default_ict_path().exists():
        print(f"# skipped: the ICT FaceKit is not at {default_ict_path()}")
        return 0
    results: dict[str, list] = {}
    for blink in args.blinks:
        for seed in range(args.identities):
            pair = synthetic_pair(seed, size=(768, 960), texture_size=512,
                                  expression={"eyeBlink_L": blink, "eyeBlink_R": blink})
            truth = {eye: visible_opening(pair.person.head, eye) for eye in ("left", "right")}
            sources = {"true": pair.fdp}
            try:
                detected = detect_images(pair.front, pair.side)
                detected.metadata["reviewed"] = False
                sources["detected"] = detected
            except InputError as e:
                print(f"# person {seed} blink {blink}: detection refused ({e})")
            for points, fdp in sources.items():
                for posed in (True, False):
                    key = f"{points}_{'posed' if posed else 'unposed'}_blink{blink:g}"
                    try:
                        head, _ = fit_head(fdp, ipd_mm=pair.person.ipd_mm, focal_px=pair.focal_px,
                                           neutral_lids=posed)
                    except InputError as e:
                        print(f"# {key} person {seed}: not built ({e})")
                        continue
                    for eye in ("left", "right"):
                        results.setdefault(key, []).append(
                            (abs(visible_opening(head, eye) - truth[eye]), lid_penetration(head, eye)))
            print(f"# person {seed} blink {blink:g}: photographed opening "
                  f"{truth['left']:.2f} / {truth['right']:.2f} mm", file=sys.stderr)
    for key, rows in results.items():
        rows = np.array(rows)
        print(f"{key}_opening_error_mm: {np.median(rows[:, 0]):.2f} (worst {rows[:, 0].max():.2f}, n={len(rows)})")
        print(f"{key}_penetration_mm: {rows[:, 1].max():.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
