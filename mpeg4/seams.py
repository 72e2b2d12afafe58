"""Duplicating vertices along texture seams, with every per-vertex table kept in step.

A texture layout may give one surface point two texture coordinates (a seam): the vertex
is then stored twice, once per side of the seam, at the same place. :func:`split_vertices`
does that to one part of a head: the original vertices keep their indices (feature-point
bindings stay valid) and the duplicates are appended, each moving exactly as its original
in every morph target and Facial Animation Table, so the two copies never tear apart.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError
from .head import Head, SparseDisplacement

__all__ = ["seam_copies", "merged_surface", "split_vertices"]


def seam_copies(vertices: np.ndarray, decimals: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """The copies of one place among a part's (N, 3) vertices (the two sides of a seam).

    Returns
    -------
    first : (M,) int64
        The first vertex at each distinct place (coordinates rounded to ``decimals``).
    inverse : (N,) int64
        Each vertex's place: ``vertices[first[inverse]]`` is ``vertices`` within rounding.
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if not len(v):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    _, first, inverse = np.unique(np.round(v, decimals), axis=0, return_index=True, return_inverse=True)
    return first.astype(np.int64), inverse.reshape(-1).astype(np.int64)


def merged_surface(vertices: np.ndarray, triangles: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A part's surface with the copies of each seam vertex made one (:func:`seam_copies`).

    Returns
    -------
    first, inverse : (M,) and (N,) int64
        As :func:`seam_copies`: a field on the merged surface ``f`` is ``f[inverse]`` on
        the part, and a field on the part ``g`` is ``g[first]`` on the merged surface.
    vertices : (M, 3) float64
    triangles : (T', 3) int64
        The part's triangles on the merged vertices, those a merge made degenerate left out.
    """
    first, inverse = seam_copies(vertices)
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)[first]
    t = inverse[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)]
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])]
    return first, inverse, v, t


def _extend(indices: np.ndarray, rows: np.ndarray, source: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices and rows (per listed vertex) with the duplicates of listed vertices added."""
    pos = np.full(n, -1, dtype=np.int64)
    pos[indices] = np.arange(len(indices))
    dup = np.arange(n, len(source))
    hit = pos[source[n:]] >= 0
    new_idx = np.r_[indices, dup[hit]]
    new_rows = np.concatenate([rows, rows[pos[source[n:][hit]]]]) if len(rows) else rows
    order = np.argsort(new_idx, kind="stable")
    return new_idx[order], new_rows[order]


def split_vertices(head: Head, part: str, source: np.ndarray, triangles: np.ndarray,
                   uv: np.ndarray | None = None, texture: np.ndarray | None = None) -> Head:
    """A copy of the head with one part's vertices duplicated.

    Parameters
    ----------
    head : Head
    part : str
        The part to split (usually ``"skin"``).
    source : (V',) int
        For each vertex of the split part, the original vertex it copies. The first N
        entries must be ``0 .. N-1`` (the originals keep their indices).
    triangles : (M, 3) int
        The part's triangles over the split vertices.
    uv : (V', 2) float, optional
        Texture coordinates of the split vertices.
    texture : (H, W, 3) uint8, optional
        The part's texture.

    Returns
    -------
    Head
        Morph targets and FATs of the part list every duplicate of a vertex they move, with
        the same displacement. ``metadata["duplicated_vertices"][part]`` lists the original
        of each duplicate (vertex ``N + k`` copies entry ``k``).
    """
    if part not in head.parts:
        raise InputError(f"the head has no part '{part}'", where="split_vertices", fix=f"use one of {sorted(head.parts)}")
    p = head.parts[part]
    n = p.n_vertices
    source = np.asarray(source, dtype=np.int64).reshape(-1)
    if len(source) < n or (source[:n] != np.arange(n)).any():
        raise InputError("the split must keep the original vertices first, in order", where="split_vertices",
                         fix="list 0..N-1 first in `source`, duplicates after")
    if len(source) and (source.min() < 0 or source.max() >= n):
        raise InputError(f"a duplicate copies a vertex outside 0..{n - 1}", where="split_vertices")
    out = head.copy()
    q = out.parts[part]
    q.vertices = p.vertices[source].copy()
    q.triangles = np.asarray(triangles, dtype=np.int64)
    if q.triangles.size and (q.triangles.min() < 0 or q.triangles.max() >= len(source)):
        raise InputError(f"a triangle index is outside 0..{len(source) - 1}", where="split_vertices")
    q.uv = None if uv is None else np.asarray(uv, dtype=np.float64).reshape(len(source), 2)
    if texture is not None:
        q.texture = np.ascontiguousarray(texture, dtype=np.uint8)
    q.__post_init__()
    for target in out.morph_targets.values():
        d = target.get(part)
        if d is not None:
            idx, vec = _extend(d.indices, d.vectors, source, n)
            target[part] = SparseDisplacement(idx, vec)
    # Per-vertex links kept in metadata (such as the generic head's ICT vertex ids) refer
    # to the originals; the duplicates' originals are recorded beside them.
    dups = dict(out.metadata.get("duplicated_vertices", {}))
    old = np.asarray(dups.get(part, []), dtype=np.int64)
    base_of = np.r_[np.arange(n - len(old)), old]  # current vertex → the vertex it first copied
    dups[part] = np.r_[old, base_of[source[n:]]].tolist()
    out.metadata = dict(out.metadata, duplicated_vertices=dups)
    if out.fat is not None:
        for table in out.fat.values():
            for mesh in table.meshes:
                if mesh.part == part:
                    mesh.indices, mesh.displacements = _extend(mesh.indices, mesh.displacements, source, n)
    return out
