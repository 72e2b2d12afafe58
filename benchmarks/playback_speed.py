"""FAT playback speed: frames per second of FAP values → vertices, for the generic head and
for the same head subdivided to 4× the triangles (about 4× the vertices), in one run.

The stream is speech-like: a viseme pair, an expression, jaw and lip-corner FAPs, eyelids,
eyeball and head rotations changing every frame. Tables are authored from the sculpted
shapes (``fmc.author``) for both heads.

Each frame's time is also given over that of a scipy sparse matrix-vector product with
all of the head's stored displacement components, measured in the same run (the issue's
yardstick: at most 1.5).

Run: ``python3 benchmarks/playback_speed.py``. Prints ``name: value unit`` lines.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def subdivide_head(head):
    """Every triangle split in four (midpoints); morph targets and FPs carried over."""
    import trimesh.remesh

    from mpeg4 import Head, Part, SparseDisplacement

    parts, targets = {}, {}
    for name, p in head.parts.items():
        dense = {t: tgt[name].dense(p.n_vertices) for t, tgt in head.morph_targets.items() if name in tgt}
        stacked = np.hstack([p.vertices] + list(dense.values()))
        v, f = trimesh.remesh.subdivide(stacked, p.triangles)  # new vertices are edge midpoints, appended
        parts[name] = Part(name, v[:, :3], f, colour=p.colour, centre=p.centre)
        for k, t in enumerate(dense):
            targets.setdefault(t, {})[name] = SparseDisplacement.from_dense(v[:, 3 + 3 * k:6 + 3 * k], tol=1e-7)
    return Head(parts, dict(head.feature_points), targets, metadata=dict(head.metadata))


def stream_values(n: int, rng) -> list[dict]:
    t = np.arange(n) / 25.0
    frames = []
    for k in range(n):
        s = np.sin(2 * np.pi * t[k] * 3)
        frames.append({(1, 10): 40 + 20 * s, (1, 1): 23 - 20 * s, (2, 1): 20.0, 3: 300 * abs(s), 12: 80 * s, 13: 80 * s,
                       19: 200 * max(0, s), 20: 200 * max(0, s), 23: 3000 * s, 24: 3000 * s, 48: -1500 * s,
                       49: 2500 * np.cos(t[k]), 31: 100 * s})
    return frames


def measure(player, frames) -> float:
    for f in frames[:20]:
        player.vertices(f)
    t = time.perf_counter()
    for f in frames:
        player.vertices(f)
    return len(frames) / (time.perf_counter() - t)


def main() -> int:
    from fmc.author import author_from_shapes
    from fmc.high_level import author_high_level
    from fmc.play import Player
    from mpeg4.generic_head import load_generic_head

    rng = np.random.default_rng(0)
    frames = stream_values(500, rng)
    results = {}
    for label, make in (("generic", lambda h: h), ("dense_4x", subdivide_head)):
        head = make(load_generic_head())
        t = time.perf_counter()
        fat, _ = author_from_shapes(head)
        fat.update(author_high_level(head))
        head.fat = fat
        t_author = time.perf_counter() - t
        t = time.perf_counter()
        player = Player(head)
        t_build = time.perf_counter() - t
        fps = measure(player, frames)
        results[label] = fps
        # The yardstick, in the same run: scipy's sparse matrix-vector product over every
        # stored displacement component of the head (what playing all tables at once costs).
        w = rng.random(player.matrix.shape[1])
        best = np.inf
        for _ in range(20):
            t = time.perf_counter()
            player.matrix @ w
            best = min(best, time.perf_counter() - t)
        n_v = sum(p.n_vertices for p in head.parts.values())
        n_t = sum(len(p.triangles) for p in head.parts.values())
        print(f"{label}_vertices: {n_v}")
        print(f"{label}_triangles: {n_t}")
        print(f"{label}_author_tables: {t_author:.2f} s")
        print(f"{label}_player_build: {t_build:.2f} s ({player.matrix.nnz} stored displacement components)")
        print(f"{label}_playback: {fps:.0f} frames/s")
        print(f"{label}_spmv_same_components: {best * 1e3:.2f} ms")
        print(f"{label}_frame_over_spmv: {1.0 / fps / best:.2f} (target <= 1.5)")
    print(f"summary: {results['generic']:.0f} frames/s for the generic head, {results['dense_4x']:.0f} frames/s "
          f"at 4x the triangles ({results['generic'] / results['dense_4x']:.1f}x slower)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
