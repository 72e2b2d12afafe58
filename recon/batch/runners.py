"""Where a batch's tasks run: local worker processes or a Dask cluster, with a progress bar.

Both gather the same plain records; a crashed local worker is replaced and its row retried
a bounded number of times.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import shutil
import time
from collections.abc import Callable, Iterator
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from mpeg4.errors import InputError

from .manifest import ManifestRow
from .task import _PARTIAL, build_person

# What a Dask nanny gives its workers (distributed.nanny.pre-spawn-environ): one thread per
# numerical library, since the parallelism is the processes; and glibc handing freed memory
# back, so that a long batch keeps a flat footprint. Local workers get the same, which also
# makes their results the same as a cluster's to the last bit.
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
               "MALLOC_TRIM_THRESHOLD_": "65536"}

# A row whose worker process dies this many times is recorded as failed.
_MAX_CRASHES = 2


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
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

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
