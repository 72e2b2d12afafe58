"""Dense source, sparse target: what anti-aliasing can and cannot do for Facial Motion Cloning.

Source: the generic head (14,062 skin vertices) with its 53 ARKit shapes. Target: an ICT
FaceKit identity re-meshed by vertex clustering to about a third of its skin vertices
(``clone_accuracy.remesh``: the kept vertices are the identity's own, so the FAPU-scaled
ground truth is exact at each). Errors over the true displacements (``clone_accuracy.pyun``),
roughness as there (mean umbrella Laplacian over mean norm, over the face). Figures:

1. ``disc_*``: an Epanechnikov disc about each target vertex (Pandžić's anti-aliasing),
   its radius a fraction of the vertex's mean edge in the alignment space; 0.04 was the
   former default.
2. ``pointwise``: the interpolation takes each target vertex's motion at its own place in
   the source's alignment space, so a sparse target differs from a dense one only by where
   the alignment puts its vertices, and by the lip each vertex is on (told along each
   mesh: a vertex where the lips touch may fall to the other lip on the coarser mesh).
   The sparse target cloned with the dense target's alignment (at the kept vertices)
   against the dense target's clone at those vertices whose lip both meshes agree on.
3. ``representation``: how well the sparse mesh can carry the true motion at all. The
   sparse mesh's linear interpolation of vertex values, evaluated at every dense vertex
   (in the identity's own alignment space), against the dense truth: with the truth's own
   values at its vertices (point samples, what cloning aims at), with the values that fit
   it best (least squares: the limit of any filter), and with the point samples of the
   truth averaged over discs first (what an averaging anti-aliasing would give).
4. ``projection``: the clone's values fitted by least squares to the source's motion at
   the source's vertices carried onto the sparse mesh (the L2-optimal transfer), blended
   with the plain clone by a ridge ``lambda``: error at the vertices and over the surface.

Run: ``python3 benchmarks/clone_antialiasing.py [--target 2000]``. Prints ``name: value unit``
lines, the last a summary.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

FACE = 9409  # ICT's full face area: the first vertices
FRACTIONS = (0.04, 0.1, 0.2, 0.35, 0.5, 1.0)
RADII = (0.003, 0.0075, 0.015, 0.03)


def spacing(space: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(N,) mean length of each vertex's edges in the alignment space (angle, height), at
    most four times the median (the long edges at the back of the head)."""
    e = np.r_[triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]
    length = np.linalg.norm(space[e[:, 0], :2] - space[e[:, 1], :2], axis=1)
    count = np.bincount(e.ravel(), minlength=len(space))
    mean = np.bincount(e.ravel(), weights=np.r_[length, length], minlength=len(space)) / np.maximum(count, 1)
    return np.minimum(mean, 4 * np.median(mean[count > 0]))


def _usable(triangles: np.ndarray, space: np.ndarray) -> np.ndarray:
    a = space[triangles, 0]
    return triangles[a.max(axis=1) - a.min(axis=1) < np.pi]  # not across the back, where the angle wraps


def _height(head) -> float:
    return 0.5 * (head.fp_position("4.1")[1] + head.fp_position("4.2")[1]) - head.fp_position("2.1")[1]


class Case:
    """The source, a dense target, its sparse re-meshing and the ground truth on both."""

    def __init__(self, seed: int = 2000, names=None):
        import clone_accuracy as bench
        from shape_accuracy import NPZ

        from mpeg4.generic_head import load_generic_head

        self.bench = bench
        self.source = load_generic_head()
        self.names = names or [n for n in sorted(self.source.morph_targets) if not n.startswith("Pupil")]
        self.shapes = {m: self.source.morph_targets[m] for m in self.names}
        self.n = self.source.skin.n_vertices
        self.dense = bench.ict_target(load_generic_head(), np.load(NPZ), seed)
        self.sparse, self.kept = bench.remesh(self.dense)
        self.m = self.sparse.skin.n_vertices
        self.face = self.kept < FACE
        truth = bench.scaled_truth(self.source, self.dense, self.names)
        self.truth = {k: truth[k]["skin"].dense(self.n) for k in self.names}

    def field(self, weights, corr) -> dict[str, np.ndarray]:
        """The source's shapes through skin weights (sparse-target vertices × source vertices)."""
        return {k: (weights @ (self.shapes[k]["skin"].dense(self.n) / corr.source_scale)) * corr.target_scale
                for k in self.names}

    def error(self, field: dict) -> float:
        """Mean over the shapes of the error at the sparse target's vertices, % of the motion."""
        from mpeg4.head import SparseDisplacement

        return float(np.mean([self.bench.pyun({"skin": SparseDisplacement.from_dense(field[k])},
                                              {"skin": SparseDisplacement.from_dense(self.truth[k][self.kept])}, self.m)
                              for k in self.names]))

    def roughness(self, field: dict) -> float:
        return float(np.mean([self.bench.roughness(field[k], self.sparse.skin.triangles, self.face) for k in self.names]))

    def truth_field(self) -> dict:
        return {k: self.truth[k][self.kept] for k in self.names}

    def aligned(self, target):
        """Source and target skins in the common alignment space (:func:`fmc.clone.align_heads`)."""
        from fmc.clone import align_heads, alignment_space, triangulation_for

        tri, _ = triangulation_for(self.source, target)
        s, t, _ = align_heads(self.source, target, tri, alignment_space(self.source, self.source.skin.vertices),
                              alignment_space(target, target.skin.vertices))
        return s, t


