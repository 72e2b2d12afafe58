"""The generic head shipped with the package (``data/generic_head/generic_head.glb``).

Built from the ICT FaceKit by ``scripts/build_generic_head.py``; see
``data/generic_head/README.md`` for what it holds and how its feature points were placed.
Its complete Facial Animation Tables are stored beside it in ``generic_head_fat.npz``
(``scripts/build_generic_fat.py``). Set the environment variable ``MPEG4_GENERIC_HEAD``
to a GLB to use another generic head (its tables, if any, in ``<name>_fat.npz`` beside it).
"""

from __future__ import annotations

import copy
import functools
import os
from pathlib import Path

from .errors import InputError
from .head import Head

__all__ = ["GENERIC_HEAD_DIR", "generic_head_path", "generic_fat_path", "load_generic_head",
           "generic_feature_points", "ict_vertex_ids"]

#: Folder of the shipped generic head.
GENERIC_HEAD_DIR = Path(__file__).resolve().parents[1] / "data" / "generic_head"


def ict_vertex_ids(head: Head) -> dict:
    """Part name → (n,) int64 ICT FaceKit vertex of each of the part's vertices, from
    ``metadata["ict_vertex_ids"]`` (a ``[start, stop)`` range or a list per part;
    ``scripts/build_generic_head.py`` writes it)."""
    import numpy as np

    out = {}
    for name, ids in head.metadata["ict_vertex_ids"].items():
        if name not in head.parts:
            continue
        n = head.parts[name].n_vertices
        out[name] = np.arange(ids[0], ids[1]) if len(ids) == 2 and ids[1] - ids[0] == n else np.asarray(ids)
    return out


def generic_head_path() -> Path:
    """The GLB in use: ``$MPEG4_GENERIC_HEAD`` if set, else the shipped one."""
    env = os.environ.get("MPEG4_GENERIC_HEAD")
    return Path(env) if env else GENERIC_HEAD_DIR / "generic_head.glb"


def generic_fat_path() -> Path:
    """The FAT file beside the generic head in use: ``<name>_fat.npz``."""
    head = generic_head_path()
    return head.with_name(head.stem + "_fat.npz")


@functools.lru_cache(maxsize=4)
def _load(path: str) -> Head:
    from .io import load_head

    return load_head(path)


@functools.lru_cache(maxsize=4)
def _load_fat(path: str):
    from .io.fat_npz import read_fat_npz

    return read_fat_npz(path)


def load_generic_head(with_fat: bool = False) -> Head:
    """A fresh copy of the generic head (read once per process).

    Parameters
    ----------
    with_fat : bool
        Also attach its complete Facial Animation Tables (66 low-level FAPs, 15 visemes,
        7 expressions) from :func:`generic_fat_path`.
    """
    path = generic_head_path()
    if not path.exists():
        raise InputError("the generic head is missing", where=str(path),
                         fix="run: python3 scripts/build_generic_head.py (it needs ../shared/data/ict_facekit)")
    head = _load(str(path)).copy()
    if with_fat:
        fat_path = generic_fat_path()
        if not fat_path.exists():
            raise InputError("the generic head's animation tables are missing", where=str(fat_path),
                             fix="run: python3 scripts/build_generic_fat.py")
        head.fat = copy.deepcopy(_load_fat(str(fat_path)))
    return head


@functools.lru_cache(maxsize=4)
def _feature_points(path: str) -> dict:
    from .io.gltf import read_glb_feature_points

    return read_glb_feature_points(path)


def generic_feature_points() -> dict:
    """The generic head's feature points, FP id → (3,) metres, without loading the head
    (read from the GLB's JSON chunk, once per process)."""
    path = generic_head_path()
    if not path.exists():
        raise InputError("the generic head is missing", where=str(path),
                         fix="run: python3 scripts/build_generic_head.py (it needs ../shared/data/ict_facekit)")
    return copy.deepcopy(_feature_points(str(path)))
