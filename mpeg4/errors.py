"""Errors that reach the user.

Every problem with something a user gave us (a file, a feature point id, a value) is
raised as an :class:`InputError` that names *where* the problem is, *what* is wrong and
*how* to fix it, so that the command line can print it as one line instead of a
traceback.
"""

from __future__ import annotations

import os

__all__ = ["InputError", "require_file"]


class InputError(ValueError):
    """A problem with user input, reported as one line: ``where: what (fix: how)``.

    Parameters
    ----------
    what : str
        What is wrong, e.g. ``"expected 68 mask flags, found 67"``.
    where : str or os.PathLike, optional
        The file, and where useful the place in it, e.g. ``"walk.fap, line 12"``.
    fix : str, optional
        How to fix it, e.g. ``"each mask line lists one 0/1 flag per FAP 1..68"``.

    Examples
    --------
    >>> str(InputError("unknown feature point '12.1'", where="a.fdp.json, points",
    ...                fix="use an id of the form 'group.index' from mpeg4.FEATURE_POINTS"))
    "a.fdp.json, points: unknown feature point '12.1' (fix: use an id of the form 'group.index' from mpeg4.FEATURE_POINTS)"
    """

    def __init__(self, what: str, where: str | os.PathLike | None = None, fix: str | None = None):
        self.what = what
        self.where = None if where is None else os.fspath(where)
        self.fix = fix
        super().__init__(self._line())

    def _line(self) -> str:
        text = self.what if self.where is None else f"{self.where}: {self.what}"
        if self.fix:
            text += f" (fix: {self.fix})"
        return text


def require_file(path: str | os.PathLike, kind: str = "file") -> str:
    """Return ``path`` as a string, or raise :class:`InputError` if it is not a readable file.

    Parameters
    ----------
    path : str or os.PathLike
        The path a user gave.
    kind : str
        What the file is for, used in the message (``"GLB head"``, ``"FAP stream"``).
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{kind} not found", where=path, fix="check the path and the current directory")
    if os.path.isdir(path):
        raise InputError(f"expected a {kind}, found a folder", where=path, fix="give the path of the file itself")
    if not os.access(path, os.R_OK):
        raise InputError(f"{kind} is not readable", where=path, fix="check the file's permissions")
    return path
