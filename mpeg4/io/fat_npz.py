"""Facial Animation Tables on their own, compactly: a ``*.fat.npz`` file beside a head.

A GLB carries a head's FATs as float32 sparse morph targets (16 bytes per listed vertex
and interval, uncompressed): the generic head's full set would triple its file. This
format keeps the same tables in a zip of numpy arrays:

- per FaceDefMesh, its listed vertices as differences of consecutive indices (small,
  so they compress well) and its displacements quantised to int16 with one scale per
  mesh: the largest component maps to ±32767, so the error of any vertex at any FAP
  value inside the borders is at most half a step (scale/2 × FAPU × interval length)
  — under a micrometre for the generic head's tables;
- interval borders, parts and FaceDefTransforms (full precision) in one JSON header,
  with a format name and version.

:func:`write_fat_npz` and :func:`read_fat_npz` are exact inverses up to that
quantisation; :func:`quantisation_error` states it in metres for a head's FAPU.
"""

from __future__ import annotations

import io
import json
import os
import zipfile

import numpy as np

from ..errors import InputError, require_file
from ..fapu import FAPU
from ..fat import FAT, FaceDefMesh, FaceDefTable, FaceDefTransform, fap_unit
from .atomic import atomic_write
from .strict_json import loads

__all__ = ["FORMAT", "VERSION", "write_fat_npz", "read_fat_npz", "quantisation_error"]

FORMAT = "mpeg4-heads FAT"
VERSION = 1
_STEPS = 32767


def _header(fat: FAT) -> tuple[dict, dict]:
    tables, arrays = [], {}
    j = 0
    for t in fat.tables():
        meshes = []
        for m in t.meshes:
            if not len(m.indices):
                continue
            peak = float(np.abs(m.displacements).max())
            scale = peak / _STEPS if peak > 0 else 1.0
            arrays[f"m{j}_index"] = np.diff(m.indices, prepend=0).astype(np.uint32)
            arrays[f"m{j}_disp"] = np.round(m.displacements / scale).astype(np.int16)
            meshes.append(dict(array=j, part=m.part, borders=m.borders.tolist(), scale=scale))
            j += 1
        transforms = [dict(part=x.part, kind=x.kind, centre=x.centre.tolist(), axis=x.axis.tolist(),
                           amount=np.asarray(x.amount, dtype=float).tolist()) for x in t.transforms]
        tables.append(dict(fap=t.fap, high_level=t.high_level, meshes=meshes, transforms=transforms))
    return dict(format=FORMAT, version=VERSION, tables=tables), arrays


def fat_npz_bytes(fat: FAT) -> bytes:
    """The file's bytes: the same tables always give the same bytes (fixed entry times and
    order), so rebuilding a committed file without a change leaves it untouched."""
    header, arrays = _header(fat)
    arrays = {"header": np.frombuffer(json.dumps(header, sort_keys=True).encode(), dtype=np.uint8), **arrays}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:  # what np.load reads, minus the clock
        for name, array in arrays.items():
            info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            with z.open(info, "w") as f:
                np.lib.format.write_array(f, np.ascontiguousarray(array), allow_pickle=False)
    return buf.getvalue()


def write_fat_npz(fat: FAT, path: str | os.PathLike) -> str:
    """Write ``fat`` to ``path`` (atomically) and return the path."""
    with atomic_write(path, "wb") as f:
        f.write(fat_npz_bytes(fat))
    return os.fspath(path)


def read_fat_npz(path: str | os.PathLike) -> FAT:
    """Read tables written by :func:`write_fat_npz`.

    Raises
    ------
    InputError
        When the file is missing, not this format, of a newer version, or truncated.
    """
    path = require_file(path, "FAT file")
    try:
        with np.load(path, allow_pickle=False) as z:
            header = loads(bytes(z["header"]), where=f"{path}, header")
            arrays = {k: z[k] for k in z.files if k != "header"}
    except (OSError, ValueError, KeyError, json.JSONDecodeError) as e:
        raise InputError(f"not a readable FAT file ({type(e).__name__}: {e})", where=path,
                         fix="rebuild it (python3 scripts/build_generic_fat.py for the generic head)") from None
    if not isinstance(header, dict):
        raise InputError("its header is not a JSON object", where=path, fix="rebuild it")
    if header.get("format") != FORMAT:
        raise InputError(f"format is {header.get('format')!r}, expected {FORMAT!r}", where=path)
    if int(header.get("version", 0)) > VERSION:
        raise InputError(f"version {header['version']} is newer than this reader's {VERSION}", where=path,
                         fix="update mpeg4-heads")
    fat = FAT()
    for t in header["tables"]:
        table = FaceDefTable(int(t["fap"]), int(t["high_level"]))
        for m in t["meshes"]:
            j = m["array"]
            if f"m{j}_index" not in arrays or f"m{j}_disp" not in arrays:
                raise InputError(f"the arrays of mesh {j} are missing", where=path, fix="rebuild the file")
            idx = np.cumsum(arrays[f"m{j}_index"].astype(np.int64))
            disp = arrays[f"m{j}_disp"].astype(np.float64) * m["scale"]
            table.meshes.append(FaceDefMesh(m["part"], m["borders"], idx, disp))
        for x in t["transforms"]:
            table.transforms.append(FaceDefTransform(x["part"], x["kind"], x["centre"], x["axis"], x["amount"]))
        fat.add(table)
    return fat


def quantisation_error(fat: FAT, fapu: FAPU) -> float:
    """Largest vertex error (metres) the int16 storage of ``fat`` makes at any FAP value
    inside the interval borders: half a step over the longest interval, per mesh."""
    worst = 0.0
    for t in fat.values():
        unit = fap_unit(t.fap, fapu)
        for m in t.meshes:
            if len(m.indices):
                step = float(np.abs(m.displacements).max()) / _STEPS
                # Three components, each off by up to half a step, over all intervals from 0.
                reach = max(abs(m.borders[0]), abs(m.borders[-1]))
                worst = max(worst, 0.5 * step * np.sqrt(3) * unit * reach)
    return worst
