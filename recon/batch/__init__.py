"""``recon batch``: many heads from a manifest, one failure costing only its own row.

A manifest (CSV with a header, or JSON Lines) lists one person a row; see
``docs/examples/batch_manifest.csv`` and ``.jsonl``:

===============  ==========================================================================
column           what
===============  ==========================================================================
``id``           the person's folder name in the output (letters, digits, ``.``, ``_``, ``-``)
``front``        front photo (optional when ``fdp`` names it)
``side``         side photo (likewise)
``fdp``          annotations of both photos (``*.fdp.json``); without them the points come
                 from automatic detection (:func:`recon.landmarks.detect`, when installed)
                 and the head is flagged unreviewed
``ipd``          interpupillary distance, mm
``focal``        focal length, pixels (when empty: from the photos' EXIF, else orthographic)
``method``       ``dffd`` or ``rbf``
``texture_size`` side of the square texture, pixels
``atlas``        ``true`` to re-pack the texture into an atlas
``shape_from``   shape–texture separation: the shape from this annotated pair …
``texture_from`` … the texture from this one
``clone``        make the head animatable: ``generic`` (the generic head's motion) or a
                 source head file
===============  ==========================================================================

Only ``id`` is required; empty cells take the batch's defaults. Paths are relative to the
manifest's folder.

Each row is one task, :func:`build_person`: it builds into a hidden temporary folder in
``OUT`` (``recon build``, then the clone step) and renames it to ``OUT/<id>/`` when
everything is written, so a folder named after a person is always complete. A failed row
writes nothing there; its error goes to ``OUT/report.jsonl`` and the other rows go on.
Running the batch again skips the rows whose folder exists and retries the others.

The same task runs in local worker processes (:class:`concurrent.futures.ProcessPoolExecutor`,
the default) or on a Dask distributed cluster (``scheduler``: its address); the task returns
a plain record either way, gathered the same way.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import functools
import gc
import json
import multiprocessing
import os
import re
import resource
import shutil
import socket
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field
from pathlib import Path

from mpeg4.errors import InputError

__all__ = ["ManifestRow", "BatchReport", "read_manifest", "build_person", "run_batch", "REPORT_NAME",
           "RECORD_NAME", "NO_LANDMARKS", "GENERIC_SOURCE"]

#: The batch's record of every row, in ``OUT``.
REPORT_NAME = "report.jsonl"
#: Each head's own record, in ``OUT/<id>/``: the row it was built from and how it went.
RECORD_NAME = "batch.json"
#: The failure of a row without annotations when automatic detection is not installed.
NO_LANDMARKS = "no annotations and automatic landmarks are not installed"
#: The ``clone`` value naming the shipped generic head with its complete animation tables.
GENERIC_SOURCE = "generic"

_PATH_COLUMNS = ("front", "side", "fdp", "shape_from", "texture_from")
_OPTION_COLUMNS = ("ipd", "focal", "method", "texture_size", "atlas")
COLUMNS = ("id", *_PATH_COLUMNS, *_OPTION_COLUMNS, "clone")
_ALIASES = {"ipd_mm": "ipd", "focal_px": "focal", "person": "id"}
_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")
_PARTIAL = ".partial-"
# What a Dask nanny gives its workers (distributed.nanny.pre-spawn-environ): one thread per
# numerical library, since the parallelism is the processes; and glibc handing freed memory
# back, so that a long batch keeps a flat footprint. Local workers get the same, which also
# makes their results the same as a cluster's to the last bit.
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
               "MALLOC_TRIM_THRESHOLD_": "65536"}
# A row whose worker process dies this many times is recorded as failed.
_MAX_CRASHES = 2


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


# --- the manifest ---------------------------------------------------------------------------

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
    if not (paths["fdp"] or paths["shape_from"]) and not (paths["front"] and paths["side"]):
        raise InputError("no photos and no annotations", where=where,
                         fix="give front and side photos (and an fdp.json if the points are marked)")
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
                try:
                    raw = json.loads(text)
                except json.JSONDecodeError as e:
                    raise InputError(f"not JSON ({e.msg}, column {e.colno})", where=f"{path}, line {n}",
                                     fix="write one JSON object a line") from None
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


# --- one person: the task ---------------------------------------------------------------------

def _landmark_detector() -> Callable | None:
    """:func:`recon.landmarks.detect` when that module is installed and imports."""
    import importlib
    import importlib.util

    if importlib.util.find_spec("recon.landmarks") is None:
        return None
    try:
        return getattr(importlib.import_module("recon.landmarks"), "detect", None)
    except ImportError:
        return None


def _memory() -> dict:
    """This process's peak resident memory so far and its resident memory now, MB.

    The peak is the kernel's high-water mark of the process's own memory (``VmHWM``; the
    ``ru_maxrss`` of :func:`resource.getrusage` would also count the parent a worker was
    started from, on Linux); ``ru_maxrss`` where ``/proc`` is absent.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            fields = dict(line.split(":", 1) for line in f if line.startswith(("VmHWM", "VmRSS")))
        return {"rss_peak_mb": round(int(fields["VmHWM"].split()[0]) / 1024, 1),
                "rss_mb": round(int(fields["VmRSS"].split()[0]) / 1024, 1)}
    except (OSError, KeyError, ValueError):
        kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kilobytes on Linux, bytes on macOS
        return {"rss_peak_mb": round(kb / 1024 / (1024 if os.uname().sysname == "Darwin" else 1), 1)}


