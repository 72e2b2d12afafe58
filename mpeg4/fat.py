"""Facial Animation Tables (FATs): how each FAP deforms a head, and morph targets both ways.

A FAT holds, per FAP (and per viseme/expression for the high-level FAPs 1 and 2), a
:class:`FaceDefTable` of

- :class:`FaceDefMesh`: piecewise-linear vertex displacements over FAP-value intervals,
  applied as the integral from 0 to the FAP value of a slope that is constant in each
  interval (reference section 5);
- :class:`FaceDefTransform`: a rotation, translation or scale of a whole part (eyeballs,
  jaw, head) proportional to the FAP value.

**Values beyond the borders.** Outside ``[I0, In]`` the slope of the nearest interval is
extended (no clamping): a FAP value twice the last border moves a vertex twice as far as
the last interval does from its start. A table with no interval on one side of 0 (a
unidirectional FAP's ``[0, I1, …]``) moves nothing for values on that side. This keeps FAP streams authored on other players
(which often exceed a model's borders) expressive, and it is what a linear morph target
does with a weight above 1.

**Units.** Mesh displacements ``D`` are in model units per FAP unit: a vertex moves by
``D · unit · (length of the value range covered in that interval)``, where the unit is the
FAP's FAPU in metres (AU in radians for rotations). High-level tables (FAP 1 visemes,
FAP 2 expressions) take the blend or intensity 0..63 as their value and a unit of 1/63 m,
so a one-interval table ``[0, 63]`` holds in ``D`` the displacement in metres at full
intensity.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .catalogue import FAPS, VISEMES, EXPRESSIONS, fap as fap_entry
from .errors import InputError
from .fapu import FAPU
from .head import SparseDisplacement
from .neck import blend_turn, joint_weights

__all__ = [
    "FaceDefMesh", "FaceDefTransform", "FaceDefTable", "FAT",
    "signed_overlaps", "fap_unit", "apply_fat", "rotation_matrix", "widen_outer_borders",
    "fat_to_morph_targets", "fat_from_morph_targets", "morph_weights", "MorphSpec",
]

#: Unit of high-level FAP values (visemes and expressions, 0..63): full intensity 63 → 1 m·D.
HIGH_LEVEL_UNIT = 1.0 / 63.0


def signed_overlaps(borders: np.ndarray, value: float) -> np.ndarray:
    """Signed length of ``[0, value]`` inside each interval, extending the outer slopes.

    Parameters
    ----------
    borders : (n + 1,) array
        Strictly increasing interval borders ``I0 < … < In`` (FAP units).
    value : float
        The FAP value P.

    Returns
    -------
    (n,) float64
        ``s_k`` such that a vertex moves by ``FAPU · Σ_k D_k s_k``; negative for P < 0.

    Examples
    --------
    The worked example of reference section 5:

    >>> signed_overlaps(np.array([-400, 0, 300, 900]), 500).tolist()
    [0.0, 300.0, 200.0]
    >>> signed_overlaps(np.array([-400, 0, 300, 900]), -100).tolist()
    [-100.0, 0.0, 0.0]
    """
    b = np.asarray(borders, dtype=np.float64)
    lo, hi = b[:-1].copy(), b[1:].copy()
    # Extend the outer slopes beyond the borders, but only on a side of 0 the table
    # defines: a table [0, I1, ...] says nothing about negative values, so they move nothing.
    if lo[0] < 0:
        lo[0] = -np.inf
    if hi[-1] > 0:
        hi[-1] = np.inf
    p = float(value)
    if p > 0:
        return np.maximum(0.0, np.minimum(p, hi) - np.maximum(0.0, lo))
    if p < 0:
        return 0.0 - np.maximum(0.0, np.minimum(0.0, hi) - np.maximum(p, lo))  # no -0.0
    return np.zeros(len(lo))


@dataclass
class FaceDefMesh:
    """Piecewise-linear displacements of some vertices of one part for one FAP.

    Attributes
    ----------
    part : str
    borders : (n + 1,) float64
        Strictly increasing FAP values; 0 must lie in ``[I0, In]``.
    indices : (k,) int64
        Vertices of the part that move.
    displacements : (k, n, 3) float64
        Per listed vertex and interval, the displacement per FAP unit (model units per
        FAPU). In the standard's flat storage this is vertex-major: ``displacements.reshape(-1, 3)``.
    """

    part: str
    borders: np.ndarray
    indices: np.ndarray
    displacements: np.ndarray

    def __post_init__(self):
        self.borders = np.asarray(self.borders, dtype=np.float64).reshape(-1)
        self.indices = np.asarray(self.indices, dtype=np.int64).reshape(-1)
        n = len(self.borders) - 1
        self.displacements = np.asarray(self.displacements, dtype=np.float64).reshape(len(self.indices), n, 3)
        if n < 1 or (np.diff(self.borders) <= 0).any():
            raise InputError(f"interval borders {self.borders.tolist()} are not strictly increasing",
                             where=f"FaceDefMesh of part '{self.part}'", fix="list at least two increasing FAP values")
        if not self.borders[0] <= 0 <= self.borders[-1]:
            raise InputError(f"interval borders {self.borders.tolist()} do not contain 0",
                             where=f"FaceDefMesh of part '{self.part}'", fix="the neutral value 0 must lie in [I0, In]")

    def offsets(self, value: float, unit: float) -> np.ndarray:
        """(k, 3) displacement in metres of the listed vertices for FAP value ``value``."""
        return unit * np.einsum("knc,n->kc", self.displacements, signed_overlaps(self.borders, value))

    def border_offsets(self, unit: float, n_vertices: int) -> np.ndarray:
        """(n + 1, V, 3) displacement in metres of every vertex of the part at each border:
        the motion is linear between them (0 at a border of 0)."""
        dense = np.zeros((n_vertices,) + self.displacements.shape[1:])
        dense[self.indices] = self.displacements
        return unit * np.einsum("vic,bi->bvc", dense, np.array([signed_overlaps(self.borders, x)
                                                                   for x in self.borders]))

    @classmethod
    def from_border_offsets(cls, part: str, borders: np.ndarray, offsets: np.ndarray, unit: float,
                            keep: np.ndarray | None = None, share: float = 1e-4) -> "FaceDefMesh":
        """The mesh table whose :meth:`border_offsets` are ``offsets`` (n + 1, V, 3), listing
        the vertices in ``keep`` and those whose displacement is over ``share`` of the
        largest."""
        b = np.asarray(borders, dtype=np.float64)
        d = np.stack([(offsets[i + 1] - offsets[i]) / (unit * (b[i + 1] - b[i])) for i in range(len(b) - 1)], axis=1)
        size = np.abs(d).max(axis=(1, 2))
        stored = np.flatnonzero(size > share * size.max(initial=0.0))
        if keep is not None:
            stored = np.union1d(np.asarray(keep, dtype=np.int64), stored)
        return cls(part, b, stored, d[stored])


@dataclass
class FaceDefTransform:
    """A rigid (or scaling) motion of a whole part proportional to a FAP value.

    Attributes
    ----------
    part : str or None
        The part that moves; None moves every part (head rotation about 7.1).
    kind : {"rotation", "translation", "scale"}
    centre : (3,) float64
        Rotation/scale centre, metres.
    axis : (3,) float64
        Rotation axis (right-handed), used when kind is "rotation".
    amount : float or (3,) float64
        Rotation: angle multiplier (angle = amount · P · unit radians).
        Translation: (3,) model units per FAP unit (offset = amount · P · unit).
        Scale: (3,) per-axis factor per model unit (scale = 1 + amount · P · unit).
    """

    part: str | None
    kind: str
    centre: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    amount: float | np.ndarray = 1.0

    def __post_init__(self):
        if self.kind not in ("rotation", "translation", "scale"):
            raise InputError(f"unknown FaceDefTransform kind {self.kind!r}", fix="use rotation, translation or scale")
        self.centre = np.asarray(self.centre, dtype=np.float64).reshape(3)
        self.axis = np.asarray(self.axis, dtype=np.float64).reshape(3)
        if self.kind == "rotation":
            norm = np.linalg.norm(self.axis)
            if norm == 0:
                raise InputError("rotation axis is zero", where=f"FaceDefTransform of part '{self.part}'")
            self.axis = self.axis / norm
            self.amount = float(self.amount)
        else:
            self.amount = np.broadcast_to(np.asarray(self.amount, dtype=np.float64), (3,)).copy()

    def affine(self, value: float, unit: float) -> tuple[np.ndarray, np.ndarray]:
        """The motion at FAP value ``value`` as ``x → A x + b``: (3, 3) A and (3,) b, metres."""
        if self.kind == "rotation":
            a = rotation_matrix(self.axis, self.amount * value * unit)
        elif self.kind == "translation":
            return np.eye(3), self.amount * value * unit
        else:
            a = np.diag(1.0 + self.amount * value * unit)
        return a, self.centre - a @ self.centre

    def apply(self, vertices: np.ndarray, value: float, unit: float) -> np.ndarray:
        """Moved copy of (N, 3) ``vertices`` for FAP value ``value``."""
        a, b = self.affine(value, unit)
        return vertices @ a.T + b


@dataclass
class FaceDefTable:
    """Everything one FAP (or one viseme/expression) does to the head."""

    fap: int
    high_level: int = 0
    meshes: list[FaceDefMesh] = field(default_factory=list)
    transforms: list[FaceDefTransform] = field(default_factory=list)

    def __post_init__(self):
        fap_entry(self.fap)  # validates the number
        if self.fap == 1 and self.high_level not in VISEMES or self.fap == 2 and self.high_level not in EXPRESSIONS:
            raise InputError(f"FAP {self.fap} table selects {self.high_level}, which is not a "
                             f"{'viseme (0..14)' if self.fap == 1 else 'expression (0..6)'}")
        if self.fap > 2 and self.high_level:
            raise InputError(f"FAP {self.fap} is low-level; high_level must be 0")

    @property
    def key(self) -> tuple[int, int]:
        return (self.fap, self.high_level)

    @property
    def name(self) -> str:
        if self.fap == 1:
            return f"viseme_{self.high_level}_{VISEMES[self.high_level].name}"
        if self.fap == 2:
            return f"expression_{EXPRESSIONS[self.high_level].name}"
        return FAPS[self.fap].name


class FAT(dict):
    """Facial Animation Tables: ``(fap, high_level)`` → :class:`FaceDefTable`.

    Low-level FAPs use ``high_level = 0``; ``FAT.add`` fills the key in.
    """

    def add(self, table: FaceDefTable) -> FaceDefTable:
        self[table.key] = table
        return table

    def tables(self) -> list[FaceDefTable]:
        """Tables in FAP order (visemes and expressions first, as FAP 1 and 2)."""
        return [self[k] for k in sorted(self)]


def fap_unit(fap: int, fapu: FAPU) -> float:
    """Size of one unit of ``fap``: FAPU metres, AU radians, or 1/63 m for FAPs 1–2."""
    return HIGH_LEVEL_UNIT if fap in (1, 2) else fapu.of_fap(fap)


def rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) right-handed rotation by ``angle`` radians about the unit vector ``axis``."""
    x, y, z = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    c, s = np.cos(angle), np.sin(angle)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def _key(k) -> tuple[int, int]:
    return (int(k[0]), int(k[1])) if isinstance(k, tuple) else (int(k), 0)