def discs(case: Case, fractions=FRACTIONS) -> dict:
    """Error and roughness with no disc and with discs of ``fractions`` of the spacing."""
    import fmc.clone.cloning as cloning
    from fmc.clone import correspond, pin_feature_points, skin_weights
    from fmc.clone.parts import find_parts

    plain = correspond(case.source, case.sparse, antialias=0.0)
    out = {"plain": (case.error(case.field(plain.skin, plain)), case.roughness(case.field(plain.skin, plain)))}
    s_al, t_al = case.aligned(case.sparse)
    step = spacing(t_al, case.sparse.skin.triangles)
    s_parts, _ = find_parts(case.source)
    t_parts, _ = find_parts(case.sparse)
    from fmc.clone import alignment_space, lip_sides

    s_lip, t_lip, _ = lip_sides(case.source, case.sparse, alignment_space(case.source, case.source.skin.vertices),
                                alignment_space(case.sparse, case.sparse.skin.vertices))
    for f in fractions:
        w = pin_feature_points(skin_weights(case.source, s_al, t_al[:, :2], t_al[:, 2], s_lip, t_lip,
                                            cloning._in_skin(case.source, s_parts),
                                            cloning._in_skin(case.sparse, t_parts), f * step),
                               case.source, case.sparse)
        field = case.field(w, plain)
        out[f] = (case.error(field), case.roughness(field), float(np.median(f * step)))
    out["spacing"] = float(np.median(step))
    return out


def pointwise(case: Case) -> dict:
    """The sparse target cloned with the dense target's alignment, against the dense clone."""
    import fmc.clone.cloning as cloning
    from fmc.clone import alignment_space, correspond, lip_sides, pin_feature_points, skin_weights
    from fmc.clone.parts import find_parts

    dense = correspond(case.source, case.dense, antialias=0.0)
    plain = correspond(case.source, case.sparse, antialias=0.0)
    s_al, t_al = case.aligned(case.dense)
    s_parts, _ = find_parts(case.source)
    t_parts, _ = find_parts(case.sparse)
    s_lip, t_lip, _ = lip_sides(case.source, case.sparse, alignment_space(case.source, case.source.skin.vertices),
                                alignment_space(case.sparse, case.sparse.skin.vertices))
    w = pin_feature_points(skin_weights(case.source, s_al, t_al[case.kept, :2], t_al[case.kept, 2], s_lip, t_lip,
                                        cloning._in_skin(case.source, s_parts), cloning._in_skin(case.sparse, t_parts),
                                        0.0), case.source, case.sparse)
    moved = case.field(w, plain)
    full = {k: v[case.kept] for k, v in case.field(dense.skin, dense).items()}
    _, d_lip, _ = lip_sides(case.source, case.dense, alignment_space(case.source, case.source.skin.vertices),
                            alignment_space(case.dense, case.dense.skin.vertices))
    agree = d_lip[case.kept] == t_lip
    diff = max(float(np.abs(moved[k][agree] - full[k][agree]).max()) for k in case.names)
    scale = max(float(np.abs(full[k]).max()) for k in case.names)
    return {"max_difference": diff / scale, "lip_side_disagreements": int((~agree).sum()),
            "error_dense_alignment": case.error(moved),
            "roughness_dense_alignment": case.roughness(moved), "error_dense_clone": case.error(full),
            "error_own_alignment": case.error(case.field(plain.skin, plain)),
            "roughness_own_alignment": case.roughness(case.field(plain.skin, plain)),
            "roughness_truth": case.roughness(case.truth_field())}