@functools.lru_cache(maxsize=1)
def _libc():
    import ctypes

    try:
        return ctypes.CDLL("libc.so.6")
    except OSError:  # not glibc (macOS, musl): nothing to trim
        return None


def _trim_heap() -> None:
    """Hand the memory freed by the head just built back to the system (glibc's
    ``malloc_trim``): without it the heap keeps the holes a build leaves, and a worker's
    footprint creeps up over the first heads of a batch."""
    libc = _libc()
    if libc is not None and hasattr(libc, "malloc_trim"):
        libc.malloc_trim(0)


def _cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _detected_annotations(row: ManifestRow, folder: Path, detect: Callable | None) -> str:
    """Annotations by automatic detection, written into the head's folder; their path."""
    from mpeg4.errors import require_file
    from mpeg4.io import write_fdp_json
    from mpeg4.io.fdp_json import FdpFile

    detect = detect or _landmark_detector()
    if detect is None:
        raise InputError(NO_LANDMARKS, where=row.where,
                         fix="mark the points (recon annotate FRONT SIDE) and give the fdp.json in the fdp "
                             "column, or install automatic detection (recon.landmarks)")
    front, side = require_file(row.front, "front photo"), require_file(row.side, "side photo")
    try:
        found = detect(front, side)
    except ImportError as e:  # recon.landmarks is there but its models are not (mediapipe)
        raise InputError(NO_LANDMARKS, where=row.where, fix=f"{e}; or mark the points (recon annotate FRONT SIDE) "
                                                            f"and give the fdp.json in the fdp column") from None
    if not isinstance(found, FdpFile):
        raise TypeError(f"automatic detection returned {type(found).__name__}, not an FdpFile")
    for name, photo in (("front", front), ("side", side)):
        if name not in found.views or not found.views[name].points:
            raise InputError(f"automatic detection found no feature points on the {name} photo", where=photo,
                             fix="check that the photo shows the face, or mark the points with recon annotate")
        found.views[name].image = photo
    found.metadata = dict(found.metadata, reviewed=False, source="automatic detection (recon.landmarks)")
    path = folder / "annotations.fdp.json"
    write_fdp_json(path, found)
    return os.fspath(path)


def _relocate_provenance(fdp_path: Path, temporary: str, final: str) -> None:
    """Name the detected annotations by where they end up, not by the temporary folder."""
    from mpeg4.io import read_fdp_json, write_fdp_json

    fdp = read_fdp_json(fdp_path)
    entry = fdp.metadata["provenance"]["inputs"]["shape"]["fdp"]
    entry["path"] = entry["path"].replace(temporary, final)
    write_fdp_json(fdp_path, fdp)


