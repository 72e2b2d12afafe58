"""The MakeHuman hm08 head from the shared test data, with its artist-made targets.

``../shared/data/foreign_heads/makehuman/base.obj`` is a whole body in decimetres (+y up,
+z forward, +x the figure's left); its first 13 380 vertices are the body, the rest helper
geometry. The head is the body's vertices above the shoulders (y > 5.85 dm: the neck's
half-width is 0.5–0.6 dm up to 5.8 dm and the shoulders spread below; the chin's lowest
point is at 6.15 dm), in metres. Its
``.target`` files (FACSHuman action units and emotions, HBC visemes: ``vertex dx dy dz``
lines, indices into ``base.obj``) become morph targets of that head.

:func:`reference_points` reads the feature points placed on it by hand
(``recon/data/makehuman_hm08_points.csv``, how they were made in its header), and
:func:`marking_error` measures points found on the head against them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head, Part, SparseDisplacement

__all__ = ["MAKEHUMAN_DIR", "REFERENCE_POINTS", "makehuman_head", "read_target", "reference_points", "marking_error"]

#: The shared MakeHuman folder beside the project.
MAKEHUMAN_DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "foreign_heads" / "makehuman"

#: The hand-placed feature points of the hm08 mesh.
REFERENCE_POINTS = Path(__file__).resolve().parents[1] / "data" / "makehuman_hm08_points.csv"

_BODY = 13380  # vertices of the body group; the rest are helpers
_NECK_DM = 5.85  # the head is the body above this height, decimetres


def read_target(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """A MakeHuman ``.target``: (k,) vertex indices into ``base.obj`` and (k, 3) decimetres."""
    rows = np.loadtxt(path, ndmin=2, comments="#")
    if rows.size == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    if rows.shape[1] != 4:
        raise InputError(f"a target line has {rows.shape[1]} numbers, not 4 (vertex dx dy dz)", where=os.fspath(path))
    return rows[:, 0].astype(np.int64), rows[:, 1:4]


def makehuman_head(folder: str | os.PathLike = MAKEHUMAN_DIR, targets: Mapping[str, str] | None = None) -> Head:
    """The hm08 head, metres, one part ``skin`` (no feature points), with ``targets``
    (name → path under ``folder``) as morph targets."""
    import trimesh

    folder = Path(folder)
    # maintain_order: the targets index the file's own vertex list, which UVs would split.
    mesh = trimesh.load(folder / "base.obj", process=False, force="mesh", skip_materials=True, maintain_order=True)
    v, f = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    keep = (np.arange(len(v)) < _BODY) & (v[:, 1] > _NECK_DM)
    tri = f[keep[f].all(axis=1)]
    ids = np.unique(tri)
    slot = np.full(len(v), -1, dtype=np.int64)
    slot[ids] = np.arange(len(ids))
    morph = {}
    for name, rel in (targets or {}).items():
        idx, d = read_target(folder / rel)
        on = slot[idx] >= 0
        morph[name] = {"skin": SparseDisplacement(slot[idx[on]], d[on] * 0.1)}
    return Head({"skin": Part("skin", v[ids] * 0.1, slot[tri])}, morph_targets=morph,
                metadata={"units": "m", "name": "MakeHuman hm08 head"})


def reference_points(folder: str | os.PathLike = MAKEHUMAN_DIR) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """The hand-placed feature points on the head of :func:`makehuman_head` (metres, its frame),
    and how far each reading may be off (metres)."""
    import csv

    import trimesh

    mesh = trimesh.load(Path(folder) / "base.obj", process=False, force="mesh", skip_materials=True,
                        maintain_order=True)
    v = np.asarray(mesh.vertices, dtype=np.float64) * 0.1
    rows = [line for line in REFERENCE_POINTS.read_text().splitlines() if line and not line.startswith("#")]
    points, unsure = {}, {}
    for row in csv.DictReader(rows):
        idx = np.array(row["vertices"].split(), dtype=np.int64)
        w = np.array(row["weights"].split(), dtype=np.float64)
        points[row["fp"]] = w @ v[idx]
        unsure[row["fp"]] = float(row["uncertainty_mm"]) / 1000.0
    return points, unsure


def marking_error(found: Mapping[str, np.ndarray], reference: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Per feature point both give, the distance between them in % of the reference's eye
    separation (ES0: its pupils' distance across)."""
    es0 = abs(float(reference["3.5"][0] - reference["3.6"][0]))
    return {i: 100.0 * float(np.linalg.norm(np.asarray(found[i]) - reference[i])) / es0
            for i in reference if i in found}
