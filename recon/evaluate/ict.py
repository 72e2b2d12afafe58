"""ICT FaceKit identities on the generic head's topology: the model read, identities drawn.

The ICT FaceKit (MIT, USC Institute for Creative Technologies) is read from
``../shared/data/ict_facekit/ict_facekit.npz`` beside the project unless a path is given.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head

__all__ = ["default_ict_path", "load_ict", "identity_vertices", "identity_head"]

#: ICT parts that make up the generic head's skin, and their UV tiles.
_SKIN_PARTS = ("Face", "Head and Neck", "Mouth socket", "Eye socket left", "Eye socket right")


def default_ict_path() -> Path:
    """``../shared/data/ict_facekit/ict_facekit.npz`` beside the project's root."""
    return Path(__file__).resolve().parents[3] / "shared" / "data" / "ict_facekit" / "ict_facekit.npz"


@functools.lru_cache(maxsize=2)
def load_ict(path: str | os.PathLike | None = None) -> dict:
    """The ICT FaceKit arrays (read once per process)."""
    path = Path(path) if path is not None else default_ict_path()
    if not path.exists():
        raise InputError("the ICT FaceKit data is missing", where=str(path),
                         fix="put ict_facekit.npz there (see ../shared/data/ict_facekit/README.md)")
    with np.load(path) as d:
        return {k: d[k] for k in d.files}


def identity_vertices(data: dict, seed: int, spread: float = 1.0, n_modes: int = 100,
                      expression: Mapping[str, float] | None = None) -> np.ndarray:
    """(N, 3) vertices in metres of the ICT identity ``mean + sum z_i mode_i``, z ~ N(0, spread²),
    with ``expression`` (ICT expression name → weight, e.g. ``{"eyeBlink_L": 0.5}``) added.

    ``seed`` 0 with ``spread`` 0 is the model mean.
    """
    rng = np.random.default_rng(seed)
    z = np.clip(rng.standard_normal(n_modes), -2.5, 2.5) * spread
    v = data["vertices"].astype(np.float64) + np.tensordot(z, data["identity_deltas"][:n_modes].astype(np.float64), 1)
    names = [str(n) for n in data["expression_names"]] if expression else []
    for name, w in (expression or {}).items():
        if name not in names:
            raise InputError(f"the ICT FaceKit has no expression {name!r}", fix=f"use one of {', '.join(names)}")
        v = v + float(w) * data["expression_deltas"][names.index(name)].astype(np.float64)
    return v * 0.01


def identity_head(data: dict, seed: int, generic: Head | None = None, spread: float = 1.0,
                  expression: Mapping[str, float] | None = None) -> Head:
    """The generic head reshaped to an ICT identity (same topology, feature points follow),
    posed by ``expression`` (see :func:`identity_vertices`)."""
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    from mpeg4.generic_head import ict_vertex_ids

    v = identity_vertices(data, seed, spread, expression=expression)
    return generic.with_vertices({name: v[ids] for name, ids in ict_vertex_ids(generic).items()})