def _build_here(row: ManifestRow, out_dir: str, defaults: dict, created: str | None,
                clone_step: Callable | None, detect: Callable | None) -> dict:
    from mpeg4.io import save_head

    from recon.build import run_build

    t0, cpu0 = time.perf_counter(), _cpu_seconds()
    out = Path(out_dir)
    final = out / row.id
    record = {"id": row.id, "line": row.line, "status": "failed", "worker": f"{socket.gethostname()}:{os.getpid()}"}
    tmp = None
    try:
        if (final / RECORD_NAME).exists():  # built meanwhile by another run of the same batch
            return {**_read_record(final), "skipped": True}
        if final.exists():
            raise InputError(f"{final} exists and was not made by recon batch", where=row.where,
                             fix="move that folder away, or write the batch into another output folder")
        tmp = Path(tempfile.mkdtemp(prefix=f".{row.id}{_PARTIAL}", dir=out))
        opts = {**defaults, **row.options}
        fdp, unreviewed = row.fdp, False
        if fdp is None and row.shape_from is None:
            fdp, unreviewed = _detected_annotations(row, tmp, detect), True
        built = []
        paths = run_build(row.front, row.side, fdp, tmp, ipd_mm=opts["ipd_mm"], focal_px=opts["focal_px"],
                          method=opts["method"], texture_size=opts["texture_size"], atlas=opts["atlas"],
                          shape_from=row.shape_from, texture_from=row.texture_from, result=built, created=created,
                          provenance={"batch": {"manifest": row.manifest, "line": row.line, "id": row.id,
                                                "reviewed_annotations": not unreviewed}})
        if unreviewed:
            _relocate_provenance(paths["fdp"], os.fspath(tmp), os.fspath(final))
        if row.clone is not None:
            if clone_step is None:
                raise InputError("the row asks for a clone step but the batch was given none", where=row.where,
                                 fix="run it with recon batch, or pass clone_step=chain.animatable.clone_step")
            head, warnings = clone_step(built[0].head, row.clone)
            save_head(head, paths["head"])
            record["clone_warnings"] = list(warnings)
            del head
        del built
        record.update(status="done", unreviewed=unreviewed, seconds=round(time.perf_counter() - t0, 2),
                      files=sorted(p.name for p in tmp.iterdir()), row=row.as_dict())
        (tmp / RECORD_NAME).write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
        os.chmod(tmp, out.stat().st_mode & 0o777)  # mkdtemp's folder is private: give it the output's
        # A folder named after the person appears complete, or not at all.
        try:
            os.rename(tmp, final)
        except OSError:
            if (final / RECORD_NAME).exists():
                return {**_read_record(final), "skipped": True}
            raise
        tmp = None
    except InputError as e:
        text = str(e)
        if tmp is not None and row.fdp is None and row.shape_from is None:  # name what was detected, not a temp file
            text = text.replace(os.fspath(tmp / "annotations.fdp.json"),
                                f"the points detected automatically on {row.front} and {row.side}")
        record.update(error=text, error_kind="input")
    except Exception as e:  # one row's bug must not cost the others; keep it visible in the report
        record.update(error=f"{type(e).__name__}: {e}", error_kind="internal", traceback=traceback.format_exc())
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        gc.collect()
        _trim_heap()
    record.setdefault("seconds", round(time.perf_counter() - t0, 2))
    record.update(cpu_seconds=round(_cpu_seconds() - cpu0, 2), **_memory())
    return record


# The renderer's OpenGL context belongs to the thread that made it. Local workers and a
# caller building in its own process build on their main thread; a Dask worker runs tasks
# on threads of its own, so there every build goes to one thread kept for it.
_builder: cf.ThreadPoolExecutor | None = None
_builder_lock = threading.Lock()


