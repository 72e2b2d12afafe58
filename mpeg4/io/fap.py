"""MPEG-4 ``.fap`` text streams: reading, writing, describing.

Layout (reference section 6)::

    # comment lines start with '#', anywhere
    <version> <name> <fps> <frame count>        header, once
    <m1> ... <m68>                              mask: one 0/1 flag per FAP 1..68
    <frame> <values of the masked FAPs, in FAP order>
    ...                                         (mask line + value line per frame)

A masked FAP 1 (viseme) contributes 4 numbers (select1, select2, blend, def), a masked
FAP 2 (expression) 6 (select1, intensity1, select2, intensity2, init_face, def); every other
FAP one value in FAPU (or AU for rotations).

The reader is tolerant of what real files do: float values, comment lines anywhere, blank
lines, tabs, CRLF line ends, frames with no FAP set, frame numbers starting at 1 (or any
increasing numbering), header versions 2.0/2.1/2.2 and a file path as the name. A frame
count in the header that disagrees with the frames present is an error, or with
``lenient=True`` the frames win (the header's count is kept in ``declared_frames``).
Anything else is an error naming the line.

An unmasked FAP is *unset* (NaN) in :attr:`FapStream.values`; :meth:`FapStream.held` gives the
common player reading: in a frame that sets only one FAP of an inner/outer lip pair
(:data:`LIP_CONTOUR_PAIRS`: 4-13 and 51-60), the other takes its value, so a stream written for
either contour moves the whole lip; then each FAP keeps its last value (and stays unset
before its first: a player reads it as 0, ``fmc`` also knows the stream never set it).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from ..catalogue import EXPRESSIONS, FAPS, VISEMES
from ..errors import InputError, require_file
from .atomic import atomic_write

__all__ = ["LIP_CONTOUR_PAIRS", "fill_lip_contours", "FapStream", "parse_fap", "read_fap", "format_fap", "write_fap",
           "describe_fap", "N_FAPS", "FPS_RANGE",
           "MAX_FRAME_NUMBER", "MAX_FAP_VALUE", "check_values"]

N_FAPS = 68
#: Frame rates accepted, frames per second (a stream's times are its frame numbers over it).
FPS_RANGE = (0.01, 10000.0)
#: Largest frame number accepted (players store them as 32-bit integers).
MAX_FRAME_NUMBER = 2 ** 31 - 1
#: Largest magnitude of a FAP value accepted: a million units is ten radians for a rotation
#: (in AU, 1e-5 rad) and a thousand times the face's own distances for a translation (in
#: FAPU, 1/1024 of them); no face moves further, and beyond it playback overflows.
MAX_FAP_VALUE = 1e6
_WIDTH = {1: 4, 2: 6}  # numbers contributed by FAPs 1 and 2


#: Inner-lip FAP → the outer-lip FAP that moves the same way on the outer contour
#: (``lower_t_midlip`` 4 ↔ ``lower_t_midlip_o`` 51, …, ``raise_r_cornerlip`` 13 ↔ 60).
LIP_CONTOUR_PAIRS = {n: n + 47 for n in range(4, 14)}


def fill_lip_contours(values: dict) -> dict:
    """A copy of one frame's FAP values (FAP → value) in which a lip FAP set without its
    inner/outer partner (:data:`LIP_CONTOUR_PAIRS`) gives the partner its value.

    The tables move the inner contour by the inner FAPs and the outer one by the outer
    FAPs (``fmc.lip_contours``); a stream that animates only one contour means the whole
    lip, as the players that write such streams show it.
    """
    out = dict(values)
    for inner, outer in LIP_CONTOUR_PAIRS.items():
        if inner in values and outer not in values:
            out[outer] = values[inner]
        elif outer in values and inner not in values:
            out[inner] = values[outer]
    return out


@dataclass
class FapStream:
    """A sequence of FAP frames.

    Attributes
    ----------
    fps : float
        Frames per second.
    frame_numbers : (F,) int64
        As written in the file (increasing; need not start at 0 or be contiguous).
    values : (F, 68) float64
        FAP k in column k − 1 (FAPU or AU); NaN where the frame does not set it. Columns 0
        and 1 (FAPs 1 and 2) are unused: see ``viseme`` and ``expression``.
    viseme : (F, 4) float64
        select1, select2, blend (0..63), def; NaN rows where FAP 1 is not set.
    expression : (F, 6) float64
        select1, intensity1, select2, intensity2, init_face, def; NaN where FAP 2 is unset.
    name : str
        Sequence name from the header.
    version : str
        Header version string (kept on writing).
    declared_frames : int or None
        The header's frame count, when it disagreed with the frames read.
    """

    fps: float
    frame_numbers: np.ndarray
    values: np.ndarray
    viseme: np.ndarray = None
    expression: np.ndarray = None
    name: str = "stream"
    version: str = "2.1"
    declared_frames: int | None = None

    def __post_init__(self):
        self.frame_numbers = np.asarray(self.frame_numbers, dtype=np.int64).reshape(-1)
        n = len(self.frame_numbers)
        self.values = np.asarray(self.values, dtype=np.float64).reshape(n, N_FAPS)
        self.viseme = np.full((n, 4), np.nan) if self.viseme is None else np.asarray(self.viseme, float).reshape(n, 4)
        self.expression = (np.full((n, 6), np.nan) if self.expression is None
                           else np.asarray(self.expression, float).reshape(n, 6))
        _check_fps(self.fps, None)

    @classmethod
    def from_values(cls, values, fps: float = 25.0, **kw) -> FapStream:
        """A stream from a (F, 68) array (NaN = unset), frames numbered from 0."""
        values = np.asarray(values, dtype=np.float64)
        return cls(fps, np.arange(len(values)), values, **kw)

    @property
    def n_frames(self) -> int:
        return len(self.frame_numbers)

    @property
    def duration(self) -> float:
        """Seconds from the first frame to one frame past the last."""
        if not self.n_frames:
            return 0.0
        return float(self.frame_numbers[-1] - self.frame_numbers[0] + 1) / self.fps

    @property
    def mask(self) -> np.ndarray:
        """(F, 68) bool: which FAPs each frame sets."""
        m = ~np.isnan(self.values)
        m[:, 0] = ~np.isnan(self.viseme[:, 0])
        m[:, 1] = ~np.isnan(self.expression[:, 0])
        return m

    def held(self) -> FapStream:
        """A copy where every FAP keeps its last set value (unset, NaN, before it is first
        set), after a frame's lip FAP set without its inner/outer partner has given it its
        value (:func:`fill_lip_contours`)."""
        out = np.array(self.values)
        for inner, outer in LIP_CONTOUR_PAIRS.items():
            a, b = out[:, inner - 1], out[:, outer - 1]
            only_a, only_b = ~np.isnan(a) & np.isnan(b), np.isnan(a) & ~np.isnan(b)
            b[only_a], a[only_b] = a[only_a], b[only_b]
        out[:, :2] = np.nan
        for k in range(2, N_FAPS):
            col = out[:, k]
            idx = np.where(~np.isnan(col), np.arange(len(col)), -1)
            np.maximum.accumulate(idx, out=idx)
            out[:, k] = np.where(idx >= 0, col[np.maximum(idx, 0)], np.nan)
        return FapStream(self.fps, self.frame_numbers.copy(), out, self.viseme.copy(), self.expression.copy(),
                         self.name, self.version)

    def frame_values(self, i: int) -> dict:
        """FAP values of frame ``i`` (row index) as :func:`mpeg4.fat.apply_fat` takes them.

        FAPs 3..68 that are set map to their values; a viseme pair maps ``(1, v1)`` to
        ``blend`` and ``(1, v2)`` to ``63 − blend``; expressions map ``(2, e)`` to their
        intensities.
        """
        out: dict = {}
        row = self.values[i]
        for k in np.flatnonzero(~np.isnan(row[2:])) + 2:
            out[int(k) + 1] = float(row[k])
        v = self.viseme[i]
        if not np.isnan(v[0]):
            out[(1, int(v[0]))] = out.get((1, int(v[0])), 0.0) + float(v[2])
            out[(1, int(v[1]))] = out.get((1, int(v[1])), 0.0) + 63.0 - float(v[2])
        e = self.expression[i]
        if not np.isnan(e[0]):
            out[(2, int(e[0]))] = out.get((2, int(e[0])), 0.0) + float(e[1])
            out[(2, int(e[2]))] = out.get((2, int(e[2])), 0.0) + float(e[3])
        return out


def _check_fps(fps: float, where: str | None, token: str | None = None) -> None:
    lo, hi = FPS_RANGE
    if not lo <= fps <= hi:
        what = "is not positive" if not fps > 0 else f"is outside {lo:g}..{hi:g}"
        raise InputError(f"frame rate {token or f'{fps:g}'} {what}", where=where, fix="give frames per second, e.g. 25")


def check_values(stream: FapStream, where: str | None = None) -> None:
    """Raise :class:`InputError` naming the first frame and FAP whose value is NaN-free but
    beyond :data:`MAX_FAP_VALUE` or not finite (unset values, NaN, are fine)."""
    for name, arr, col in (("values", stream.values, None), ("viseme", stream.viseme, 1), ("expression", stream.expression, 2)):
        bad = np.isinf(arr) | (np.abs(np.nan_to_num(arr)) > MAX_FAP_VALUE)
        if bad.any():
            i, j = (int(k[0]) for k in np.nonzero(bad))
            fap_no = j + 1 if col is None else col
            raise InputError(f"frame {stream.frame_numbers[i]}: FAP {fap_no} ({FAPS[fap_no].name}) is {arr[i, j]:g}, "
                             f"beyond the {MAX_FAP_VALUE:g} any face motion needs", where=where,
                             fix="check the stream's values (FAPU or AU; a few hundred to a few thousand is usual)")


def _number(token: str, where: str, what: str) -> float:
    try:
        x = float(token)
    except ValueError:
        raise InputError(f"{what} '{token}' is not a number", where=where,
                         fix="values are numbers separated by spaces or tabs") from None
    if not math.isfinite(x):
        raise InputError(f"{what} '{token}' is not a finite number", where=where)
    return x


def parse_fap(text: str, where: str = "<string>", lenient: bool = False) -> FapStream:
    """Parse the text of a ``.fap`` file; ``where`` names it in error messages.

    A header frame count that disagrees with the frames in the body is an error unless
    ``lenient`` (then the body wins and the header's count is kept in ``declared_frames``).
    """
    lines = [(k + 1, line.split()) for k, line in enumerate(re.split(r"\r\n|\r|\n", text))]
    lines = [(n, toks) for n, toks in lines if toks and not toks[0].startswith("#")]
    if not lines:
        raise InputError("the file has no header line", where=where,
                         fix="a .fap file starts with '<version> <name> <fps> <frame count>', e.g. '2.1 demo 25 100'")
    n0, head = lines[0]
    here = f"{where}, line {n0}"
    if len(head) < 4:
        raise InputError(f"the header has {len(head)} fields, expected 4: version, name, fps, frame count",
                         where=here, fix="e.g. '2.1 demo 25 100'")
    version, name = head[0], " ".join(head[1:-2])
    fps = _number(head[-2], here, "frame rate")
    _check_fps(fps, here, head[-2])
    declared = _number(head[-1], here, "frame count")
    if declared < 0 or declared != int(declared) or declared > MAX_FRAME_NUMBER:
        raise InputError(f"frame count {head[-1]} is not a whole number up to {MAX_FRAME_NUMBER}", where=here)
    body = lines[1:]
    frames, vals, vis, exps = [], [], [], []
    k = 0
    while k < len(body):
        n_mask, mtoks = body[k]
        here = f"{where}, line {n_mask}"
        if len(mtoks) != N_FAPS:
            raise InputError(f"expected {N_FAPS} mask flags, found {len(mtoks)}", where=here,
                             fix="each frame starts with a mask line of one 0/1 flag per FAP 1..68")
        mask = np.array([_number(t, here, "mask flag") for t in mtoks])
        if not np.isin(mask, (0, 1)).all():
            bad = mtoks[int(np.flatnonzero(~np.isin(mask, (0, 1)))[0])]
            raise InputError(f"mask flag '{bad}' is not 0 or 1", where=here, fix="a mask line holds only 0 and 1")
        if k + 1 >= len(body):
            raise InputError("the last mask line has no value line after it", where=here,
                             fix="the file is truncated; each mask line is followed by '<frame> <values>'")
        n_val, vtoks = body[k + 1]
        here = f"{where}, line {n_val}"
        flags = mask.astype(bool)
        expected = 1 + sum(_WIDTH.get(f + 1, 1) for f in np.flatnonzero(flags))
        if len(vtoks) != expected:
            raise InputError(f"frame {vtoks[0]}: expected {expected} numbers (the frame number and "
                             f"{expected - 1} values for the {int(flags.sum())} FAPs in the mask), found {len(vtoks)}",
                             where=here, fix="give one value per masked FAP (4 for FAP 1, 6 for FAP 2), in FAP order")
        nums = [_number(t, here, "value") for t in vtoks]
        frame = nums[0]
        if frame != int(frame):
            raise InputError(f"frame number {vtoks[0]} is not a whole number", where=here)
        if abs(frame) > MAX_FRAME_NUMBER:
            raise InputError(f"frame number {vtoks[0]} is beyond {MAX_FRAME_NUMBER}", where=here,
                             fix="number the frames from 0 or 1")

        if frames and int(frame) <= frames[-1]:
            raise InputError(f"frame number {int(frame)} does not follow frame {frames[-1]}", where=here,
                             fix="frame numbers must increase")
        row = np.full(N_FAPS, np.nan)
        v = np.full(4, np.nan)
        e = np.full(6, np.nan)
        pos = 1
        for f in np.flatnonzero(flags):
            width = _WIDTH.get(f + 1, 1)
            chunk = nums[pos:pos + width]
            big = [k for k, x in enumerate(chunk) if abs(x) > MAX_FAP_VALUE]
            if big:
                raise InputError(f"frame {int(frame)}: FAP {f + 1} ({FAPS[f + 1].name}) is {vtoks[pos + big[0]]}, beyond "
                                 f"the {MAX_FAP_VALUE:g} any face motion needs", where=here,
                                 fix="check the stream's values (FAPU or AU; a few hundred to a few thousand is usual)")
            pos += width
            if f == 0:
                v[:] = chunk
            elif f == 1:
                e[:] = chunk
            else:
                row[f] = chunk[0]
        if not np.isnan(v[0]) and not (v[0] in VISEMES and v[1] in VISEMES):
            raise InputError(f"frame {int(frame)}: viseme numbers {v[0]:g}, {v[1]:g} are not in 0..14", where=here)
        if not np.isnan(e[0]) and not (e[0] in EXPRESSIONS and e[2] in EXPRESSIONS):
            raise InputError(f"frame {int(frame)}: expression numbers {e[0]:g}, {e[2]:g} are not in 0..6", where=here)
        frames.append(int(frame))
        vals.append(row)
        vis.append(v)
        exps.append(e)
        k += 2
    n = len(frames)
    if int(declared) != n and not lenient:
        raise InputError(f"the header says {int(declared)} frames but the file holds {n}", where=f"{where}, line {n0}",
                         fix="correct the frame count (the header's last field), or read it leniently "
                             "(--lenient) to trust the frames")
    return FapStream(fps, np.array(frames, dtype=np.int64), np.array(vals).reshape(n, N_FAPS),
                     np.array(vis).reshape(n, 4), np.array(exps).reshape(n, 6), name=name or "stream",
                     version=version, declared_frames=None if int(declared) == n else int(declared))


def read_fap(path: str | os.PathLike, lenient: bool = False) -> FapStream:
    """Read a ``.fap`` file (errors name the file and line; ``lenient`` as :func:`parse_fap`)."""
    path = require_file(path, "FAP stream")
    try:
        with open(path, encoding="utf-8", errors="strict") as f:
            text = f.read()
    except UnicodeDecodeError:
        with open(path, encoding="latin-1") as f:  # names with accents in old files
            text = f.read()
    return parse_fap(text, where=path, lenient=lenient)


def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else repr(float(x))


def format_fap(stream: FapStream) -> str:
    """The ``.fap`` text of ``stream`` (every frame with its own mask)."""
    name = re.sub(r"\s+", "_", stream.name.strip()) or "stream"
    out = [f"{stream.version} {name} {_fmt(stream.fps)} {stream.n_frames}"]
    mask = stream.mask
    for i in range(stream.n_frames):
        out.append(" ".join("1" if m else "0" for m in mask[i]))
        vals = [str(int(stream.frame_numbers[i]))]
        for f in np.flatnonzero(mask[i]):
            if f == 0:
                vals += [_fmt(x) for x in stream.viseme[i]]
            elif f == 1:
                vals += [_fmt(x) for x in stream.expression[i]]
            else:
                vals.append(_fmt(stream.values[i, f]))
        out.append(" ".join(vals))
    return "\n".join(out) + "\n"


def write_fap(stream: FapStream, path: str | os.PathLike) -> str:
    """Write ``stream`` as a ``.fap`` file, atomically (refusing values :func:`check_values` refuses)."""
    check_values(stream, where=os.fspath(path))
    with atomic_write(path, "w", encoding="utf-8") as f:
        f.write(format_fap(stream))
    return os.fspath(path)


def describe_fap(stream: FapStream) -> str:
    """A few lines about a stream: rate, frames, duration, which FAPs it drives and how far."""
    mask = stream.mask
    used = np.flatnonzero(mask.any(axis=0)) + 1
    low = [int(f) for f in used if f > 2]
    lines = [f"name: {stream.name} (version {stream.version})",
             f"frames: {stream.n_frames} at {stream.fps:g} fps, {stream.duration:.2f} s"
             + (f" (the header says {stream.declared_frames})" if stream.declared_frames is not None else "")]
    if stream.n_frames:
        lines.append(f"frame numbers: {stream.frame_numbers[0]} to {stream.frame_numbers[-1]}"
                     + ("" if np.all(np.diff(stream.frame_numbers) == 1) else " (with gaps)"))
    empty = int((~mask.any(axis=1)).sum())
    if empty:
        lines.append(f"frames that set no FAP: {empty}")
    lines.append(f"low-level FAPs driven: {len(low)}"
                 + (": " + ", ".join(f"{f} {FAPS[f].name}" for f in low[:8]) + (" ..." if len(low) > 8 else "")
                    if low else ""))
    for f in low[:8]:
        col = stream.values[:, f - 1]
        col = col[~np.isnan(col)]
        lines.append(f"  {f} {FAPS[f].name}: {col.min():g} .. {col.max():g} {FAPS[f].unit}")
    if mask[:, 0].any():
        v = stream.viseme[mask[:, 0]]
        ids = sorted({int(x) for x in np.r_[v[:, 0], v[:, 1]]})
        lines.append("visemes: " + ", ".join(f"{i} {VISEMES[i].name}" for i in ids))
    if mask[:, 1].any():
        e = stream.expression[mask[:, 1]]
        ids = sorted({int(x) for x in np.r_[e[:, 0], e[:, 2]]})
        lines.append("expressions: " + ", ".join(f"{i} {EXPRESSIONS[i].name}" for i in ids))
    return "\n".join(lines)
