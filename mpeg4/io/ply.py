"""PLY meshes (scans, sculpting tools): read by trimesh as one part, ``skin``.

PLY carries no parts, feature points or animation; a ``.fdp.json`` beside the file (as
``fmc mark`` writes it) gives them, read by :func:`mpeg4.io.load_head`.
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import InputError, require_file
from ..head import Head, Part

__all__ = ["read_ply"]


def read_ply(path: str | os.PathLike) -> Head:
    """Read a PLY triangle mesh (ASCII or binary) as a head with one part, ``skin``.

    Vertices keep their order and the file's units; faces with more than three corners
    are triangulated by trimesh; per-vertex colours give the part's mean colour.

    Raises
    ------
    InputError
        The file is not a PLY mesh, or has no faces.
    """
    import trimesh

    path = require_file(path, "head file")
    try:
        mesh = trimesh.load(path, file_type="ply", process=False, force="mesh")
    except Exception as e:  # trimesh raises many kinds on a damaged file
        raise InputError(f"not a readable PLY mesh ({e.__class__.__name__}: {e})", where=path,
                         fix="export the head as a PLY triangle mesh") from None
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    if not len(faces):
        raise InputError("the file has no faces", where=path,
                         fix="export the head as a polygon mesh, not a point cloud")
    colour = (0.8, 0.8, 0.8)
    vc = getattr(getattr(mesh, "visual", None), "vertex_colors", None)
    if getattr(mesh.visual, "kind", None) == "vertex" and vc is not None and len(vc) == len(mesh.vertices):
        colour = tuple(float(c) for c in np.asarray(vc)[:, :3].mean(axis=0) / 255.0)
    return Head({"skin": Part("skin", np.asarray(mesh.vertices, dtype=np.float64), faces, colour=colour)},
                metadata={"source": os.path.basename(path)})
