"""Tables that leave other FAPs' points still, so FAPs given together add up as the standard says.

Each FAP moves its own feature point by value × FAPU along its axis, and FAPs given together
move each point by the sum of its own FAPs' motions (ISO/IEC 14496-2; the reference,
sections 3 and 5). A table authored from sculpted shapes or from the muscle model moves far
more than its own point: on the generic head the cheek puff moved the lip corners 2.6 times
as far as its own point, the chin raiser (``depress_chin``) lifted the lower lip by as much
as the chin boss, a lip corner's stretch lifted the cheek by half. A real stream sets many
FAPs at once, so every point moved by its own FAPs and by its neighbours': 78 % of the
feature-point frames of the nine Xface and six Greta streams were where the standard puts
them. Solving the frame's values so that the points come out right does not work: the
tables are too alike (the puff and the corner stretch move both points), and the values
found fold the face.

:func:`separate_tables` takes out of each table what it does to the other FAPs' points,
along those FAPs' axes, and changes the rest of the face as little and as smoothly as it
can. The correction is a field that is, at each feature point, the table's motion there
along its FAPs' axes (zero at the table's own point along its own axis); along the lip and
lid contours and the brows, the straight-line interpolation of those between the points
(so a contour between two held points does not wave); and over the rest of the skin the
bi-harmonic interpolation of these values (:func:`mpeg4.surface.bilaplacian`), falling
to nothing :data:`REACH` beyond the feature points. The copies of a seam vertex are one
vertex there. Each table keeps its own point's motion exactly, and the motion no FAP of
the standard governs (a lip's depth where no FAP pushes it) stays as authored.

Cloned tables (:mod:`fmc.clone`) carry the separation with them; separating them again on
the target changed nothing measurable on the example's head (98.0 % of the feature-point
frames where the standard puts them either way) and cost a little on foreign heads
(MakeHuman's FAPU conformance 47 to 44 %), so cloning does not.

Left as authored: the tables a caller keeps, the jaw's (:data:`fmc.author.JAW_FAPS`), whose carry of the lips and chin the player
takes out only when a stream moves those (:mod:`fmc.decouple`: a stream that only opens the
jaw keeps its lips on it); rotations (eyeballs, head turns); the visemes and expressions
(whole shapes of their own); parts other than the skin.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mpeg4.catalogue import FAPS
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable
from mpeg4.head import Head
from mpeg4.seams import merged_surface
from mpeg4.surface import bilaplacian, contour_path, edge_graph, smoothest_fill

__all__ = ["REACH", "CHAINS", "held_rows", "correction_basis", "separate_tables"]

#: Distance, metres, from the nearest feature point beyond which a correction is nothing.
REACH = 0.035

#: Feature-point chains along which a correction is interpolated in a straight line: the
#: lid margins, the lips' inner and outer contours and corners, the brows.
CHAINS = (
    ("3.11", "3.1", "3.7"), ("3.11", "3.3", "3.7"), ("3.12", "3.2", "3.8"), ("3.12", "3.4", "3.8"),
    ("2.4", "2.6", "2.2", "2.7", "2.5"), ("2.4", "2.8", "2.3", "2.9", "2.5"),
    ("8.3", "8.5", "8.1", "8.6", "8.4"), ("8.3", "8.7", "8.2", "8.8", "8.4"),
    ("8.3", "2.4"), ("8.4", "2.5"),
    ("4.1", "4.3", "4.5"), ("4.2", "4.4", "4.6"),
)

# Corrections under this share of a table's largest motion are not stored.
_KEEP = 1e-4


def held_rows(head: Head, fat=None) -> list[tuple[int, str, np.ndarray]]:
    """(FAP, feature point, (3,) axis) of every translation FAP with a table in ``fat``
    (default ``head.fat``) whose point lies on the skin: the motions the other tables
    must leave alone."""
    fat = (head.fat if fat is None else fat) or {}
    out = []
    for n in range(3, 69):
        fap = FAPS[n]
        b = head.feature_points.get(fap.feature_points[0])
        if (n, 0) in fat and fap.kind == "translation" and b is not None and b.part == "skin":
            out.append((n, fap.feature_points[0], np.asarray(fap.axis_vector, dtype=np.float64)))
    return out


def correction_basis(head: Head, points: list[str], reach: float = REACH) -> np.ndarray:
    """(V, P) for each of ``points`` the skin field that is 1 at it and 0 at the others,
    interpolated in a straight line along :data:`CHAINS` and bi-harmonically elsewhere,
    0 beyond ``reach`` metres of every point (V: the skin's vertices, seam copies alike).

    A chain's end that is not among ``points`` (an eye corner, which no FAP moves) holds
    every field at 0 there.
    """
    skin = head.skin
    _, inverse, v, t = merged_surface(skin.vertices, skin.triangles)
    col = {fp: k for k, fp in enumerate(points)}
    values = np.zeros((len(v), len(points)))
    held = np.zeros(len(v), bool)
    graph = None
    for chain in CHAINS:
        if not any(fp in col for fp in chain):
            continue
        graph = edge_graph(skin.vertices, skin.triangles) if graph is None else graph
        paths = contour_path(head, chain, graph)
        if paths is None:  # a point missing or the contour not found: the points alone hold
            continue
        for (a, b), path in zip(zip(chain[:-1], chain[1:]), paths):
            step = np.linalg.norm(np.diff(skin.vertices[path], axis=0), axis=1)
            s = np.r_[0.0, np.cumsum(step)] / max(step.sum(), 1e-12)
            rows = inverse[path]
            held[rows] = True
            values[rows] = 0.0
            if a in col:
                values[rows, col[a]] = 1.0 - s
            if b in col:
                values[rows, col[b]] = s
    for fp, k in col.items():
        rows = inverse[np.asarray(head.feature_points[fp].vertices)]
        held[rows] = True
        values[rows] = 0.0
        values[rows, k] = 1.0
    far, _ = cKDTree(np.array([head.fp_position(fp) for fp in points])).query(v)
    held |= far > reach
    if not held.all():
        values = smoothest_fill(bilaplacian(v, t), values, ~held)
    return values[inverse]


def separate_tables(head: Head, fat=None, *, keep, reach: float = REACH) -> FAT:
    """A copy of ``fat`` (default ``head.fat``) whose low-level skin tables leave the other
    FAPs' feature points still along those FAPs' axes (see the module's docstring); the
    tables kept as they are share their objects with ``fat``.

    Parameters
    ----------
    head : Head
    fat : FAT, optional
    keep : iterable of int
        FAPs whose tables stay as they are (the jaw's, :data:`fmc.author.JAW_FAPS`).
    reach : float
        See :data:`REACH`.
    """
    keep = frozenset(keep)
    given = (head.fat if fat is None else fat) or {}
    fat = FAT(given)
    rows = held_rows(head, given)
    points = sorted({fp for _, fp, _ in rows})
    if not points:
        return fat
    basis = correction_basis(head, points, reach)
    col = {fp: k for k, fp in enumerate(points)}
    # Per point, the (3, 3) projection onto the axes its FAPs fix.
    axes = {fp: np.zeros((3, 3)) for fp in points}
    for fp in points:
        for a in {tuple(a) for _, p, a in rows if p == fp}:
            axes[fp] += np.outer(a, a)
    bindings = {fp: (np.asarray(head.feature_points[fp].vertices), np.asarray(head.feature_points[fp].weights))
                for fp in points}
    n_skin = len(head.skin.vertices)
    for (n, hl), table in given.items():
        if hl or n in keep or FAPS[n].kind != "translation" or not any(m.part == "skin" for m in table.meshes):
            continue
        own_fp, own_axis = FAPS[n].feature_points[0], np.asarray(FAPS[n].axis_vector, dtype=np.float64)
        meshes = []
        for mesh in table.meshes:
            if mesh.part != "skin":
                meshes.append(mesh)
                continue
            dense = np.zeros((n_skin,) + mesh.displacements.shape[1:])
            dense[mesh.indices] = mesh.displacements
            residual = np.zeros((len(points),) + mesh.displacements.shape[1:])  # (P, intervals, 3)
            for fp, k in col.items():
                idx, w = bindings[fp]
                proj = axes[fp] - np.outer(own_axis, own_axis) if fp == own_fp else axes[fp]
                residual[k] = np.einsum("j,jic->ic", w, dense[idx]) @ proj
            correction = np.einsum("vp,pic->vic", basis, residual)
            size = np.abs(correction).max(axis=(1, 2))
            if not size.max(initial=0.0):
                meshes.append(mesh)
                continue
            dense -= correction
            stored = np.union1d(mesh.indices, np.flatnonzero(size > _KEEP * size.max()))
            meshes.append(FaceDefMesh("skin", mesh.borders, stored, dense[stored]))
        fat.add(FaceDefTable(table.fap, table.high_level, meshes, list(table.transforms)))
    return fat
