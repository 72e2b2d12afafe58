"""Facial motion cloning accuracy and speed against the ICT FaceKit's ground truth.

Source: the generic head with its 53 ARKit shapes. Targets: ICT identities (fixed seeds;
``neutral + sum z_i identity_i``, z ~ N(0, 1)) on the same topology, so every cloned
vertex has a true counterpart; their eyeball centres move with their eyeballs. Errors are
on the skin, averaged over the cloned shapes, two ways:

- Pyun et al.'s eq. 12, ``Σ‖x − x̂‖ / Σ‖x‖ × 100`` with x the true vertex positions of
  the moved head (model frame, metres, origin inside the head) and x̂ the cloned ones;
- the same errors over the displacement norms, ``Σ‖x − x̂‖ / Σ‖x − x_neutral‖ × 100``:
  relative to the motion itself, so about 140 times stricter (the generic head's skin
  vertices lie 0.105 m from its origin on average, its shapes move them by 0.73 mm). Every line without "positions"
  in its name is this one.

"narrow face" restricts the sums to ICT's narrow face area (no neck, no mouth socket, no
eye sockets). Per test pair:

- source → source;
- source → target → source (round trip);
- source → target against the ICT shape on the target. ICT applies one and the same
  delta to every identity; the standard's FAPU normalisation instead scales motion with
  the face, so the ground truth is ICT's delta multiplied per vertex and axis by the ratio
  of the two heads' region FAPU scales (:func:`fmc.clone.normalisation`, target over
  source); the raw delta is printed beside it;
- the same with a Delaunay triangulation of the source's feature points instead of the
  shipped one, and with the piecewise-affine map between the feature points instead of
  the bi-harmonic surface map;
- source → target with the target re-meshed to about a third of its skin vertices (vertex
  clustering that keeps original vertices, so the ground truth is exact there), as cloned
  (no anti-aliasing) and with a disc of 0.02 averaging the motion, and the roughness of
  the cloned displacement field (the mean norm of its umbrella Laplacian over the mean
  norm of the field, over the face) beside that of the ground truth on the same mesh:
  aliasing shows as roughness above the truth's, blur as roughness below it
  (``benchmarks/clone_antialiasing.py`` looks at the sparse target more closely).

Speed: every morph target of a source with animation tables (the 53 shapes and the FAT's
targets) cloned onto an identity at the generic head's resolution, by :func:`fmc.clone.clone`.

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
FACE = slice(0, 9409)  # ICT's "Full face area"


def pyun(cloned: dict, truth: dict, n: int, region=slice(None), neutral: np.ndarray | None = None) -> float:
    """The error of a cloned morph target in per cent over the skin vertices ``region``.

    With ``neutral`` (N, 3), the true head's skin vertices (metres), Pyun et al.'s eq. 12:
    the errors over the norms of the moved head's vertex positions; without, over the
    norms of the true displacements.
    """
    c = (cloned["skin"].dense(n) if "skin" in cloned else np.zeros((n, 3)))[region]
    g = (truth["skin"].dense(n) if "skin" in truth else np.zeros((n, 3)))[region]
    den = np.linalg.norm(g if neutral is None else neutral[region] + g, axis=1).sum()
    return 100 * np.linalg.norm(c - g, axis=1).sum() / den if den > 0 else 0.0


def ict_target(generic, data, seed: int):
    """The generic head on an ICT identity (seeded), without morph targets; each eyeball's
    centre moves by its vertices' mean displacement."""
    from shape_accuracy import identity_vertices, part_vertices

    head = generic.with_vertices(part_vertices(generic, identity_vertices(data, np.random.default_rng(seed))))
    for name, part in head.parts.items():
        if part.centre is not None:
            part.centre = part.centre + (part.vertices - generic.parts[name].vertices).mean(axis=0)
    head.morph_targets = {}
    return head


def scaled_truth(source, target, names) -> dict:
    """ICT's deltas (on the source) scaled by the target's over the source's region FAPU."""
    from fmc.clone import normalisation
    from mpeg4.head import SparseDisplacement

    n = source.skin.n_vertices
    ratio = normalisation(target) / normalisation(source)
    return {m: {"skin": SparseDisplacement.from_dense(source.morph_targets[m]["skin"].dense(n) * ratio)} for m in names}


