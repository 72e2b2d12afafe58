"""The generic head shipped with the package (``data/generic_head/generic_head.glb``).

Built from the ICT FaceKit by ``scripts/build_generic_head.py``; see
``data/generic_head/README.md`` for what it holds and how its feature points were placed.
Set the environment variable ``MPEG4_GENERIC_HEAD`` to a GLB to use another generic head.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from .errors import InputError
from .head import Head

__all__ = ["GENERIC_HEAD_DIR", "generic_head_path", "load_generic_head"]

#: Folder of the shipped generic head.
GENERIC_HEAD_DIR = Path(__file__).resolve().parents[1] / "data" / "generic_head"


def generic_head_path() -> Path:
    """The GLB in use: ``$MPEG4_GENERIC_HEAD`` if set, else the shipped one."""
    env = os.environ.get("MPEG4_GENERIC_HEAD")
    return Path(env) if env else GENERIC_HEAD_DIR / "generic_head.glb"


@functools.lru_cache(maxsize=4)
def _load(path: str) -> Head:
    from .io import load_head

    return load_head(path)


def load_generic_head() -> Head:
    """A fresh copy of the generic head (read once per process)."""
    path = generic_head_path()
    if not path.exists():
        raise InputError("the generic head is missing", where=str(path),
                         fix="run: python3 scripts/build_generic_head.py (it needs ../shared/data/ict_facekit)")
    return _load(str(path)).copy()
