"""Reading and writing heads and their companions, one module per format.

- :mod:`mpeg4.io.gltf`: GLB/glTF 2.0 heads (parts, textures, morph targets, feature points,
  FAPU, Facial Animation Tables);
- :mod:`mpeg4.io.obj`: OBJ + MTL + PNG heads, with the feature points in a ``.fdp.json``
  beside them;
- :mod:`mpeg4.io.ply`: PLY meshes (one part), their feature points in a ``.fdp.json`` beside them;
- :mod:`mpeg4.io.fdp_json`: ``*.fdp.json`` annotations and 3D feature points;
- :mod:`mpeg4.io.fap`: MPEG-4 ``.fap`` animation streams;
- :mod:`mpeg4.io.greta`: Greta's expression tables (action units as FAP values);
- :mod:`mpeg4.io.atomic`: every writer replaces files atomically.

:func:`load_head` and :func:`save_head` choose the format by the file extension.
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path

from ..errors import InputError, require_file
from .atomic import atomic_write

__all__ = ["atomic_write", "load_head", "save_head", "HEAD_FORMATS", "read_glb", "write_glb", "read_obj",
           "write_obj", "read_fdp_json", "write_fdp_json", "fdp_from_head", "apply_fdp", "FdpFile",
           "ViewAnnotation", "read_fap", "write_fap", "parse_fap", "format_fap", "FapStream", "describe_fap"]

#: Extensions → (reader, writer) names; None where the format cannot be written.
HEAD_FORMATS = {".glb": ("gltf.read_glb", "gltf.write_glb"), ".gltf": ("gltf.read_glb", None),
                ".obj": ("obj.read_obj", "obj.write_obj"), ".ply": ("ply.read_ply", None)}

_LAZY = {
    "read_glb": "gltf", "write_glb": "gltf", "read_obj": "obj", "write_obj": "obj",
    "read_fdp_json": "fdp_json", "write_fdp_json": "fdp_json", "fdp_from_head": "fdp_json",
    "apply_fdp": "fdp_json", "FdpFile": "fdp_json", "ViewAnnotation": "fdp_json",
    "read_fap": "fap", "write_fap": "fap", "parse_fap": "fap", "format_fap": "fap", "FapStream": "fap",
    "describe_fap": "fap",
}


def __getattr__(name):
    # Format modules load on first use: importing mpeg4.io stays cheap.
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'mpeg4.io' has no attribute {name!r}")


def _function(spec: str):
    module, func = spec.split(".")
    return getattr(importlib.import_module(f".{module}", __name__), func)


def _format(path: str | os.PathLike, writing: bool) -> str:
    ext = Path(path).suffix.lower()
    if ext not in HEAD_FORMATS or (writing and HEAD_FORMATS[ext][1] is None):
        known = [e for e, (r, w) in HEAD_FORMATS.items() if (w if writing else r)]
        raise InputError(f"cannot {'write' if writing else 'read'} heads as '{ext or 'no extension'}'",
                         where=os.fspath(path), fix=f"use one of {', '.join(known)}")
    return ext


def load_head(path: str | os.PathLike, feature_points: bool = True):
    """Read a head from ``.glb``, ``.gltf``, ``.obj`` or ``.ply``.

    Parameters
    ----------
    path : path
    feature_points : bool
        Also read the feature points of a mesh that does not carry its own (an OBJ or PLY,
        or a GLB from elsewhere) from ``<stem>.fdp.json`` beside it, when there is one; that
        file may also bring the mesh into the neutral frame and name its parts
        (:func:`mpeg4.io.fdp_json.place_mesh`). False: the mesh as the file has it.
    """
    require_file(path, "head file")
    ext = _format(path, False)
    try:
        if ext == ".obj":
            return _function("obj.read_obj")(path, feature_points=feature_points)
        head = _function(HEAD_FORMATS[ext][0])(path)
    except InputError as e:
        if e.where is None or not e.where.startswith("part "):
            raise
        # A part's own check knows the part, not the file it came from.
        raise InputError(e.what, where=f"{os.fspath(path)}, {e.where}", fix=e.fix) from None
    sidecar = Path(path).with_suffix(".fdp.json")
    if feature_points and not head.feature_points and sidecar.is_file():
        from .fdp_json import apply_fdp, read_fdp_json

        fdp = read_fdp_json(sidecar)
        head = apply_fdp(head, fdp, where=os.fspath(sidecar))
        head.metadata = dict(head.metadata, **fdp.metadata)
    return head


def save_head(head, path: str | os.PathLike) -> str:
    """Write a head as ``.glb`` or ``.obj`` (+ ``.mtl``, textures, ``.fdp.json``), atomically."""
    _function(HEAD_FORMATS[_format(path, True)][1])(head, path)
    return os.fspath(path)