def build_person(row: ManifestRow, out_dir: str, defaults: dict, created: str | None = None,
                 clone_step: Callable | None = None, detect: Callable | None = None) -> dict:
    """Build one person of a batch into ``out_dir/<id>/`` (the task the batch runs).

    Never raises for a problem with the row: the returned record says what happened.

    Parameters
    ----------
    row : ManifestRow
    out_dir : str
        The batch's output folder (it exists).
    defaults : dict
        ``ipd_mm``, ``focal_px``, ``method``, ``texture_size``, ``atlas`` for what the row
        leaves empty.
    created : str, optional
        Time stamp for the bundle's provenance (:func:`recon.build.build_time`).
    clone_step : callable, optional
        ``clone_step(head, source) -> (head, warnings)`` for rows with a ``clone`` column
        (:func:`chain.animatable.clone_step`).
    detect : callable, optional
        ``detect(front, side) -> FdpFile`` for rows without annotations (by default
        :func:`recon.landmarks.detect` when installed).

    Returns
    -------
    dict
        ``id``, ``line``, ``status`` (``"done"`` or ``"failed"``), ``seconds``,
        ``cpu_seconds`` (of the whole worker process meanwhile), ``worker`` (host:pid),
        ``rss_peak_mb`` and ``rss_mb`` (the worker's peak memory so far, and after this
        row); when done ``files``,
        ``unreviewed`` (points from automatic detection), ``clone_warnings``; when failed
        ``error`` (one line), ``error_kind`` (``"input"``: something in the row;
        ``"internal"``: a bug, with its ``traceback``).
    """
    global _builder
    if threading.current_thread() is threading.main_thread():
        return _build_here(row, out_dir, defaults, created, clone_step, detect)
    with _builder_lock:
        if _builder is None:
            _builder = cf.ThreadPoolExecutor(max_workers=1, thread_name_prefix="recon-batch")
    return _builder.submit(_build_here, row, out_dir, defaults, created, clone_step, detect).result()


