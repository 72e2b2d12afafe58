"""Speed of the exact Sibson coordinates against scipy's RBFInterpolator, in one run.

The control set is the generic head's feature points plus the 27 bounding points; the
queries are all the head's vertices. Then how the cost grows with the number of queries
and of control points (extra controls are skin vertices picked at random).

Run: ``python3 benchmarks/dffd_speed.py``. Prints ``name: value unit`` lines.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def best_of(f, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> int:
    from scipy.interpolate import RBFInterpolator

    from mpeg4.generic_head import load_generic_head
    from recon.shape.deform import bounding_controls
    from recon.shape.sibson import NaturalNeighbours

    head = load_generic_head()
    verts = np.concatenate([p.vertices for p in head.parts.values()])
    _, fps = head.fp_array()
    fps = np.unique(fps.round(9), axis=0)  # 11.5 shares 11.4's vertex on the hairless head
    controls = np.vstack([fps, bounding_controls(verts)])
    moved = controls + np.random.default_rng(0).normal(0, 0.003, controls.shape)
    print(f"queries: {len(verts)} vertices")
    print(f"controls: {len(controls)} points ({len(fps)} distinct feature points + 27 bounding)")

    t_build = best_of(lambda: NaturalNeighbours(controls))
    nn = NaturalNeighbours(controls)
    t_sibson = best_of(lambda: nn.coordinates(verts))
    t_rbf = best_of(lambda: RBFInterpolator(controls, moved - controls, kernel="thin_plate_spline")(verts))
    w = nn.coordinates(verts)
    print(f"delaunay_build: {t_build * 1000:.1f} ms")
    print(f"sibson_coordinates_all_vertices: {t_sibson:.3f} s")
    print(f"sibson_nonzeros_per_vertex: {w.nnz / len(verts):.1f}")
    print(f"rbf_thin_plate_fit_and_eval: {t_rbf:.3f} s")
    print(f"sibson_over_rbf_time_ratio: {t_sibson / t_rbf:.2f}")

    rng = np.random.default_rng(1)
    for frac in (0.25, 0.5, 1.0):
        q = verts[rng.choice(len(verts), int(frac * len(verts)), replace=False)]
        print(f"scaling_queries_{len(q)}: {best_of(lambda: nn.coordinates(q), 2):.3f} s")
    skin = head.skin.vertices
    for extra in (0, 100, 300):
        c = np.vstack([controls, skin[rng.choice(len(skin), extra, replace=False)]]) if extra else controls
        c = np.unique(c.round(9), axis=0)
        n = NaturalNeighbours(c)
        print(f"scaling_controls_{len(c)}: {best_of(lambda: n.coordinates(verts), 2):.3f} s "
              f"({len(n.simplices)} tetrahedra)")
    print(f"summary: exact Sibson coordinates for {len(verts)} vertices and {len(controls)} controls in "
          f"{t_sibson:.2f} s ({t_sibson / t_rbf:.2f}x the time of a thin-plate RBF)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
