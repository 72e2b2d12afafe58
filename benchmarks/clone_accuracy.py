"""Facial motion cloning accuracy and speed against the ICT FaceKit's ground truth.

Source: the generic head with its 53 ARKit shapes. Targets: ICT identities (fixed seeds)
on the same topology, so every cloned vertex has a true counterpart. Errors are Pyun et
al.'s: sum of vertex position errors over sum of displacement norms × 100, averaged over
the cloned shapes, on the skin.

- source → source;
- source → target → source (round trip);
- source → target against the ICT shape on the target, two ways: the raw ICT delta (ICT
  applies one delta to every identity) and that delta scaled per vertex by the ratio of
  the two heads' region FAPU (what the standard's FAPU normalisation implies).

Run: ``python3 benchmarks/clone_accuracy.py [--targets 3]``. Prints ``name: value unit`` lines.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


NARROW_FACE = slice(0, 6706)  # ICT's "Narrow face area": the face without the neck and the sides


def pyun(cloned: dict, truth: dict, n: int, region=slice(None)) -> float:
    c = (cloned["skin"].dense(n) if "skin" in cloned else np.zeros((n, 3)))[region]
    g = (truth["skin"].dense(n) if "skin" in truth else np.zeros((n, 3)))[region]
    den = np.linalg.norm(g, axis=1).sum()
    return 100 * np.linalg.norm(c - g, axis=1).sum() / den if den > 0 else 0.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=3)
    args = ap.parse_args(argv)
    from shape_accuracy import NPZ, identity_vertices, part_vertices

    if not NPZ.exists():
        print(f"skipped: {NPZ} is absent (the ICT FaceKit test data)")
        return 0
    from fmc.clone import clone_targets, normalisation
    from mpeg4.generic_head import load_generic_head
    from mpeg4.head import Head, SparseDisplacement

    source = load_generic_head()
    names = [n for n in sorted(source.morph_targets) if not n.startswith("Pupil")]
    n = source.skin.n_vertices
    t = time.perf_counter()
    self_clone = clone_targets(source, source, names)
    t_self = time.perf_counter() - t
    e_self = np.mean([pyun(self_clone[k], source.morph_targets[k], n) for k in names])
    print(f"source_to_source: {e_self:.4f} %")
    print(f"clone_time_{len(names)}_targets: {t_self:.2f} s ({1000 * t_self / len(names):.0f} ms per target)")
    data = np.load(NPZ)
    trips, raw, scaled, trips_face = [], [], [], []
    for k in range(args.targets):
        target = load_generic_head()
        target = target.with_vertices(part_vertices(target, identity_vertices(data, np.random.default_rng(2000 + k))))
        target.morph_targets = {}
        there = clone_targets(source, target, names)
        back = clone_targets(Head(target.parts, target.feature_points, there, metadata=target.metadata), source, names)
        trips.append(np.mean([pyun(back[m], source.morph_targets[m], n) for m in names]))
        trips_face.append(np.mean([pyun(back[m], source.morph_targets[m], n, NARROW_FACE) for m in names]))
        raw.append(np.mean([pyun(there[m], source.morph_targets[m], n) for m in names]))
        ratio = normalisation(target) / normalisation(source)
        truth = {m: {"skin": SparseDisplacement.from_dense(source.morph_targets[m]["skin"].dense(n) * ratio)}
                 for m in names}
        scaled.append(np.mean([pyun(there[m], truth[m], n) for m in names]))
        print(f"target_{k}: round trip {trips[-1]:.2f} % (narrow face {trips_face[-1]:.2f} %), vs ICT delta {raw[-1]:.2f} %, "
              f"vs FAPU-scaled ICT delta {scaled[-1]:.2f} %")
    print(f"round_trip_mean: {np.mean(trips):.2f} %")
    print(f"round_trip_narrow_face_mean: {np.mean(trips_face):.2f} %")
    print(f"source_to_target_vs_ict_mean: {np.mean(raw):.2f} %")
    print(f"source_to_target_vs_fapu_scaled_ict_mean: {np.mean(scaled):.2f} %")
    print(f"summary: source->source {e_self:.4f} %, round trip {np.mean(trips):.2f} % over {args.targets} targets, "
          f"{len(names)} shapes cloned in {t_self:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