def _read_record(folder: Path) -> dict:
    try:
        return json.loads((folder / RECORD_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {"id": folder.name, "status": "done"}


# --- the batch ----------------------------------------------------------------------------------

@dataclass
class BatchReport:
    """What a batch did.

    Attributes
    ----------
    records : list of dict
        One per manifest row, in its order (see :func:`build_person`); rows finished by an
        earlier run have ``skipped`` True.
    out_dir : Path
    seconds : float
        Wall time of this run.
    """

    records: list[dict]
    out_dir: Path
    seconds: float

    def count(self, status: str) -> int:
        if status == "skipped":
            return sum(bool(r.get("skipped")) for r in self.records)
        if status == "built":
            return sum(r["status"] == "done" and not r.get("skipped") for r in self.records)
        return sum(r["status"] == status for r in self.records)

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.records if r["status"] == "failed"]

    @property
    def heads_per_minute(self) -> float:
        return 60.0 * self.count("built") / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> str:
        """One line: how many were built, skipped and failed, in how long."""
        return (f"{self.count('built')} built, {self.count('skipped')} done before, {self.count('failed')} failed "
                f"in {self.seconds:.0f} s ({self.heads_per_minute:.1f} heads/min); report: "
                f"{self.out_dir / REPORT_NAME}")

    def table(self, max_rows: int = 40):
        """A :class:`rich.table.Table` of the rows (the failed and unreviewed ones first
        when there are more than ``max_rows``)."""
        from rich.table import Table

        table = Table(title=f"recon batch: {self.out_dir}", title_justify="left")
        for name, kw in (("id", {}), ("status", {}), ("s", {"justify": "right"}), ("note", {"overflow": "fold"})):
            table.add_column(name, **kw)
        rows = self.records
        if len(rows) > max_rows:
            rows = [r for r in rows if r["status"] == "failed" or r.get("unreviewed") or r.get("stale")][:max_rows]
        for r in rows:
            status = "done before" if r.get("skipped") else r["status"]
            style = "red" if r["status"] == "failed" else ("yellow" if r.get("unreviewed") else None)
            note = r.get("error") or "; ".join(
                [*(["points unreviewed (automatic detection)"] if r.get("unreviewed") else []),
                 *([r["stale"]] if r.get("stale") else []),
                 *(f"clone: {w}" for w in r.get("clone_warnings", [])[:2])])
            table.add_row(r["id"], status, f"{r.get('seconds', 0):.1f}", note, style=style)
        if len(rows) < len(self.records):
            table.caption = f"and {len(self.records) - len(rows)} more rows done (all in {REPORT_NAME})"
        return table


def _rate_column():
    from rich.progress import ProgressColumn
    from rich.text import Text

    class HeadsPerMinute(ProgressColumn):
        def render(self, task):
            speed = task.finished_speed or task.speed
            return Text("? heads/min" if speed is None else f"{60 * speed:.1f} heads/min", style="progress.data.speed")

    return HeadsPerMinute()


@contextlib.contextmanager
def _progress_bar(enabled: bool, total: int, done: int) -> Iterator[Callable[[dict], None]]:
    if not enabled:
        yield lambda record: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, \
        TimeRemainingColumn

    columns = (TextColumn("[bold]recon batch"), BarColumn(), MofNCompleteColumn(), _rate_column(),
               TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(), TextColumn("{task.fields[last]}"))
    with Progress(*columns, console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task("heads", total=total, completed=done, last="")

        def advance(record: dict) -> None:
            mark = "failed" if record["status"] == "failed" else "done"
            bar.update(task, advance=1, last=f"{record['id']} {mark}")

        yield advance


@contextlib.contextmanager
def _worker_environment() -> Iterator[None]:
    """The variables of :data:`_WORKER_ENV` for processes started meanwhile (those
    already set are kept)."""
    saved = {k: os.environ.get(k) for k in _WORKER_ENV}
    for k, v in _WORKER_ENV.items():
        os.environ.setdefault(k, v)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _same_row(a: dict, b: dict) -> bool:
    """Whether two records' rows ask for the same head (wherever they sit in the manifest)."""
    return {k: v for k, v in a.items() if k != "line"} == {k: v for k, v in b.items() if k != "line"}


def _partials(out: Path, pid: str | None = None) -> list[Path]:
    pattern = f".{pid}{_PARTIAL}*" if pid else f".*{_PARTIAL}*"
    return [p for p in out.glob(pattern) if p.is_dir()]


def _run_local(todo: list[ManifestRow], workers: int, submit_args: tuple, out: Path,
               on_result: Callable[[dict], None]) -> None:
    """The rows on ``workers`` local processes.

    A process that dies (killed, out of memory, a crash in native code) breaks the pool:
    the rows it may have been building — those that left a temporary folder — are tried
    again, up to :data:`_MAX_CRASHES` times, and the others go on in a new pool. An
    interruption (Ctrl-C) stops the workers at once; what they were building is left as
    hidden temporary folders, removed by the next run.
    """
    context = multiprocessing.get_context("spawn")  # fresh interpreters: no copied threads or GL state
    pending = {row.id: row for row in todo}
    crashes: dict[str, int] = {}
    unexplained = 0
    while pending:
        with _worker_environment():
            pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(pending)), mp_context=context)
        broken = None
        try:
            futures = {pool.submit(build_person, row, *submit_args): row for row in pending.values()}
            for future in cf.as_completed(futures):
                row = futures[future]
                try:
                    record = future.result()
                except BrokenProcessPool as e:
                    broken = e
                    continue
                pending.pop(row.id)
                on_result(record)
        except BaseException:
            processes = list((getattr(pool, "_processes", None) or {}).values())  # no public way before 3.14
            pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()
            raise
        pool.shutdown()
        if broken is None:
            continue
        suspects = [pid for pid in pending if _partials(out, pid)]
        if not suspects:  # the pool died before any row started (e.g. a worker could not start)
            unexplained += 1
            if unexplained >= _MAX_CRASHES:
                raise RuntimeError(f"the local worker processes keep dying before building anything ({broken})")
        for pid in suspects:
            for p in _partials(out, pid):
                shutil.rmtree(p, ignore_errors=True)
            crashes[pid] = crashes.get(pid, 0) + 1
            if crashes[pid] >= _MAX_CRASHES:
                row = pending.pop(pid)
                on_result({"id": pid, "line": row.line, "status": "failed", "error_kind": "crash",
                           "error": f"{row.where}: the worker process died while building it, {crashes[pid]} times "
                                    f"({broken}) (fix: check the worker's memory, or build this row alone with "
                                    f"recon build to see the crash)"})


