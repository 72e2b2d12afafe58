"""Authoring and deformation speed of the two FAT routes on the generic head, in one run.

- time to author the full FAT set (66 low-level FAPs, 15 visemes, 7 expressions) from the
  sculpted shapes (``fmc.author``) and from the muscle model (``fmc.muscles``: placing the
  model, fitting each FAP, evaluating the visemes and expressions);
- conformance of each route's tables through the decoder: for every translation FAP at
  ±512, the feature point's error against ``value × FAPU`` along the axis (for the jaw,
  the motion along the axis) and the largest motion of an unrelated point, relative;
- the muscle model's per-frame deformation (FAP values → vertices through the parametric
  layer, the muscles and the combination rule) for a speech-like stream, beside FAT
  playback of the same frames through the muscle route's tables (``fmc.play.Player``).

Run: ``python3 benchmarks/muscle_speed.py [--frames 200]``. Prints ``name: value unit`` lines.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages first


def frames(n: int) -> list[dict]:
    """Speech-like low-level FAP values: jaw, lips, corners, lids, brows, eyes, head."""
    t = np.arange(n) / 25.0
    out = []
    for k in range(n):
        s = np.sin(2 * np.pi * t[k] * 3)
        out.append({3: 300 * abs(s), 4: 30 * s, 5: 30 * s, 53: 60 * s, 54: 60 * s, 59: 80 * s, 60: 80 * s,
                    19: 200 * max(0, s), 20: 200 * max(0, s), 31: 100 * s, 32: 100 * s, 41: 60 * abs(s),
                    23: 3000 * s, 24: 3000 * s, 48: -1500 * s, 49: 2500 * np.cos(t[k])})
    return out


def conformance(head, fat) -> tuple[np.ndarray, np.ndarray]:
    """Per translation FAP and sign: relative FP error and relative leak (the tests' measure)."""
    from fmc.author import unrelated
    from mpeg4 import FAPS, FP_IDS, apply_fat
    from mpeg4.fat import fap_unit

    neutral = {n: p.vertices for n, p in head.parts.items()}
    ids = [i for i in FP_IDS if i in head.feature_points]
    base = np.array([head.fp_position(i) for i in ids])
    errors, leaks = [], []
    for n in range(3, 69):
        fap = FAPS[n]
        if fap.kind != "translation":
            continue
        k = ids.index(fap.feature_points[0])
        bad = unrelated(fap.feature_points[0], ids)
        for value in ((512.0,) if fap.direction == "U" else (512.0, -512.0)):
            moved = apply_fat(fat, neutral, {n: value}, head.fapu)
            motion = np.array([head.fp_position(i, moved) for i in ids]) - base
            goal = value * fap_unit(n, head.fapu) * fap.axis_vector
            g = np.linalg.norm(goal)
            errors.append(abs(motion[k] @ goal / g - g) / g if n in (3, 14, 15) else np.linalg.norm(motion[k] - goal) / g)
            leaks.append(np.linalg.norm(motion[bad], axis=1).max() / g)
    return np.array(errors), np.array(leaks)


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    args = ap.parse_args(argv)

    from fmc.author import author_from_shapes
    from fmc.high_level import author_high_level
    from fmc.muscles import MuscleRig, author_from_muscles, author_high_level_from_muscles
    from fmc.play import Player
    from mpeg4.generic_head import load_generic_head

    state = {}
    head = load_generic_head()
    bare = load_generic_head()
    bare.morph_targets = {}

    def shapes():
        fat, _ = author_from_shapes(head)
        fat.update(author_high_level(head))
        state.update(shapes=fat)

    def muscles():
        rig = MuscleRig.from_head(bare)
        fat, _ = author_from_muscles(bare, rig=rig)
        fat.update(author_high_level_from_muscles(rig))
        state.update(rig=rig, fat=fat)

    t_shapes = best_of(shapes)
    t_muscles = best_of(muscles)
    print(f"author_shapes: {t_shapes:.2f} s")
    print(f"author_muscles: {t_muscles:.2f} s")
    for label, h, fat in (("shapes", head, state["shapes"]), ("muscles", bare, state["fat"])):
        err, leak = conformance(h, fat)
        print(f"conformance_{label}_fp_error: median {np.median(err):.1%}, worst {err.max():.1%} "
              f"over {len(err)} FAP directions")
        print(f"conformance_{label}_unrelated_leak: median {np.median(leak):.1%}, worst {leak.max():.1%}")
    rig = state["rig"]
    t_place = best_of(lambda: MuscleRig.from_head(bare))
    print(f"muscle_model_placement: {t_place:.2f} s ({len(rig.muscles)} muscles over {len(rig.support)} skin vertices)")

    stream = frames(args.frames)
    for f in stream[:10]:
        rig.deform_faps(f)
    t = time.perf_counter()
    for f in stream:
        rig.deform_faps(f)
    per_frame = (time.perf_counter() - t) / len(stream)
    bare.fat = state["fat"]
    player = Player(bare)
    for f in stream[:10]:
        player.vertices(f)
    t = time.perf_counter()
    for f in stream:
        player.vertices(f)
    per_frame_fat = (time.perf_counter() - t) / len(stream)
    n_v = sum(p.n_vertices for p in bare.parts.values())
    print(f"muscle_model_frame: {per_frame * 1000:.2f} ms ({1 / per_frame:.0f} frames/s, {n_v} vertices)")
    print(f"fat_playback_frame: {per_frame_fat * 1000:.2f} ms ({1 / per_frame_fat:.0f} frames/s, the muscle route's tables)")
    print(f"summary: full FAT set in {t_shapes:.2f} s from shapes, {t_muscles:.2f} s from muscles "
          f"({t_shapes / t_muscles:.1f}x); muscle model {per_frame * 1000:.1f} ms/frame, "
          f"{per_frame / per_frame_fat:.0f}x FAT playback")
    return 0


if __name__ == "__main__":
    sys.exit(main())
