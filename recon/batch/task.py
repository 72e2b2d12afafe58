"""One person of a batch: :func:`build_person`, the task local workers and Dask run.

The head is built into a hidden temporary folder in ``OUT`` (``recon build``, then the clone
step) and renamed to ``OUT/<id>/`` once everything is written; a row without annotations
takes its points from automatic detection. The task returns a plain record: status, error,
times and the worker's memory.
"""

from __future__ import annotations

import concurrent.futures as cf
import functools
import gc
import json
import os
import resource
import shutil
import socket
import tempfile
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from mpeg4.errors import InputError

from recon.detection import DETECTED_NAME, correction_hint, detect_annotations

from .manifest import ManifestRow

__all__ = ["RECORD_NAME", "NO_LANDMARKS", "build_person"]

#: Each head's own record, in ``OUT/<id>/``: the row it was built from and how it went.
RECORD_NAME = "batch.json"

#: The failure of a row without annotations when automatic detection is not installed.
NO_LANDMARKS = "no annotations and automatic landmarks are not installed"
_PARTIAL = ".partial-"


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
    detect = detect or _landmark_detector()
    if detect is None:
        raise InputError(NO_LANDMARKS, where=row.where,
                         fix="mark the points (recon annotate FRONT SIDE) and give the fdp.json in the fdp "
                             "column, or install automatic detection (recon.landmarks)")
    try:
        path = detect_annotations(row.front, row.side, folder / DETECTED_NAME, detect=detect, where=row.where)
    except ImportError as e:  # recon.landmarks is there but its models are not (mediapipe)
        raise InputError(NO_LANDMARKS, where=row.where, fix=f"{e}; or mark the points (recon annotate FRONT SIDE) "
                                                            f"and give the fdp.json in the fdp column") from None
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
        detected = None if tmp is None else tmp / DETECTED_NAME
        if detected is not None and detected.exists() and row.fdp is None and row.shape_from is None:
            # Keep what was detected beside the report, for a person to correct.
            kept = out / f"{row.id}.{DETECTED_NAME}"
            shutil.copyfile(detected, kept)
            text = text.replace(os.fspath(detected), os.fspath(kept))
            if os.fspath(kept) not in text:
                text += f" (the detected points are kept in {kept}: {correction_hint(row.front, row.side, kept)})"
            record["annotations"] = os.fspath(kept)
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
        Time stamp for the bundle's provenance (:func:`recon.bundle.build_time`).
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