def _run_dask(todo: list[ManifestRow], scheduler, submit_args: tuple, on_result: Callable[[dict], None]) -> None:
    """The rows as tasks on a Dask distributed cluster; a task whose worker died (the
    scheduler retries it on others first) is recorded as failed."""
    try:
        from distributed import Client, as_completed
    except ImportError as e:
        raise InputError(f"Dask distributed is not installed ({e})", where="--scheduler",
                         fix="pip install 'dask[distributed]' (or bash install.sh)") from None
    own = not isinstance(scheduler, Client)
    try:
        client = Client(scheduler, set_as_default=False) if own else scheduler
    except (OSError, TimeoutError) as e:
        raise InputError(f"cannot reach the Dask scheduler ({e})", where=f"--scheduler {scheduler}",
                         fix="start one (dask scheduler) with workers (dask worker ADDRESS), or check the address")
    try:
        run = f"{os.getpid()}-{time.time_ns()}"
        futures = {client.submit(build_person, row, *submit_args, key=f"recon-batch-{row.id}-{run}", pure=False):
                   row for row in todo}
        for future in as_completed(futures, loop=client.loop):
            row = futures[future]
            try:
                record = future.result()
            except Exception as e:  # the worker died (KilledWorker) or the task could not run there
                record = {"id": row.id, "line": row.line, "status": "failed", "error_kind": "crash",
                          "error": f"{row.where}: the Dask task failed on the cluster ({type(e).__name__}: {e})"}
            future.release()
            on_result(record)
    finally:
        if own:
            client.close()


class _Report:
    """``OUT/report.jsonl``: a line appended (and flushed to disk) as each row ends, so an
    interrupted batch keeps what it learnt; rewritten in the manifest's order at the end."""

    def __init__(self, out: Path):
        self.path = out / REPORT_NAME
        self.latest = self._read()
        self.file = open(self.path, "a", encoding="utf-8")

    def _read(self) -> dict[str, dict]:
        latest = {}
        if self.path.exists():
            for text in self.path.read_text(encoding="utf-8").splitlines():
                try:
                    r = json.loads(text)
                    latest[r["id"]] = r
                except (ValueError, KeyError, TypeError):  # a line cut short by a kill
                    continue
        return latest

    def add(self, record: dict) -> None:
        self.latest[record["id"]] = record
        self.file.write(json.dumps(record) + "\n")
        self.file.flush()
        os.fsync(self.file.fileno())

    def close(self, rows: list[ManifestRow]) -> list[dict]:
        from mpeg4.io.atomic import atomic_write

        self.file.close()
        records = [self.latest[r.id] for r in rows if r.id in self.latest]
        with atomic_write(self.path, "w") as f:
            for r in records:
                f.write(json.dumps(r) + "\n")
        return records


@contextlib.contextmanager
def _exclusive(out: Path) -> Iterator[None]:
    """One batch at a time in an output folder (the lock goes with the process, even killed)."""
    import fcntl

    with open(out / ".batch.lock", "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError("another recon batch is writing into this folder", where=os.fspath(out),
                             fix="wait for it to finish, or write into another folder") from None
        yield