def remesh(head, fraction: float = 1 / 3):
    """The head with its skin re-meshed by vertex clustering to about ``fraction`` of its
    vertices.

    Vertices are clustered on a grid (its cell found by bisection), apart by the lip they
    are on and by the main direction of their normal (so the lips and the two sides of
    thin folds do not weld); each cluster keeps one of its own vertices (a feature point's
    where it holds one), so the re-meshed skin's vertices are vertices of the original.

    Returns
    -------
    head : Head
    kept : (M,) int64
        The original skin index of each new vertex.
    """
    from fmc.clone import LIP_FPS, alignment_space, lip_classes
    from mpeg4.head import FeaturePointBinding, Part
    from mpeg4.render import vertex_normals

    skin = head.skin
    v = skin.vertices
    normals = vertex_normals(v, skin.triangles)
    axis = np.argmax(np.abs(normals), axis=1)
    bucket = 2 * axis + (normals[np.arange(len(v)), axis] > 0)
    space = alignment_space(head, v)
    lip = lip_classes(space, dict(zip(LIP_FPS, alignment_space(head, np.array([head.fp_position(i) for i in LIP_FPS])))))
    forced = np.unique([k for b in head.feature_points.values() if b.part == "skin" for k in b.vertices])

    def cluster(cell):
        key = np.c_[np.floor(v / cell).astype(np.int64), bucket, lip.astype(np.int64)]
        _, label = np.unique(key, axis=0, return_inverse=True)
        label = label.ravel()
        rep = np.full(label.max() + 1, -1)
        # Feature-point vertices first: each keeps itself; a second one in a cluster
        # becomes a cluster of its own.
        for k in forced:
            if rep[label[k]] < 0:
                rep[label[k]] = k
            else:
                label[k] = len(rep)
                rep = np.r_[rep, k]
        centroid = np.zeros((len(rep), 3))
        np.add.at(centroid, label, v)
        centroid /= np.bincount(label, minlength=len(rep))[:, None]
        d = np.linalg.norm(v - centroid[label], axis=1)
        order = np.lexsort((d, label))
        first = order[np.r_[True, label[order][1:] != label[order][:-1]]]
        free = rep < 0
        rep[label[first][free[label[first]]]] = first[free[label[first]]]
        return label, rep

    lo, hi = 1e-4, 0.05
    for _ in range(14):
        mid = np.sqrt(lo * hi)
        label, rep = cluster(mid)
        lo, hi = (mid, hi) if len(rep) > fraction * len(v) else (lo, mid)
    label, rep = cluster(hi)
    new_of_rep = np.full(len(v), -1)
    new_of_rep[rep] = np.arange(len(rep))
    tri = new_of_rep[rep[label[skin.triangles]]]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])]
    _, first = np.unique(np.sort(tri, axis=1), axis=0, return_index=True)
    tri = tri[np.sort(first)]
    out = head.copy()
    out.parts["skin"] = Part("skin", v[rep], tri, None if skin.uv is None else skin.uv[rep], skin.texture, skin.colour)
    out.feature_points = {i: (FeaturePointBinding("skin", tuple(int(new_of_rep[k]) for k in b.vertices), b.weights)
                              if b.part == "skin" else b) for i, b in head.feature_points.items()}
    out.morph_targets = {}
    return out, rep


