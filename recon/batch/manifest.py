"""A batch's manifest: CSV with a header or JSON Lines, one person a row (:func:`read_manifest`).

Each row is checked and made a :class:`ManifestRow`; paths are relative to the manifest's
folder, empty cells take the batch's defaults, and an error names the line and the column.
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path

from mpeg4.errors import InputError
from mpeg4.io.strict_json import loads

__all__ = ["GENERIC_SOURCE", "ManifestRow", "read_manifest"]

#: The ``clone`` value naming the shipped generic head with its complete animation tables.
GENERIC_SOURCE = "generic"
_PATH_COLUMNS = ("front", "side", "fdp", "shape_from", "texture_from")
_OPTION_COLUMNS = ("ipd", "focal", "method", "texture_size", "atlas")
COLUMNS = ("id", *_PATH_COLUMNS, *_OPTION_COLUMNS, "clone")
_ALIASES = {"ipd_mm": "ipd", "focal_px": "focal", "person": "id"}
_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


@dataclass(frozen=True)
class ManifestRow:
    """One person of a manifest (paths resolved against the manifest's folder).

    Attributes
    ----------
    id : str
    line : int
        Line of the manifest (1-based; the CSV header is line 1).
    front, side, fdp, shape_from, texture_from : str or None
        Absolute paths.
    clone : str or None
        ``"generic"`` or an absolute path to the source head.
    options : dict
        Those given in the row: ``ipd_mm``, ``focal_px``, ``method``, ``texture_size``, ``atlas``.
    manifest : str
    """

    id: str
    line: int
    front: str | None = None
    side: str | None = None
    fdp: str | None = None
    shape_from: str | None = None
    texture_from: str | None = None
    clone: str | None = None
    options: dict = field(default_factory=dict)
    manifest: str = ""

    @property
    def where(self) -> str:
        return f"{self.manifest}, line {self.line} ({self.id})"

    def as_dict(self) -> dict:
        """The row as written to the records (no manifest path: that is the batch's)."""
        d = asdict(self)
        d.pop("manifest")
        return d


def _cell(value) -> object:
    if isinstance(value, str):
        value = value.strip()
        return value or None
    return value


def _number(value, column: str, where: str, kind=float, low: float = 0.0):
    try:
        x = kind(value)
        if isinstance(value, bool) or (kind is int and float(value) != x):
            raise ValueError
    except (TypeError, ValueError):
        raise InputError(f"{column} is {value!r}, not a {'whole ' if kind is int else ''}number", where=where,
                         fix=f"write the {column} as a number, or leave it empty for the default") from None
    if not x > low:
        raise InputError(f"{column} is {value!r}", where=where, fix=f"give a {column} above {low:g}")
    return x


def _flag(value, where: str) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).lower()
    if text in ("1", "true", "yes", "y"):
        return True
    if text in ("0", "false", "no", "n"):
        return False
    raise InputError(f"atlas is {value!r}", where=where, fix="write true or false")


def _parse_row(raw: dict, line: int, folder: Path, manifest: str) -> ManifestRow:
    where = f"{manifest}, line {line}"
    cells = {}
    for key, value in raw.items():
        if key is None:  # csv: more cells than the header has columns
            raise InputError(f"{len(value)} cell(s) more than the header's columns", where=where,
                             fix="quote cells that contain commas, or add the missing column to the header")
        name = _ALIASES.get(key.strip().lower().replace("-", "_"), key.strip().lower().replace("-", "_"))
        if name not in COLUMNS:
            raise InputError(f"unknown column {key!r}", where=where, fix="use the columns " + ", ".join(COLUMNS))
        cells[name] = _cell(value)
    pid = cells.get("id")
    if pid is None:
        raise InputError("the row has no id", where=where, fix="give every row an id (its output folder's name)")
    pid = str(pid)
    if not _ID.fullmatch(pid):
        raise InputError(f"id {pid!r} cannot name a folder", where=where,
                         fix="use letters, digits, '.', '_' and '-' (not first), at most 100 characters")
    where = f"{where} ({pid})"

    def path(name):
        v = cells.get(name)
        if v is None:
            return None
        p = Path(os.path.expanduser(str(v)))
        return os.fspath(p if p.is_absolute() else (folder / p).resolve())

    paths = {n: path(n) for n in _PATH_COLUMNS}
    if paths["fdp"] and paths["shape_from"]:
        raise InputError("both fdp and shape_from are given", where=where,
                         fix="use fdp for one annotated pair, or shape_from with texture_from for two")
    if paths["texture_from"] and not paths["shape_from"]:
        raise InputError("texture_from is given without shape_from", where=where,
                         fix="give shape_from too (or put the annotations in the fdp column)")
    if not (paths["fdp"] or paths["shape_from"]) and not paths["front"]:
        raise InputError("no photos and no annotations", where=where,
                         fix="give a front photo, and a side photo if there is one (and an fdp.json if the points "
                             "are marked)")
    options = {}
    if cells.get("ipd") is not None:
        options["ipd_mm"] = _number(cells["ipd"], "ipd", where)
    if cells.get("focal") is not None:
        options["focal_px"] = _number(cells["focal"], "focal", where)
    if cells.get("texture_size") is not None:
        options["texture_size"] = _number(cells["texture_size"], "texture_size", where, int, 63)
    if cells.get("atlas") is not None:
        options["atlas"] = _flag(cells["atlas"], where)
    if cells.get("method") is not None:
        if cells["method"] not in ("dffd", "rbf"):
            raise InputError(f"method is {cells['method']!r}", where=where, fix="write dffd or rbf")
        options["method"] = cells["method"]
    clone = cells.get("clone")
    if clone is not None:
        clone = GENERIC_SOURCE if str(clone).lower() == GENERIC_SOURCE else path("clone")
    return ManifestRow(pid, line, clone=clone, options=options, manifest=manifest, **paths)


def read_manifest(path: str | os.PathLike) -> list[ManifestRow]:
    """The rows of a batch manifest (see the module docstring).

    Parameters
    ----------
    path : path
        ``.csv`` (a header line, then one person a line) or ``.jsonl`` (one JSON object a
        line). Blank lines and lines starting with ``#`` are skipped.

    Returns
    -------
    list of ManifestRow
        In the manifest's order.

    Raises
    ------
    InputError
        For what is wrong with the manifest itself (its format, an unknown column, an id
        given twice, a value that is not a number), naming the line, before anything is
        built. Missing or bad photos and annotations are the rows' own failures, found
        when they are built.
    """
    from mpeg4.errors import require_file

    path = require_file(path, "batch manifest")
    manifest = os.path.abspath(path)
    folder = Path(manifest).parent
    suffix = Path(path).suffix.lower()
    raw_rows: list[tuple[int, dict]] = []
    with open(path, encoding="utf-8-sig", newline="") as f:
        if suffix == ".csv":
            lines = [(n, text) for n, text in enumerate(f, 1) if text.strip() and not text.lstrip().startswith("#")]
            if not lines:
                raise InputError("the manifest is empty", where=path, fix="write a header line and one row a person")
            reader = csv.DictReader([t for _, t in lines])
            for (n, _), raw in zip(lines[1:], reader):
                raw_rows.append((n, raw))
        elif suffix in (".jsonl", ".ndjson"):
            for n, text in enumerate(f, 1):
                if not text.strip() or text.lstrip().startswith("#"):
                    continue
                raw = loads(text, where=f"{path}, line {n}")
                if not isinstance(raw, dict):
                    raise InputError(f"a JSON {type(raw).__name__}, not an object", where=f"{path}, line {n}",
                                     fix='write one object a line, e.g. {"id": "p1", "front": "p1_front.jpg"}')
                raw_rows.append((n, raw))
        else:
            raise InputError(f"unknown manifest format {suffix or '(no extension)'!r}", where=path,
                             fix="name it .csv (with a header line) or .jsonl (one JSON object a line)")
    rows, seen = [], {}
    for n, raw in raw_rows:
        row = _parse_row(raw, n, folder, manifest)
        if row.id in seen:
            raise InputError(f"id {row.id!r} is also on line {seen[row.id]}", where=f"{path}, line {n}",
                             fix="give every person an id of their own")
        seen[row.id] = n
        rows.append(row)
    if not rows:
        raise InputError("the manifest lists nobody", where=path, fix="add one row a person")
    return rows
