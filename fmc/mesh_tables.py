"""Displacements made from a head's sculpted shapes, and the mesh tables that hold them.

The steps every table authored from shapes shares: the weighted sum of shapes over some
parts (:func:`combine_shapes`), the feature points' motion under a displacement
(:func:`fp_motion`), and the FaceDefTable holding the displacement at the FAP value, each
way (:func:`mesh_table`).
"""

from __future__ import annotations

import numpy as np

from mpeg4.fat import FaceDefMesh, FaceDefTable
from mpeg4.head import Head, SparseDisplacement

__all__ = ["combine_shapes", "fp_motion", "mesh_table"]


def combine_shapes(head: Head, names: list[str], w: np.ndarray, parts=None) -> dict[str, SparseDisplacement]:
    """Part → displacement of the weighted sum of shapes, over ``parts`` (all if None)."""
    out: dict[str, np.ndarray] = {}
    for name, wi in zip(names, w):
        if wi <= 0:
            continue
        for part, d in head.morph_targets[name].items():
            if parts is not None and part not in parts:
                continue
            dense = out.setdefault(part, np.zeros((head.parts[part].n_vertices, 3)))
            dense[d.indices] += wi * d.vectors
    # Motions under 10 µm at the authoring value are below anything a renderer shows and
    # would only bloat the tables (a combination of shapes touches most of the face).
    return {p: SparseDisplacement.from_dense(v, tol=1e-5) for p, v in out.items()}


def fp_motion(head: Head, disp: dict[str, SparseDisplacement], ids: list[str]) -> np.ndarray:
    """(K, 3) motion of the FPs ``ids`` under a displacement."""
    dense = {p: d.dense(head.parts[p].n_vertices) for p, d in disp.items()}
    out = np.zeros((len(ids), 3))
    for k, i in enumerate(ids):
        b = head.feature_points[i]
        if b.part in dense:
            out[k] = np.asarray(b.weights) @ dense[b.part][list(b.vertices)]
    return out


def mesh_table(head, n, by_sign, value, unit, high_level: int = 0) -> FaceDefTable:
    """A FaceDefTable from the displacement at +value (and −value)."""
    signs = sorted(by_sign)
    borders = [-value, 0.0, value] if len(signs) == 2 else [0.0, value]
    parts = sorted({p for d in by_sign.values() for p in d})
    table = FaceDefTable(n, high_level)
    for part in parts:
        idx = np.unique(np.concatenate([by_sign[s][part].indices for s in signs if part in by_sign[s]]))
        disp = np.zeros((len(idx), len(signs), 3))
        for j, s in enumerate(signs):
            d = by_sign[s].get(part)
            if d is not None:
                # Slope per FAP unit: the displacement reached at s * value, over s * value units.
                disp[np.searchsorted(idx, d.indices), j] = d.vectors / (s * value * unit)
        table.meshes.append(FaceDefMesh(part, borders, idx, disp))
    return table