def roughness(displacement: np.ndarray, triangles: np.ndarray, region: np.ndarray) -> float:
    """Mean norm of the umbrella Laplacian of a (N, 3) field over its mean norm, over the
    vertices ``region`` (bool mask)."""
    from scipy import sparse

    n = len(displacement)
    e = np.r_[triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]
    e = np.unique(np.sort(e, axis=1), axis=0)
    adj = sparse.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                            shape=(n, n)).tocsr()
    deg = np.asarray(adj.sum(axis=1)).ravel()
    lap = displacement - (adj @ displacement) / np.maximum(deg, 1)[:, None]
    norm = np.linalg.norm(displacement[region], axis=1).mean()
    return float(np.linalg.norm(lap[region], axis=1).mean() / norm) if norm > 0 else 0.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=3)
    args = ap.parse_args(argv)
    from shape_accuracy import NPZ

    if not NPZ.exists():
        print(f"skipped: {NPZ} is absent (the ICT FaceKit test data)")
        return 0
    from fmc.author import author_from_shapes
    from fmc.high_level import author_high_level
    from fmc.clone import clone, correspond
    from mpeg4.fat import fat_to_morph_targets
    from mpeg4.generic_head import load_generic_head
    from mpeg4.head import Head, SparseDisplacement

    source = load_generic_head()
    names = [n for n in sorted(source.morph_targets) if not n.startswith("Pupil")]
    n = source.skin.n_vertices
    shapes = {m: source.morph_targets[m] for m in names}
    x_s = source.skin.vertices
    self_cloned = correspond(source, source).transfer(shapes)
    e_self = np.mean([pyun(v, shapes[m], n) for m, v in self_cloned.items()])
    e_self_pos = np.mean([pyun(v, shapes[m], n, neutral=x_s) for m, v in self_cloned.items()])
    print(f"source_to_source_positions: {e_self_pos:.4f} %")
    print(f"source_to_source: {e_self:.4f} %")
    data = np.load(NPZ)
    rows = []
    for k in range(args.targets):
        target = ict_target(load_generic_head(), data, 2000 + k)
        there = correspond(source, target).transfer(shapes)
        back = correspond(Head(target.parts, target.feature_points, there, metadata=target.metadata),
                          source).transfer(there)
        truth = scaled_truth(source, target, names)
        r = dict(trip_pos=np.mean([pyun(back[m], shapes[m], n, neutral=x_s) for m in names]),
                 scaled_pos=np.mean([pyun(there[m], truth[m], n, neutral=target.skin.vertices) for m in names]),
                 trip=np.mean([pyun(back[m], shapes[m], n) for m in names]),
                 trip_face=np.mean([pyun(back[m], shapes[m], n, NARROW_FACE) for m in names]),
                 raw=np.mean([pyun(there[m], shapes[m], n) for m in names]),
                 scaled=np.mean([pyun(there[m], truth[m], n) for m in names]),
                 scaled_face=np.mean([pyun(there[m], truth[m], n, NARROW_FACE) for m in names]))
        # The same with a Delaunay triangulation of the source's feature points.
        there_d = correspond(source, target, triangulation="delaunay").transfer(shapes)
        back_d = correspond(Head(target.parts, target.feature_points, there_d, metadata=target.metadata), source,
                            triangulation="delaunay").transfer(there_d)
        r["trip_delaunay"] = np.mean([pyun(back_d[m], shapes[m], n) for m in names])
        r["scaled_delaunay"] = np.mean([pyun(there_d[m], truth[m], n) for m in names])
        # The same with the piecewise-affine map between the feature points.
        there_a = correspond(source, target, alignment="affine").transfer(shapes)
        back_a = correspond(Head(target.parts, target.feature_points, there_a, metadata=target.metadata), source,
                            alignment="affine").transfer(there_a)
        r["trip_affine"] = np.mean([pyun(back_a[m], shapes[m], n) for m in names])
        r["scaled_affine"] = np.mean([pyun(there_a[m], truth[m], n) for m in names])
        # The re-meshed target: ground truth at the kept vertices.
        coarse, kept = remesh(target)
        m_c = coarse.skin.n_vertices
        face = kept < FACE.stop
        truth_c = {m: {"skin": SparseDisplacement.from_dense(truth[m]["skin"].dense(n)[kept])} for m in names}
        for label, support in (("plain", 0.0), ("aa02", 0.02)):
            corr = correspond(source, coarse, antialias=support)
            cl = corr.transfer(shapes)
            r[f"coarse_{label}"] = np.mean([pyun(cl[m], truth_c[m], m_c) for m in names])
            r[f"rough_{label}"] = np.mean([roughness(cl[m]["skin"].dense(m_c), coarse.skin.triangles, face)
                                           for m in names])
        r["rough_truth"] = np.mean([roughness(truth_c[m]["skin"].dense(m_c), coarse.skin.triangles, face) for m in names])
        r["coarse_n"] = m_c
        rows.append(r)
        print(f"target_{k}_positions: round trip {r['trip_pos']:.4f} %, vs FAPU-scaled ICT {r['scaled_pos']:.4f} %")
        print(f"target_{k}: round trip {r['trip']:.2f} % (narrow face {r['trip_face']:.2f} %), "
              f"vs FAPU-scaled ICT {r['scaled']:.2f} % (narrow face {r['scaled_face']:.2f} %), "
              f"vs raw ICT delta {r['raw']:.2f} %")
        print(f"target_{k}_delaunay: round trip {r['trip_delaunay']:.2f} %, vs FAPU-scaled ICT {r['scaled_delaunay']:.2f} %")
        print(f"target_{k}_affine: round trip {r['trip_affine']:.2f} %, vs FAPU-scaled ICT {r['scaled_affine']:.2f} %")
        print(f"target_{k}_remeshed ({m_c} of {n} skin vertices): vs FAPU-scaled ICT {r['coarse_plain']:.3f} % "
              f"as cloned, {r['coarse_aa02']:.3f} % with a disc of 0.02; face roughness {r['rough_plain']:.4f} as "
              f"cloned, {r['rough_aa02']:.4f} with the disc, ground truth {r['rough_truth']:.4f}")
    mean = {key: np.mean([r[key] for r in rows]) for key in rows[0]}
    print(f"round_trip_positions_mean: {mean['trip_pos']:.4f} %")
    print(f"source_to_target_vs_fapu_scaled_ict_positions_mean: {mean['scaled_pos']:.4f} %")
    print(f"round_trip_mean: {mean['trip']:.2f} %")
    print(f"round_trip_narrow_face_mean: {mean['trip_face']:.2f} %")
    print(f"source_to_target_vs_fapu_scaled_ict_mean: {mean['scaled']:.2f} %")
    print(f"source_to_target_vs_fapu_scaled_ict_narrow_face_mean: {mean['scaled_face']:.2f} %")
    print(f"source_to_target_vs_raw_ict_mean: {mean['raw']:.2f} %")
    print(f"delaunay_triangulation_mean: round trip {mean['trip_delaunay']:.2f} %, vs FAPU-scaled ICT "
          f"{mean['scaled_delaunay']:.2f} %")
    print(f"affine_alignment_mean: round trip {mean['trip_affine']:.2f} %, vs FAPU-scaled ICT "
          f"{mean['scaled_affine']:.2f} %")
    print(f"remeshed_vs_fapu_scaled_ict_mean: {mean['coarse_plain']:.3f} % as cloned, "
          f"{mean['coarse_aa02']:.3f} % with a disc of 0.02")
    print(f"remeshed_face_roughness_mean: {mean['rough_plain']:.4f} as cloned, {mean['rough_aa02']:.4f} with a disc of "
          f"0.02, {mean['rough_truth']:.4f} ground truth")
    # Speed: all morph targets of a source with animation tables, at full resolution.
    fat, _ = author_from_shapes(source)
    fat.update(author_high_level(source))
    source.fat = fat
    n_targets = len(source.morph_targets) + len(fat_to_morph_targets(fat, source.fapu)[0])
    target = ict_target(load_generic_head(), data, 2000)
    t0 = time.perf_counter()
    clone(source, target)
    dt = time.perf_counter() - t0
    print(f"clone_time_{n_targets}_targets: {dt:.2f} s ({1000 * dt / n_targets:.1f} ms per target, "
          f"{target.skin.n_vertices} skin vertices)")
    print(f"summary: Pyun's eq. 12 (positions) source->source {e_self_pos:.4f} %, round trip {mean['trip_pos']:.4f} %, "
          f"vs FAPU-scaled ICT {mean['scaled_pos']:.4f} %; over the motion source->source {e_self:.4f} %, round trip "
          f"{mean['trip']:.2f} %, vs FAPU-scaled ICT {mean['scaled']:.2f} % over {args.targets} targets; "
          f"{n_targets} targets cloned in {dt:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
