"""Feature points on head meshes from elsewhere: ``recon.mark`` against ICT FaceKit truth.

Each identity (``recon.evaluate.synthetic.remeshed_identity``: fixed seeds) is decimated per part by
quadric edge collapse to 25-55 % of its triangles with its vertex order shuffled (so no
vertex id or position survives), tilted by up to 10 degrees about a random axis, written
in a random unit (m, cm, mm) and axis convention (y up / z forward, z up / -y forward,
z up / +y forward, y up / -z forward), as a merged PLY, an OBJ of anonymous groups or a
GLB of anonymous meshes in turn. :func:`recon.mark.mark` finds its feature points; each
is compared with the identity's true point (on the original surface), in the identity's
own metric (the file's unit undone), so the error is what a user would see on the mesh.

The 2D detector is :func:`recon.landmarks.detect` when installed (the photo annotation's;
the targets apply to it: median <= 2 mm on the landmark-model points, <= 4 mm on the
rest), else the perfect 2D detector of :mod:`recon.evaluate.synthetic` (the true points seen by the
renders' cameras), which measures everything after detection. ``--detector`` chooses.

``by_rule`` gives the median error and confidence of the points each rule placed
(``fitted``: found and smoothed by the generic head fitted to the surface; ``shape``: the
fitted generic head's, for points a grey render cannot show), so that the confidences can
be checked against the errors.

Landmark-model points: those a front photo shows clearly (catalogue ``front = Y``), on the
skin and eyes; the rest: the ears, cheeks, skull, jaw, teeth, tongue and 7.1.

Run: ``python3 benchmarks/mark3d_accuracy.py [--identities 20] [--detector auto|landmarks|perfect]``
Prints ``name: value unit`` lines; the last line is a summary.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
NPZ = ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_facekit.npz"


def landmark_model_point(fp_id: str) -> bool:
    from mpeg4 import FEATURE_POINTS

    fp = FEATURE_POINTS[fp_id]
    return fp.front == "Y" and fp.group not in (6, 7) and fp_id not in ("9.8", "9.9", "9.10", "9.11")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--identities", type=int, default=20)
    parser.add_argument("--detector", choices=("auto", "landmarks", "perfect"), default="auto")
    parser.add_argument("--passes", type=int, default=2)
    args = parser.parse_args(argv)
    if not NPZ.exists():
        print(f"skipped: the ICT FaceKit data is missing ({NPZ})")
        return 0
    from mpeg4 import FEATURE_POINTS
    from mpeg4.errors import InputError
    from recon.mark import landmark_detector, mark
    from recon.evaluate.synthetic import load_ict, perfect_detector, remeshed_identity

    have = importlib.util.find_spec("recon.landmarks") is not None
    which = "landmarks" if args.detector == "landmarks" or (args.detector == "auto" and have) else "perfect"
    print(f"detector: {'recon.landmarks.detect' if which == 'landmarks' else 'perfect 2D detector (true points)'}")
    data = load_ict(NPZ)
    errors: dict[str, list[float]] = {}
    by_rule: dict[str, list[tuple[float, float]]] = {}  # how a point was placed -> (error, confidence)
    frame_ok, tilt_left, times, faces, failed = [], [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.identities):
            mf = remeshed_identity(seed, tmp, data)
            detect = landmark_detector() if which == "landmarks" else perfect_detector(mf.points)
            t0 = time.perf_counter()
            try:
                result = mark(mf.path, detect=detect, passes=args.passes)
            except InputError as e:
                failed.append(f"{seed}: {e.what}")
                continue
            times.append(time.perf_counter() - t0)
            faces.append(mf.faces)
            to_m = 1.0 / np.linalg.norm(mf.to_file[:3, 0])
            for i, h in result.hits.items():
                if i in mf.points:
                    p = result.frame.inverse(h.point[None])[0]
                    errors.setdefault(i, []).append(float(np.linalg.norm(p - mf.points[i]) * to_m * 1000))
                    by_rule.setdefault(h.how, []).append((errors[i][-1], h.confidence))
            f = result.frame
            frame_ok.append((f.unit, f.up, f.forward) == (mf.unit, mf.up, mf.forward))
            # What remains of the tilt: the found frame against the identity's own.
            truth = mf.to_file[:3, :3] * to_m  # neutral -> file rotation
            r = f.rotation @ truth
            tilt_left.append(float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))))
    groups = sorted({FEATURE_POINTS[i].group for i in errors})
    for g in groups:
        e = np.concatenate([errors[i] for i in errors if FEATURE_POINTS[i].group == g])
        print(f"group_{g}_median: {np.median(e):.2f} mm")
        print(f"group_{g}_p90: {np.percentile(e, 90):.2f} mm")
        print(f"group_{g}_within_3mm: {np.mean(e < 3.0) * 100:.1f} %")
    lm = np.concatenate([errors[i] for i in errors if landmark_model_point(i)])
    rest = np.concatenate([errors[i] for i in errors if not landmark_model_point(i)])
    allv = np.concatenate(list(errors.values()))
    worst = sorted(errors, key=lambda i: -np.median(errors[i]))[:5]
    done = args.identities - len(failed)
    print(f"meshes_marked: {done} of {args.identities}" + (f" (failed: {'; '.join(failed)})" if failed else ""))
    print(f"points_found: {len(allv) / max(done, 1):.1f} of 84 per mesh")
    print(f"landmark_points_median: {np.median(lm):.2f} mm")
    print(f"rest_median: {np.median(rest):.2f} mm")
    print(f"within_3mm: {np.mean(allv < 3.0) * 100:.1f} %")
    print("worst_points: " + ", ".join(f"{i} {np.median(errors[i]):.1f}" for i in worst) + " mm")
    rules = sorted(by_rule, key=lambda r: -len(by_rule[r]))
    print("by_rule: " + ", ".join(f"{r} {np.median([e for e, _ in by_rule[r]]):.1f} mm at confidence "
                                  f"{np.median([c for _, c in by_rule[r]]):.2f} ({len(by_rule[r])})" for r in rules))
    print(f"frame_correct: {np.mean(frame_ok) * 100:.0f} % (unit, up and forward)")
    print(f"tilt_left_median: {np.median(tilt_left):.2f} deg (applied: up to 10)")
    print(f"triangles_median: {np.median(faces):.0f}")
    print(f"time_per_mesh: {np.median(times):.2f} s")
    ok = np.median(lm) <= 2.0 and np.median(rest) <= 4.0 and not failed
    print(f"summary: {done} of {args.identities} re-meshed identities marked, {which} detector: "
          f"median {np.median(lm):.2f} mm on "
          f"landmark-model points (target 2), {np.median(rest):.2f} mm on the rest (target 4), "
          f"{np.mean(allv < 3.0) * 100:.0f} % within 3 mm, frame right on {np.mean(frame_ok) * 100:.0f} % "
          f"-> {'met' if ok else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
