"""JSON read strictly: every JSON text the tools take from a user goes through :func:`loads`.

Python's parser recurses once per level of nesting, so a file of a hundred thousand ``[``
ends in a ``RecursionError`` deep inside it, and it keeps the last of two equal keys
without a word. Here a text nested deeper than :data:`MAX_DEPTH` is refused before it is
parsed, a key given twice in one object is refused, and a syntax error names the line
and column, and so does a number too large for a double, a NaN or an Infinity (Python's
parser takes them), all as one-line :class:`~mpeg4.errors.InputError` messages.
"""

from __future__ import annotations

import json
import math
import os
import re

import numpy as np

from ..errors import InputError, require_file

__all__ = ["MAX_DEPTH", "MAX_INT", "loads", "read_json", "json_depth"]

#: Deepest nesting of objects and arrays accepted. The project's own files nest at most
#: 6 levels (an fdp.json's metadata a few more); glTF documents about 8.
MAX_DEPTH = 64

# A JSON string: what is between its quotes never opens or closes anything.
_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def json_depth(text: str | bytes) -> int:
    """How deeply the objects and arrays of a JSON text nest (0 for a bare value).

    Strings are skipped, so brackets inside them do not count. For a text that is not
    valid JSON the figure is still an upper bound of what a parser would recurse into.

    Examples
    --------
    >>> json_depth('{"a": [1, [2, "]]]"]]}')
    3
    """
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else bytes(text)
    bare = np.frombuffer(_STRING.sub(b'""', data), dtype=np.uint8)
    step = np.isin(bare, (ord("["), ord("{"))).astype(np.int64) - np.isin(bare, (ord("]"), ord("}")))
    return int(np.cumsum(step).max(initial=0))


#: Largest whole number accepted (every one up to it is exact as a float64).
MAX_INT = 2 ** 53


class _BadNumber(Exception):
    """A number token the parser's hooks refuse: the token and why."""


def _number(token: str):
    x = float(token)
    if not math.isfinite(x):
        raise _BadNumber(token, "is too large for a double")
    return x


def _whole(token: str):
    if len(token.lstrip("-")) > 16 or abs(int(token)) > MAX_INT:
        raise _BadNumber(token, f"is a whole number beyond {MAX_INT}")
    return int(token)


def _constant(token: str):
    raise _BadNumber(token, "is not a finite number")


def _locate(text: str, token: str) -> str:
    """'line L, column C' of the first ``token`` outside the strings of ``text``."""
    masked = re.sub(r'"(?:[^"\\]|\\.)*"', lambda m: re.sub(r"[^\n]", " ", m.group()), text, flags=re.DOTALL)
    k = masked.find(token)
    if k < 0:
        return ""
    line = masked.count("\n", 0, k) + 1
    return f", line {line}, column {k - (masked.rfind(chr(10), 0, k) + 1) + 1}"


def _no_duplicates(where: str):
    def hook(pairs):
        out = {}
        for key, value in pairs:
            if key in out:
                raise InputError(f"the key {key!r} appears twice in one object", where=where,
                                 fix="keep one of them (a JSON object holds each key once)")
            out[key] = value
        return out

    return hook


def loads(text: str | bytes, where: str, max_depth: int = MAX_DEPTH):
    """Parse a JSON text, refusing deep nesting and repeated keys.

    Parameters
    ----------
    text : str or bytes
        The JSON text (bytes are decoded as UTF-8).
    where : str
        Names the text in errors (a file path, ``"request body"``).
    max_depth : int
        Deepest nesting accepted.

    Raises
    ------
    InputError
        Not UTF-8, not JSON (with line and column), nested too deeply, or a key repeated.
    """
    if isinstance(text, (bytes, bytearray)):
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError:
            raise InputError("not UTF-8 text", where=where, fix="give a JSON text file") from None
    depth = json_depth(text)
    if depth > max_depth:
        raise InputError(f"JSON nested {depth} levels deep, more than the {max_depth} accepted", where=where,
                         fix="give a file of the documented layout (it nests a few levels)")
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates(where), parse_float=_number, parse_int=_whole,
                          parse_constant=_constant)
    except _BadNumber as e:
        token, why = e.args
        shown = token if len(token) <= 40 else token[:37] + "..."
        raise InputError(f"{shown} {why}", where=f"{where}{_locate(text, token)}",
                         fix="give finite numbers of a sensible size (JSON has no NaN or Infinity)") from None
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON: {e.msg} at line {e.lineno}, column {e.colno}", where=where,
                         fix="fix the JSON syntax (a missing comma or quote?)") from None
    except RecursionError:  # a stack smaller than the depth limit assumes
        raise InputError("JSON nested too deeply to read", where=where,
                         fix="give a file of the documented layout") from None


def read_json(path: str | os.PathLike, kind: str = "JSON file", max_depth: int = MAX_DEPTH):
    """Read a JSON file as :func:`loads` parses it (``kind`` names it when it is missing)."""
    path = require_file(path, kind)
    with open(path, "rb") as f:
        data = f.read()
    if data.startswith(b"\xef\xbb\xbf"):  # a byte-order mark some editors write
        data = data[3:]
    return loads(data, where=path, max_depth=max_depth)
