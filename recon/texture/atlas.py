"""Re-packing the skin's texture into a clean, non-overlapping atlas (xatlas).

The composite texture of :mod:`recon.texture` is an unrolled picture of the head: easy to
read and to retouch, but its charts overlap where the photos' layers meet and much of the
square is unused. Tools that bake lighting or paint in texture space want an atlas: every
triangle its own texels, charts packed tightly. :func:`repack` asks xatlas for one and
bakes the composite into it (:func:`recon.texture.bake.bake`); the head keeps its shape, feature
points, morph targets and animation tables (vertices xatlas splits along its chart seams
are duplicated with :func:`mpeg4.seams.split_vertices`).
"""

from __future__ import annotations

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head
from mpeg4.seams import split_vertices

from .bake import bake

__all__ = ["unwrap", "repack"]


def unwrap(vertices: np.ndarray, triangles: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An xatlas atlas of a mesh: its vertices split along the charts' seams.

    Parameters
    ----------
    vertices : (N, 3) float
    triangles : (M, 3) int
    size : int
        Side of the texture the atlas is packed for, pixels (charts lie a few texels
        apart, so that mip levels do not bleed).

    Returns
    -------
    source : (V', ) int64
        The original vertex of each atlas vertex: ``0 .. N-1`` first (each original keeps
        its index, so feature-point bindings and tables stay valid), the seams' extra
        copies after (:func:`mpeg4.seams.split_vertices` takes it as is).
    triangles : (M, 3) int64
        The same triangles, in order, over the atlas vertices.
    uv : (V', 2) float
        Texture coordinates, t = 0 at the bottom.
    """
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(np.asarray(vertices, np.float32), np.asarray(triangles, np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution = int(size)
    pack.padding = max(2, size // 256)  # texels between charts, so mip levels do not bleed
    pack.bilinear = True
    atlas.generate(pack_options=pack)
    vmap, tris, uv = atlas[0] if hasattr(atlas, "__getitem__") else atlas.get_mesh(0)
    vmap = vmap.astype(np.int64)
    tris = tris.astype(np.int64)
    if tris.shape != np.shape(triangles):
        raise InputError(f"xatlas returned {len(tris)} triangles for {len(triangles)}", where="atlas")
    n = len(vertices)
    first = np.full(n, -1, dtype=np.int64)
    order = np.arange(len(vmap))
    first[vmap[::-1]] = order[::-1]  # the first atlas vertex of each original
    new_index = np.empty(len(vmap), dtype=np.int64)
    has = first >= 0
    new_index[first[has]] = np.flatnonzero(has)
    extra = np.setdiff1d(order, first[has])
    new_index[extra] = n + np.arange(len(extra))
    source = np.r_[np.arange(n), vmap[extra]]
    new_uv = np.zeros((len(source), 2))
    new_uv[new_index] = uv
    return source, new_index[tris], new_uv


def repack(head: Head, size: int = 2048, part: str = "skin") -> Head:
    """A copy of ``head`` whose ``part`` texture is re-packed into an xatlas atlas.

    Parameters
    ----------
    head : Head
        With texture coordinates and a texture on ``part``.
    size : int
        Side of the baked atlas, pixels.
    part : str

    Returns
    -------
    Head
    """
    p = head.parts.get(part)
    if p is None or p.uv is None or p.texture is None:
        raise InputError(f"part '{part}' has no texture to re-pack", where="atlas",
                         fix="texture the head first (recon build)")
    source, new_tris, new_uv = unwrap(p.vertices, p.triangles, size)
    # Bake: each triangle, corner by corner, from the composite layout into the atlas.
    baked = bake(p.texture, p.uv, new_uv, p.triangles, new_tris, (size, size))
    out = split_vertices(head, part, source, new_tris, uv=new_uv, texture=baked)
    out.metadata = dict(out.metadata, atlas={"part": part, "size": size, "charts_vertices": int(len(source))})
    return out
