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

__all__ = ["repack"]


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
    import xatlas

    p = head.parts.get(part)
    if p is None or p.uv is None or p.texture is None:
        raise InputError(f"part '{part}' has no texture to re-pack", where="atlas",
                         fix="texture the head first (recon build)")
    atlas = xatlas.Atlas()
    atlas.add_mesh(p.vertices.astype(np.float32), p.triangles.astype(np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution = int(size)
    pack.padding = max(2, size // 256)  # texels between charts, so mip levels do not bleed
    pack.bilinear = True
    atlas.generate(pack_options=pack)
    vmap, tris, uv = atlas[0] if hasattr(atlas, "__getitem__") else atlas.get_mesh(0)
    vmap = vmap.astype(np.int64)
    tris = tris.astype(np.int64)
    if tris.shape != p.triangles.shape:
        raise InputError(f"xatlas returned {len(tris)} triangles for {len(p.triangles)}", where="atlas")
    # Order the atlas's vertices so that each original vertex keeps its index (its first
    # copy), the extra copies after: feature-point bindings and tables stay valid.
    n = p.n_vertices
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
    new_tris = new_index[tris]
    # Bake: each triangle, corner by corner, from the composite layout into the atlas.
    baked = bake(p.texture, p.uv, new_uv, p.triangles, new_tris, (size, size))
    out = split_vertices(head, part, source, new_tris, uv=new_uv, texture=baked)
    out.metadata = dict(out.metadata, atlas={"part": part, "size": size, "charts_vertices": int(len(source))})
    return out