def apply_fat(fat: FAT, vertices: Mapping[str, np.ndarray], values: Mapping, fapu: FAPU,
              neck_fade: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Deform a head's parts by a set of FAP values (reference section 5).

    Mesh displacements of all active tables add up (superposition) on the neutral
    vertices; then the transforms are applied, part-specific ones in FAP order and the
    whole-head ones (part None, the head rotations about 7.1) last, composed into one
    motion that each vertex follows by its share ``neck_fade`` (:func:`mpeg4.neck.blend_turn`:
    the shoulders stay, the head turns fully).

    Parameters
    ----------
    fat : FAT
    vertices : mapping of str to (N, 3) array
        Neutral vertices per part, metres.
    values : mapping
        FAP number (3..68) → value in FAPU, or ``(1, viseme)`` / ``(2, expression)`` →
        value 0..63. Values of FAPs without a table are ignored.
    fapu : FAPU
        The head's FAPU.
    neck_fade : mapping of str to (N,) array, optional
        Per part, each neutral vertex's share of the head turn in [0, 1]
        (``mpeg4.neck.neck_fade(head).fade``); parts not given, or all of them when None,
        turn rigidly with the head (the standard's whole-face rotation).

    Returns
    -------
    dict of str to (N, 3) float64
        Deformed vertices per part (new arrays).
    """
    out = {name: np.array(v, dtype=np.float64, copy=True) for name, v in vertices.items()}
    active = []
    for k, value in values.items():
        key = _key(k)
        if key in fat and value:
            active.append((fat[key], float(value)))
    active.sort(key=lambda tv: tv[0].key)
    for table, value in active:
        unit = fap_unit(table.fap, fapu)
        for m in table.meshes:
            if m.part in out:
                out[m.part][m.indices] += m.offsets(value, unit)
    late = []
    for table, value in active:
        unit = fap_unit(table.fap, fapu)
        for t in table.transforms:
            if t.part is None:
                late.append((t, value, unit))
            elif t.part in out:
                out[t.part] = t.apply(out[t.part], value, unit)
    if late:
        a, b = np.eye(3), np.zeros(3)
        for t, value, unit in late:  # composed in FAP order: one motion of the head
            ta, tb = t.affine(value, unit)
            a, b = ta @ a, ta @ b + tb
        pivot = next((t.centre for t, _, _ in late if t.kind == "rotation"), late[0][0].centre)
        for name in out:
            fade = None if neck_fade is None else neck_fade.get(name)
            if fade is None:
                out[name] = out[name] @ a.T + b
            else:
                out[name] = blend_turn(out[name], joint_weights(fade), a, b, pivot)
    return out


def widen_outer_borders(fat: FAT, extents: Mapping) -> FAT:
    """A copy of ``fat`` whose tables' outer interval borders reach the values given.

    The outer intervals extrapolate linearly (reference section 5), so the deformation is
    the same for every value; what changes is the morph target made from an outer interval
    (:func:`fat_to_morph_targets`): it holds the displacement at the wider border, so the
    weights an animation needs stay within [0, 1] (Blender clamps shape-key values above
    1, three.js plays them as stored).

    Parameters
    ----------
    fat : FAT
    extents : mapping
        Table key ``(fap, high_level)`` → (smallest, largest) value to cover.
    """
    out = FAT()
    for key, table in fat.items():
        lo, hi = extents.get(key, (0.0, 0.0))
        meshes = []
        for m in table.meshes:
            b = m.borders.copy()
            if b[-1] > 0 and hi > b[-1]:
                b[-1] = hi
            if b[0] < 0 and lo < b[0]:
                b[0] = lo
            meshes.append(FaceDefMesh(m.part, b, m.indices, m.displacements))
        out.add(FaceDefTable(table.fap, table.high_level, meshes, list(table.transforms)))
    return out


# --- FAT <-> morph targets ---------------------------------------------------------

@dataclass(frozen=True)
class MorphSpec:
    """How one morph target stands for one interval of one FAP table.

    A target made from the one-sided interval ``[lo, hi]`` (both ≥ 0 or both ≤ 0) holds the
    displacement reached at the far end from 0; its weight for a FAP value P is the
    fraction of the interval covered by ``[0, P]``, unbounded beyond the outer borders.
    """

    target: str
    fap: int
    high_level: int
    lo: float
    hi: float
    outermost: bool

    def weight(self, value: float) -> float:
        """Weight of this target for FAP value ``value``."""
        length = self.hi - self.lo
        if self.hi <= 0:  # negative side: 0 at hi, 1 at lo
            if value >= 0:
                return 0.0
            w = (self.hi - value) / length
        else:
            if value <= 0:
                return 0.0
            w = (value - self.lo) / length
        return float(max(0.0, w if self.outermost else min(1.0, w)))

    @property
    def reach(self) -> float:
        """Signed FAP-value length from the near end to the far end (negative below 0)."""
        return self.lo - self.hi if self.hi <= 0 else self.hi - self.lo

    def as_dict(self) -> dict:
        return dict(target=self.target, fap=self.fap, high_level=self.high_level, lo=self.lo, hi=self.hi,
                    outermost=self.outermost)


def _one_sided(borders: np.ndarray) -> list[tuple[int, float, float, bool]]:
    """Intervals split at 0: (source interval index, lo, hi, outermost)."""
    out = []
    n = len(borders) - 1
    for k in range(n):
        lo, hi = float(borders[k]), float(borders[k + 1])
        pieces = [(lo, 0.0), (0.0, hi)] if lo < 0 < hi else [(lo, hi)]
        for a, b in pieces:
            outer = (k == 0 and a == lo and a < 0) or (k == n - 1 and b == hi and b > 0)
            out.append((k, a, b, outer))
    return out


def _target_name(table: FaceDefTable, lo: float, hi: float, n_same_side: int) -> str:
    base = table.name
    if n_same_side == 1:
        return base if hi > 0 else base + "-"
    return f"{base}[{lo:g},{hi:g}]"


def fat_to_morph_targets(fat: FAT, fapu: FAPU) -> tuple[dict[str, dict[str, SparseDisplacement]], list[MorphSpec]]:
    """Express the mesh part of a FAT as morph targets (one per one-sided interval).

    Transforms are not morph targets (rotations are not linear in the FAP value); they
    stay in the FAT and travel beside the targets.

    Returns
    -------
    targets : dict
        Target name → part → :class:`SparseDisplacement` at weight 1 (metres).
    specs : list of MorphSpec
        How each target's weight follows its FAP value (see :func:`morph_weights`).
    """
    targets: dict[str, dict[str, SparseDisplacement]] = {}
    specs: dict[str, MorphSpec] = {}
    for table in fat.tables():
        unit = fap_unit(table.fap, fapu)
        pieces = {}
        for m in table.meshes:
            for k, lo, hi, outer in _one_sided(m.borders):
                pieces.setdefault((lo, hi), []).append((m, k, outer))
        pos = sum(1 for lo, hi in pieces if hi > 0)
        neg = len(pieces) - pos
        for (lo, hi), uses in sorted(pieces.items()):
            name = _target_name(table, lo, hi, pos if hi > 0 else neg)
            spec = MorphSpec(name, table.fap, table.high_level, lo, hi, outermost=all(u[2] for u in uses))
            target = targets.setdefault(name, {})
            for m, k, _ in uses:
                d = SparseDisplacement(m.indices, m.displacements[:, k, :] * unit * spec.reach)
                # Two meshes of one table on the same part add up.
                target[m.part] = target[m.part] + d if m.part in target else d
            specs[name] = spec
    return targets, list(specs.values())


def morph_weights(specs: list[MorphSpec], values: Mapping) -> dict[str, float]:
    """Morph-target weights that reproduce the FAT's mesh deformation for ``values``."""
    vals = {_key(k): float(v) for k, v in values.items()}
    return {s.target: s.weight(vals.get((s.fap, s.high_level), 0.0)) for s in specs}


def fat_from_morph_targets(targets: Mapping[str, Mapping[str, SparseDisplacement]], specs: list[MorphSpec],
                           fapu: FAPU, transforms: FAT | None = None) -> FAT:
    """Rebuild FaceDefMeshes from morph targets made by :func:`fat_to_morph_targets`.

    Parameters
    ----------
    targets : mapping
        Target name → part → displacement at weight 1.
    specs : list of MorphSpec
        The interval each target stands for.
    fapu : FAPU
    transforms : FAT, optional
        Tables whose transforms are copied into the result (morph targets carry none).

    Returns
    -------
    FAT
        One FaceDefMesh per (table, part), its borders the union of the targets'
        intervals; vertices a target does not move get a zero slope there.
    """
    fat = FAT()
    by_table: dict[tuple[int, int], list[MorphSpec]] = {}
    for s in specs:
        if s.target not in targets:
            raise InputError(f"morph target '{s.target}' is named in the FAT description but missing",
                             fix="keep the targets and their extras together when editing the file")
        by_table.setdefault((s.fap, s.high_level), []).append(s)
    for key in sorted(by_table):
        group = sorted(by_table[key], key=lambda s: s.lo)
        borders = [group[0].lo] + [s.hi for s in group]
        for a, b in zip(group, group[1:]):
            if a.hi != b.lo:
                raise InputError(f"FAP {key[0]} morph targets '{a.target}' and '{b.target}' leave a gap "
                                 f"between {a.hi:g} and {b.lo:g}", fix="targets of one FAP must cover adjacent intervals")
        table = FaceDefTable(key[0], key[1])
        unit = fap_unit(key[0], fapu)
        parts = sorted({p for s in group for p in targets[s.target]})
        for part in parts:
            idx = np.unique(np.concatenate([targets[s.target][part].indices for s in group
                                            if part in targets[s.target]]))
            disp = np.zeros((len(idx), len(group), 3))
            for k, s in enumerate(group):
                d = targets[s.target].get(part)
                if d is not None:
                    disp[np.searchsorted(idx, d.indices), k] = d.vectors / (unit * s.reach)
            table.meshes.append(FaceDefMesh(part, np.array(borders), idx, disp))
        if transforms is not None and key in transforms:
            table.transforms = list(transforms[key].transforms)
        fat.add(table)
    if transforms is not None:
        for key, t in transforms.items():
            if key not in fat and t.transforms:
                fat.add(FaceDefTable(t.fap, t.high_level, [], list(t.transforms)))
    return fat