def representation(case: Case, radii=RADII) -> dict:
    """Surface error (%) of the sparse mesh carrying the dense truth: point samples, the
    least-squares best, disc-averaged point samples."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    from fmc.clone import alignment_space, interpolation_matrix

    sp = alignment_space(case.dense, case.dense.skin.vertices)
    cs = sp[case.kept]
    at_dense = interpolation_matrix(sp[:, :2], sp[:, 2], cs, _usable(case.sparse.skin.triangles, cs), case.m,
                                    _height(case.dense))
    face = np.arange(case.n) < FACE
    rows = at_dense[face]
    lu = splu((rows.T @ rows + 1e-9 * sparse.eye(case.m)).tocsc())
    averaged = {r: interpolation_matrix(cs[:, :2], cs[:, 2], sp, _usable(case.dense.skin.triangles, sp), case.n,
                                        _height(case.dense), support=r) for r in radii}

    def err(values, d):
        r = at_dense @ values
        return 100 * np.linalg.norm(r[face] - d[face], axis=1).sum() / np.linalg.norm(d[face], axis=1).sum()

    out = {"point": [], "best": [], **{r: [] for r in radii}}
    for k in case.names:
        d = case.truth[k]
        out["point"].append(err(d[case.kept], d))
        out["best"].append(err(lu.solve(np.asarray(rows.T @ d[face])), d))
        for r in radii:
            out[r].append(err(averaged[r] @ d, d))
    return {k: float(np.mean(v)) for k, v in out.items()}


def projection(case: Case, lambdas=(0.2, 1.0, 5.0)) -> dict:
    """Vertex and surface errors of the plain clone and of its least-squares projections."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    from fmc.clone import alignment_space, correspond, interpolation_matrix

    plain = correspond(case.source, case.sparse, antialias=0.0)
    s_al, t_al = case.aligned(case.sparse)
    at_source = interpolation_matrix(s_al[:, :2], s_al[:, 2], t_al, _usable(case.sparse.skin.triangles, t_al), case.m,
                                     _height(case.sparse))
    sp = alignment_space(case.dense, case.dense.skin.vertices)
    cs = sp[case.kept]
    at_dense = interpolation_matrix(sp[:, :2], sp[:, 2], cs, _usable(case.sparse.skin.triangles, cs), case.m,
                                    _height(case.dense))
    face = np.arange(case.n) < FACE
    normal = (at_source.T @ at_source).tocsc()
    scale = float(np.median(normal.diagonal()[normal.diagonal() > 0]))

    def surface(field):
        return float(np.mean([100 * np.linalg.norm((at_dense @ field[k])[face] - case.truth[k][face], axis=1).sum()
                              / np.linalg.norm(case.truth[k][face], axis=1).sum() for k in case.names]))

    base = case.field(plain.skin, plain)
    out = {"plain": (case.error(base), surface(base))}
    for lam in lambdas:
        lu = splu((normal + lam * scale * sparse.eye(case.m)).tocsc())
        field = {}
        for k in case.names:
            u = case.shapes[k]["skin"].dense(case.n) / plain.source_scale
            field[k] = lu.solve(np.asarray(at_source.T @ u + lam * scale * (base[k] / plain.target_scale))) \
                * plain.target_scale
        out[lam] = (case.error(field), surface(field))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--target", type=int, default=2000, help="seed of the ICT identity")
    args = ap.parse_args(argv)
    from shape_accuracy import NPZ

    if not NPZ.exists():
        print(f"skipped: {NPZ} is absent (the ICT FaceKit test data)")
        return 0
    case = Case(args.target)
    print(f"target: {case.m} of {case.n} skin vertices, {len(case.names)} shapes")
    d = discs(case)
    from fmc.clone import alignment_space
    from fmc.clone.align import _median_edge

    edges = [_median_edge(alignment_space(h, h.skin.vertices), h.skin.triangles) for h in (case.source, case.sparse)]
    print(f"spacing_target_median: {d['spacing']:.4f} (alignment space; median edge over the face: source "
          f"{edges[0]:.4f}, target {edges[1]:.4f})")
    print(f"disc_none: error {d['plain'][0]:.3f} %, roughness {d['plain'][1]:.4f}")
    for f in FRACTIONS:
        e, r, radius = d[f]
        print(f"disc_{f:g}_of_spacing: radius {radius:.4f}, error {e:.3f} %, roughness {r:.4f}")
    p = pointwise(case)
    print(f"pointwise_max_difference: {p['max_difference']:.2e} of the largest motion (sparse target with the dense "
          f"target's alignment against the dense clone at the same vertices, on the same lip)")
    print(f"pointwise_lip_side_disagreements: {p['lip_side_disagreements']} vertices")
    print(f"pointwise_error: dense clone {p['error_dense_clone']:.3f} %, sparse with the dense alignment "
          f"{p['error_dense_alignment']:.3f} %, sparse with its own alignment {p['error_own_alignment']:.3f} %")
    print(f"pointwise_roughness: dense alignment {p['roughness_dense_alignment']:.4f}, own alignment "
          f"{p['roughness_own_alignment']:.4f}, truth {p['roughness_truth']:.4f}")
    r = representation(case)
    print(f"representation_surface_error: point samples {r['point']:.3f} %, least-squares best {r['best']:.3f} %, "
          + ", ".join(f"disc {k:g} {r[k]:.3f} %" for k in RADII))
    q = projection(case)
    print(f"projection: plain clone vertices {q['plain'][0]:.3f} %, surface {q['plain'][1]:.3f} %; "
          + "; ".join(f"lambda {k:g} vertices {q[k][0]:.3f} %, surface {q[k][1]:.3f} %" for k in q if k != "plain"))
    print(f"summary: no disc {d['plain'][0]:.3f} %, the former default disc {d[0.04][0]:.3f} %, discs of 0.2-1 of the "
          f"spacing {d[0.2][0]:.2f}-{d[1.0][0]:.2f} %; the sparse mesh carries the truth's point samples at "
          f"{r['point']:.2f} % over its surface against {r['best']:.2f} % at best, averaged samples {r[RADII[0]]:.2f} % "
          f"or worse")
    return 0


if __name__ == "__main__":
    sys.exit(main())
