"""Face-mesh landmarks → MPEG-4 feature points, by tables stored as data.

Each feature point the face mesh covers is a fixed affine combination of three of its
landmarks, ``fp = w0 * L[a] + w1 * L[b] + w2 * L[c]`` with ``w0 + w1 + w2 = 1`` (barycentric
coordinates in the landmarks' triangle, extended beyond it when a weight is negative), the
way the project binds feature points to a mesh. The table,
``recon/data/facemesh_mpeg4.csv``, names the anatomy of each row; its landmark triples and
weights were fitted by ``scripts/build_facemesh_map.py`` to synthetic photos of ICT FaceKit
identities (seeds disjoint from the benchmark's), so that the points land where this
project's generic head defines them.

A second table, ``recon/data/facemesh_side.csv``, has the same form over the landmarks'
depth and height: the points of a side photo, which :mod:`recon.landmarks.side` carries
there through the profile fit (:mod:`recon.landmarks.profile`).
"""

from __future__ import annotations

import csv
import functools
import io
from dataclasses import dataclass
from importlib import resources

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS

from .models import N_LANDMARKS

__all__ = ["MAP_FILE", "SIDE_MAP_FILE", "FpMapping", "load_mapping", "apply_mapping", "write_mapping"]

#: The front photo's table inside the package (over the landmarks' pixels).
MAP_FILE = "data/facemesh_mpeg4.csv"
#: The side photo's table (over the landmarks' depth and height).
SIDE_MAP_FILE = "data/facemesh_side.csv"
_COLUMNS = ["fp", "landmarks", "weights", "fit_error_pct", "anatomy"]


@dataclass(frozen=True)
class FpMapping:
    """One row of the table.

    Attributes
    ----------
    fp : str
        Feature point id.
    landmarks : (3,) tuple of int
        Face mesh landmark indices (0–477).
    weights : (3,) tuple of float
        Affine weights, summing to 1.
    fit_error_pct : float
        Median error of the row on the photos it was fitted to, in % of the distance
        between the pupils.
    anatomy : str
        What the landmarks are, in words.
    """

    fp: str
    landmarks: tuple[int, int, int]
    weights: tuple[float, float, float]
    fit_error_pct: float
    anatomy: str


def _parse(text: str, where: str) -> dict[str, FpMapping]:
    rows = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    reader = csv.DictReader(io.StringIO("\n".join(rows)))
    if reader.fieldnames != _COLUMNS:
        raise ValueError(f"{where}: columns {reader.fieldnames}, expected {_COLUMNS}")
    out = {}
    for k, row in enumerate(reader, start=2):
        fp = row["fp"]
        if fp not in FEATURE_POINTS:
            raise ValueError(f"{where}, row {k}: unknown feature point {fp!r}")
        if fp in out:
            raise ValueError(f"{where}, row {k}: feature point {fp} given twice")
        lms = tuple(int(x) for x in row["landmarks"].split())
        ws = tuple(float(x) for x in row["weights"].split())
        if len(lms) != 3 or len(ws) != 3:
            raise ValueError(f"{where}, row {k}: expected three landmarks and three weights")
        if not all(0 <= i < N_LANDMARKS for i in lms):
            raise ValueError(f"{where}, row {k}: landmark index outside 0..{N_LANDMARKS - 1}")
        if abs(sum(ws) - 1) > 1e-5:
            raise ValueError(f"{where}, row {k}: weights sum to {sum(ws):.6g}, not 1")
        out[fp] = FpMapping(fp, lms, ws, float(row["fit_error_pct"]), row["anatomy"])
    return out


@functools.lru_cache(maxsize=2)
def load_mapping(table: str = MAP_FILE) -> dict[str, FpMapping]:
    """A shipped table: FP id → :class:`FpMapping`.

    Parameters
    ----------
    table : str
        :data:`MAP_FILE` (the front photo's) or :data:`SIDE_MAP_FILE`.

    Examples
    --------
    >>> m = load_mapping()
    >>> m["3.5"].anatomy
    'left iris centre'
    >>> round(sum(m["8.1"].weights), 9)
    1.0
    """
    text = resources.files("recon").joinpath(table).read_text(encoding="utf-8")
    return _parse(text, f"recon/{table}")


def apply_mapping(landmarks: np.ndarray, mapping: dict[str, FpMapping] | None = None) -> dict[str, np.ndarray]:
    """Feature points from one face's landmarks.

    Parameters
    ----------
    landmarks : (478, D) float
        Face mesh landmarks (D = 2 or 3: pixels, and relative depth; for the side table,
        depth and height).
    mapping : dict, optional
        :func:`load_mapping` by default.

    Returns
    -------
    dict of str to (D,) float64
    """
    mapping = load_mapping() if mapping is None else mapping
    lm = np.asarray(landmarks, dtype=np.float64)
    return {fp: np.asarray(m.weights) @ lm[list(m.landmarks)] for fp, m in mapping.items()}


def write_mapping(path, rows: list[FpMapping], header: str) -> None:
    """Write a table (``header`` becomes ``#`` comment lines above the columns)."""
    from mpeg4.io.atomic import atomic_write

    with atomic_write(path, "w", encoding="utf-8") as f:
        for line in header.strip().splitlines():
            f.write(f"# {line}".rstrip() + "\n")
        w = csv.writer(f, lineterminator="\n")
        w.writerow(_COLUMNS)
        for r in rows:
            w0, w1 = round(r.weights[0], 6), round(r.weights[1], 6)
            ws = (w0, w1, round(1.0 - w0 - w1, 6))  # rounded, still summing to 1
            w.writerow([r.fp, " ".join(map(str, r.landmarks)), " ".join(f"{x:.6f}" for x in ws),
                        f"{r.fit_error_pct:.2f}", r.anatomy])
