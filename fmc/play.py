"""Fast playback of Facial Animation Tables: FAP values → vertex positions.

:class:`Player` turns a head's FAT into one sparse matrix whose columns are the
per-interval displacement slopes of every FaceDefMesh (metres per FAP unit, over all the
head's vertices stacked), so that a frame is: the signed overlaps of each active table's
intervals (the section-5 rule, :func:`mpeg4.fat.signed_overlaps`), one sparse product over
the active columns, then the FaceDefTransforms (parts first, the whole head last, faded
over the neck by :func:`mpeg4.neck.neck_fade`), exactly as :func:`mpeg4.fat.apply_fat`
does it with that fade, only without touching the tables again.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping

import numpy as np
import scipy.sparse as sp

try:  # y += A x in place (scipy's own kernel); plain products otherwise
    from scipy.sparse._sparsetools import csc_matvec as _csc_matvec
except ImportError:  # pragma: no cover - other scipy layouts
    def _csc_matvec(n_row, n_col, indptr, indices, data, x, y):
        y += sp.csc_matrix((data, indices, indptr), shape=(n_row, n_col)) @ x

from mpeg4.errors import InputError
from mpeg4.fat import _key, fap_unit
from mpeg4.head import Head
from mpeg4.neck import blend_turn, joint_weights, neck_fade

from .frames import FrameDecoder

__all__ = ["Player"]


class Player:
    """Precomputed FAT playback for one head.

    Parameters
    ----------
    head : Head
        With ``head.fat``.
    limits : bool
        Keep frames within the limits a face has (:class:`fmc.limits.Limits`); which
        acted, and in how many frames, is counted in ``player.decode.clamped``.

    Examples
    --------
    >>> from mpeg4.generic_head import load_generic_head  # doctest: +SKIP
    >>> player = Player(head)  # doctest: +SKIP
    >>> parts = player.part_vertices(player.vertices({3: 300.0, 49: 5000.0}))  # doctest: +SKIP
    """

    def __init__(self, head: Head, limits: bool = True):
        if head.fat is None or not len(head.fat):
            raise InputError("the head has no Facial Animation Tables to play",
                             fix="author them (fmc author) or clone them from a source head")
        self.head = head
        self.decode = FrameDecoder(head, limits=limits)
        fapu = head.fapu
        self.part_names = list(head.parts)
        sizes = [head.parts[n].n_vertices for n in self.part_names]
        self.offsets = dict(zip(self.part_names, np.cumsum([0] + sizes[:-1]).tolist()))
        self.slices = {n: slice(o, o + s) for n, o, s in zip(self.part_names, self.offsets.values(), sizes)}
        self.neutral = np.concatenate([head.parts[n].vertices for n in self.part_names])
        n_all = len(self.neutral)
        self._neutral_t = np.ascontiguousarray(self.neutral.T)  # (3, N)
        rows, cols, vals = [], [], []
        self.tables: dict[tuple[int, int], tuple[np.ndarray, list]] = {}
        self.transforms = []
        col = 0
        for table in head.fat.tables():
            unit = fap_unit(table.fap, fapu)
            mesh_cols = []
            for m in table.meshes:
                if m.part not in self.offsets:
                    continue
                base = self.offsets[m.part] + m.indices
                n = len(m.borders) - 1
                for k in range(n):
                    d = m.displacements[:, k, :] * unit
                    # Component-major rows (all x, then all y, then all z): rotations of
                    # the whole head are then one small BLAS product.
                    rows.append((base[None, :] + n_all * np.arange(3)[:, None]).ravel())
                    cols.append(np.full(3 * len(m.indices), col))
                    vals.append(d.T.ravel())
                    mesh_cols.append((col, m.borders, k))
                    col += 1
            self.tables[table.key] = mesh_cols
            for t in table.transforms:
                self.transforms.append((table.key, t, unit))
        self.n_columns = col
        self.matrix = sp.csc_matrix((np.concatenate(vals) if vals else np.zeros(0),
                                     (np.concatenate(rows) if rows else np.zeros(0, int),
                                      np.concatenate(cols) if cols else np.zeros(0, int))),
                                    shape=(3 * len(self.neutral), max(col, 1)))
        self.matrix.sum_duplicates()
        # Per table and sign of the value, the columns that can be non-zero, as their own
        # small matrix: a frame then costs the motion of its active tables only.
        self._blocks = {}
        for key, mesh_cols in self.tables.items():
            for sign in (1, -1):
                chosen = [(c, b, j) for c, b, j in mesh_cols if (b[j + 1] > 0 if sign > 0 else b[j] < 0)]
                if not chosen:
                    continue
                borders, pick = [], []
                for _, b, j in chosen:  # each distinct set of borders once per frame
                    n = next((n for n, known in enumerate(borders) if known == tuple(float(x) for x in b)),
                             len(borders))
                    if n == len(borders):
                        borders.append(tuple(float(x) for x in b))
                    pick.append((n, j))
                self._blocks[key, sign] = (self.matrix[:, [c for c, _, _ in chosen]].tocsc(), borders, pick)
        # Whole-head transforms go last, after the parts' own (apply_fat's order).
        self.transforms.sort(key=lambda kt: (kt[1].part is None, kt[0]))
        # Each vertex's share of the head turn: the head turns, the shoulders stay.
        whole = [t for _, t, _ in self.transforms if t.part is None]
        self.turn_weights = None
        if whole:
            fade = neck_fade(head).fade
            self.turn_weights = np.concatenate([joint_weights(fade[n]) for n in self.part_names])
            self.turn_pivot = next((t.centre for t in whole if t.kind == "rotation"), whole[0].centre)

    def vertices(self, values: Mapping) -> np.ndarray:
        """(N, 3) vertices of all parts stacked (part order of the head) for one frame.

        Parameters
        ----------
        values : mapping
            FAP number → value (FAPU), or ``(1, v)`` / ``(2, e)`` → intensity; FAPs without
            a table are ignored, like :func:`mpeg4.fat.apply_fat` does. A lip FAP given
            without its inner/outer partner gives it its value
            (:func:`mpeg4.io.fap.fill_lip_contours`): a frame that moves one lip contour
            moves the whole lip; the limits a face has apply (unless the player was made
            with ``limits=False``); the lip FAPs set lose what the jaw FAPs already do to
            their points (:class:`fmc.frames.FrameDecoder`).
        """
        values = self.decode(values)
        out_t = self._neutral_t.copy()
        flat = out_t.reshape(-1)
        keys = []
        for k, value in values.items():
            key = _key(k)
            if key not in self.tables or not value:
                continue
            value = float(value)
            keys.append((key, value))
            block = self._blocks.get((key, 1 if value > 0 else -1))
            if block is None:
                continue
            matrix, borders, pick = block
            overlaps = [_overlaps(b, value) for b in borders]
            w = np.array([overlaps[n][j] for n, j in pick])
            # y += A x in place, without a temporary the size of the whole head.
            _csc_matvec(matrix.shape[0], matrix.shape[1], matrix.indptr, matrix.indices, matrix.data, w, flat)
        out = out_t.T  # (N, 3) view
        if self.transforms:
            vals = dict(keys)
            whole = None  # the whole-head motions, composed into one affine map
            for key, t, unit in self.transforms:
                value = vals.get(key)
                if not value:
                    continue
                if t.part is None:
                    a, b = t.affine(value, unit)
                    whole = (a, b) if whole is None else (a @ whole[0], a @ whole[1] + b)
                elif t.part in self.slices:
                    sl = self.slices[t.part]
                    out[sl] = t.apply(out[sl], value, unit)
            if whole is not None:
                out = blend_turn(out, self.turn_weights, whole[0], whole[1], self.turn_pivot)
        return out

    def part_vertices(self, stacked: np.ndarray) -> dict[str, np.ndarray]:
        """Split stacked (N, 3) vertices into the head's parts."""
        return {n: stacked[sl] for n, sl in self.slices.items()}

    def play(self, stream) -> Iterator[np.ndarray]:
        """Stacked vertices of every frame of a :class:`mpeg4.io.fap.FapStream` (values held
        between frames that leave a FAP unset, as most players do)."""
        held = stream.held()
        for i in range(held.n_frames):
            yield self.vertices(held.frame_values(i))


def _overlaps(borders: tuple[float, ...], value: float) -> list[float]:
    """:func:`mpeg4.fat.signed_overlaps` on plain floats (a frame needs a handful of them,
    where numpy's per-call cost would dominate)."""
    n = len(borders) - 1
    out = []
    for k in range(n):
        lo, hi = borders[k], borders[k + 1]
        if k == 0 and lo < 0:
            lo = -math.inf
        if k == n - 1 and hi > 0:
            hi = math.inf
        if value > 0:
            out.append(max(0.0, min(value, hi) - max(0.0, lo)))
        elif value < 0:
            out.append(0.0 - max(0.0, min(0.0, hi) - max(value, lo)))
        else:
            out.append(0.0)
    return out