def run_batch(manifest: str | os.PathLike, out_dir: str | os.PathLike, workers: int | None = None,
              scheduler=None, ipd_mm: float | None = None, focal_px: float | None = None, method: str = "dffd",
              texture_size: int | None = None, atlas: bool = False, clone_step: Callable | None = None,
              detect: Callable | None = None, created: str | None = None, progress: bool = False) -> BatchReport:
    """``recon batch``: build every person of a manifest into ``out_dir/<id>/``.

    Parameters
    ----------
    manifest : path
        CSV or JSON Lines (:func:`read_manifest`).
    out_dir : path
        Created if needed. Holds a folder per finished person (the ``recon build`` bundle
        and ``batch.json``) and ``report.jsonl`` (one record per row, see
        :func:`build_person`). Rows whose folder exists are skipped; the others (new or
        failed before) are built.
    workers : int, optional
        Local worker processes (default: the CPUs this process may use); 0 builds in this
        process, one row after another.
    scheduler : str or distributed.Client, optional
        Run the tasks on this Dask distributed cluster instead (``tcp://host:8786``); the
        workers must see the manifest's files and ``out_dir`` at the same paths.
    ipd_mm, focal_px, method, texture_size, atlas
        Defaults for what a row leaves empty (see :func:`recon.build.run_build`).
    clone_step : callable, optional
        For rows with a ``clone`` column: ``clone_step(head, source) -> (head, warnings)``,
        e.g. :func:`chain.animatable.clone_step` (which ``recon batch`` passes).
    detect : callable, optional
        ``detect(front, side) -> FdpFile`` for rows without annotations (default:
        :func:`recon.landmarks.detect` when installed; else such rows fail with
        :data:`NO_LANDMARKS`).
    created : str, optional
        Time stamp in every head's provenance (default ``SOURCE_DATE_EPOCH`` if set, else
        the batch's start): with the same value, the same rows give byte-identical
        ``head.fdp.json`` files however and wherever they run.
    progress : bool
        Show a progress bar (rate, time left) on stderr.

    Returns
    -------
    BatchReport
    """
    from recon.build import DEFAULT_TEXTURE_SIZE, build_time
    from recon.shape.calibrate import DEFAULT_IPD_MM

    t0 = time.perf_counter()
    rows = read_manifest(manifest)
    if scheduler is not None and workers is not None:
        raise InputError("both --workers and --scheduler are given", where="recon batch",
                         fix="--workers is for local processes; a cluster's workers are its own")
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if workers < 0:
        raise InputError(f"--workers is {workers}", where="recon batch", fix="give 0 or more")
    defaults = {"ipd_mm": DEFAULT_IPD_MM if ipd_mm is None else ipd_mm, "focal_px": focal_px, "method": method,
                "texture_size": DEFAULT_TEXTURE_SIZE if texture_size is None else texture_size, "atlas": atlas}
    created = build_time(created)
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    with _exclusive(out):
        for p in _partials(out):  # left by a batch that was killed
            shutil.rmtree(p, ignore_errors=True)
        report = _Report(out)
        todo = []
        for row in rows:
            folder = out / row.id
            if (folder / RECORD_NAME).exists():
                record = {**_read_record(folder), "skipped": True}
                if record.get("row") is not None and not _same_row(record["row"], row.as_dict()):
                    record["stale"] = f"built from another version of the row; delete {folder} to build it again"
                report.latest[row.id] = record
            else:
                todo.append(row)
        submit_args = (os.fspath(out), defaults, created, clone_step, detect)
        try:
            with _progress_bar(progress, len(rows), len(rows) - len(todo)) as advance:
                def on_result(record):
                    report.add(record)
                    advance(record)

                if not todo:
                    pass
                elif scheduler is not None:
                    _run_dask(todo, scheduler, submit_args, on_result)
                elif workers == 0:
                    for row in todo:
                        on_result(build_person(row, *submit_args))
                else:
                    _run_local(todo, workers, submit_args, out, on_result)
        finally:
            records = report.close(rows)
    return BatchReport(records, out, time.perf_counter() - t0)
