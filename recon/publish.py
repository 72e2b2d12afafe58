"""A folder of files that belong together, put in place whole or not at all.

``recon build`` writes a bundle whose files refer to each other (``head.obj`` names
``head.mtl``, which names ``texture.png``; ``head.fdp.json`` describes ``head.glb``). Replaced
one file at a time, a kill between two replaces leaves an OBJ with the last build's texture.
:func:`publish` avoids that:

- when the output folder holds nothing but an earlier bundle (or does not exist yet), the
  new bundle is written in a hidden folder beside it, ``.OUT.build-XXXX``, which then takes
  the output folder's place in one step (``renameat2`` with ``RENAME_EXCHANGE``: the two
  folders swap names atomically); the old one is deleted after;
- when the output folder holds other files too (the user's own, a ``say/`` folder), or is
  the current folder of this process, or a mount point, or the file system cannot swap
  folders, the new bundle is written whole into ``OUT/.build-XXXX``, marked complete, and
  then moved in file by file: a kill between two moves leaves the marked folder, and the
  next run completes the moves before anything else. Nothing but the bundle's own names is
  ever replaced, so the user's other files stay as they are.

Leftovers of killed runs (unmarked hidden folders, old bundles swapped out) are removed by
the next run into the same folder. Runs into one folder take turns (an ``fcntl`` lock on
``.OUT.lock`` beside it), so one never removes another's folder while it is written.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import glob
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

__all__ = ["BUNDLE_NAMES", "COMPLETE", "publish", "is_bundle_name"]

#: Names of the files a ``recon build`` bundle holds (``head_<part>.png``: a part's texture).
BUNDLE_NAMES = re.compile(r"^(head\.glb|head\.obj|head\.mtl|texture\.png|head\.fdp\.json|preview\.png|head_[\w.-]+\.png)$")
#: The marker a staging folder holds once every file in it is complete.
COMPLETE = ".complete"
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def is_bundle_name(name: str) -> bool:
    """Whether a file name is one a bundle holds (and a build may replace)."""
    return BUNDLE_NAMES.match(name) is not None


def _exchange(a: Path, b: Path) -> None:
    """Swap two paths' names in one step (Linux ``renameat2``); OSError where it cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except AttributeError:
        raise OSError(errno.ENOSYS, "renameat2 is not available") from None
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) != 0:
        e = ctypes.get_errno()
        raise OSError(e, os.strerror(e), os.fspath(a))


@contextlib.contextmanager
def _lock(out: Path) -> Iterator[None]:
    """Exclusive use of ``out`` among the processes that publish into it."""
    path = out.parent / f".{out.name}.lock"
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o600)
        fcntl.flock(fd, fcntl.LOCK_EX)
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:  # not a lock file the last holder removed while this one waited
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
        os.close(fd)


def _move_in(staged: Path, out: Path) -> None:
    """Move a complete staging folder's files into ``out`` (each replace atomic), then
    remove the folder."""
    for p in sorted(staged.iterdir()):
        if p.name != COMPLETE:
            os.replace(p, out / p.name)
    shutil.rmtree(staged, ignore_errors=True)


def _recover(out: Path) -> None:
    """Finish what a killed run left: a complete staging folder (inside ``out`` or beside
    it) is moved in; every other leftover (incomplete, or an old bundle swapped out) is
    removed."""
    beside = out.parent.glob(f".{glob.escape(out.name)}.build-*")
    inside = out.glob(".build-*") if out.is_dir() else []
    for p in sorted(beside) + sorted(inside):
        if not p.is_dir() or p.is_symlink():
            continue
        if (p / COMPLETE).is_file():
            out.mkdir(exist_ok=True)
            _move_in(p, out)
        else:
            shutil.rmtree(p, ignore_errors=True)


def _swappable(out: Path) -> bool:
    """Whether ``out`` can be swapped whole: it holds nothing but a bundle's files (and
    hidden leftovers of ours), it is not this process's current folder nor holds it, and it
    is not a mount point."""
    if not out.exists():
        return True
    if not out.is_dir() or os.path.ismount(out):
        return False
    here = Path.cwd().resolve()
    if here == out.resolve() or out.resolve() in here.parents:
        return False
    return all(is_bundle_name(p.name) for p in out.iterdir())


def publish(out: str | os.PathLike, write: Callable[[Path], dict[str, Path]]) -> dict[str, Path]:
    """Write a bundle with ``write(folder)`` and put it in ``out`` whole (see the module
    docstring).

    Parameters
    ----------
    out : path
        The output folder (created with its parents if missing; a link to a folder is
        followed).
    write : callable
        Writes the bundle's files into the folder it is given (only names
        :func:`is_bundle_name` accepts) and returns {key: path in that folder}.

    Returns
    -------
    dict of str to Path
        {key: path in ``out``} for the files written.
    """
    out = Path(out)
    if out.is_symlink():
        out = out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    with _lock(out):
        _recover(out)
        swap = _swappable(out)
        if not swap:
            out.mkdir(exist_ok=True)
        staged = Path(tempfile.mkdtemp(prefix=f".{out.name}.build-" if swap else ".build-",
                                       dir=out.parent if swap else out))
        try:
            written = write(staged)
            strays = sorted(p.name for p in staged.iterdir() if not is_bundle_name(p.name))
            if strays:
                raise ValueError(f"a bundle may not hold {strays}")
            (staged / COMPLETE).touch()
            if swap:
                _put_in_place(staged, out)
            else:
                _move_in(staged, out)
        finally:
            if staged.exists():
                shutil.rmtree(staged, ignore_errors=True)
    return {key: out / Path(p).name for key, p in written.items()}


def _put_in_place(staged: Path, out: Path) -> None:
    """``staged`` becomes ``out`` in one step; what ``out`` held is deleted after."""
    if out.exists():
        staged.chmod(out.stat().st_mode & 0o7777)
    else:
        umask = os.umask(0)
        os.umask(umask)
        staged.chmod(0o777 & ~umask)  # mkdtemp's folder is private: what mkdir would have made
    (staged / COMPLETE).unlink()
    if not out.exists():
        try:
            os.rename(staged, out)
            return
        except OSError:  # made meanwhile, by someone else: swap with it instead
            pass
    try:
        _exchange(staged, out)
    except OSError as e:
        if e.errno not in (errno.ENOSYS, errno.EINVAL, errno.EXDEV, errno.EPERM, errno.ENOTSUP):
            raise
        # This file system cannot swap folders: move the files in one by one instead.
        (staged / COMPLETE).touch()
        _move_in(staged, out)
        return
    shutil.rmtree(staged, ignore_errors=True)  # now the old bundle
