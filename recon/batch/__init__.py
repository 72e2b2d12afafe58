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

import contextlib
import os
import shutil
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from mpeg4.errors import InputError

from .manifest import GENERIC_SOURCE, ManifestRow, read_manifest
from .report import REPORT_NAME, BatchReport, _Report
from .runners import _partials, _progress_bar, _run_dask, _run_local, _same_row
from .task import NO_LANDMARKS, RECORD_NAME, _read_record, build_person

__all__ = ["ManifestRow", "BatchReport", "read_manifest", "build_person", "run_batch", "REPORT_NAME",
           "RECORD_NAME", "NO_LANDMARKS", "GENERIC_SOURCE"]


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
    from recon.build import DEFAULT_TEXTURE_SIZE
    from recon.bundle import build_time
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
