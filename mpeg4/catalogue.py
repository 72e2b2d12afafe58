"""The MPEG-4 Face Animation catalogue: feature points, FAPU, FAPs, visemes, expressions.

Everything here is loaded from one table file, ``mpeg4/data/catalogue.toml``, written by
``scripts/catalogue_from_reference.py`` from the project's MPEG-4 reference. Code never
spells out a table of its own: it asks this module.

Frame of the neutral face: +x the face's own left, +y up, +z towards the viewer.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources

import numpy as np

from .errors import InputError

__all__ = [
    "FeaturePoint", "FAPUnitDefinition", "FAP", "Viseme", "Expression",
    "FEATURE_POINTS", "FP_IDS", "FP_GROUP_SIZES", "FAPU_DEFINITIONS", "ANGLE_UNIT",
    "FAPS", "VISEMES", "EXPRESSIONS", "feature_point", "fap", "check_fp_id",
]


@dataclass(frozen=True)
class FeaturePoint:
    """One of the 84 MPEG-4 feature points.

    Attributes
    ----------
    id : str
        ``"group.index"``, e.g. ``"3.5"`` (left pupil).
    group : int
        2..11.
    side : {"L", "R", "C"}
        The face's own left (+x), right (−x) or the midline.
    front, side_view : str
        Visibility on a front photo (``Y`` clear, ``~`` estimated, ``N`` hidden) and on a
        profile photo (``P`` on the silhouette, ``Y``, ``~``, ``N``).
    mirror : str or None
        The left/right partner's id; None on the midline.
    description : str
        Where the point is.
    """

    id: str
    group: int
    side: str
    front: str
    side_view: str
    mirror: str | None
    description: str


@dataclass(frozen=True)
class FAPUnitDefinition:
    """How one FAPU distance is measured on the neutral face: ``first.axis − second.axis``."""

    name: str
    first: str
    second: str
    axis: str
    divisor: int
    description: str


@dataclass(frozen=True)
class FAP:
    """One of the 68 Facial Animation Parameters.

    Attributes
    ----------
    id : int
        1..68. FAPs 1 and 2 are the high-level viseme and expression.
    name : str
        E.g. ``"open_jaw"``.
    unit : str
        ``"MNS"``, ``"MW"``, ``"ES"``, ``"ENS"``, ``"IRISD"``, ``"AU"``; empty for 1–2.
    direction : str
        ``"U"`` unidirectional or ``"B"`` bidirectional; empty for 1–2.
    kind : str
        ``"translation"``, ``"rotation"``, ``"scale"`` (pupil), ``"roll"`` (tongue),
        ``"high_level"``.
    axis : str
        Translations: the signed axis a positive value moves along (``"-y"``).
        Rotations: the right-handed rotation axis of a positive value (``"+y"``).
    positive : str
        The reference's word for a positive value (``"down"``).
    group : int
        FAP group 1..10.
    feature_points : tuple of str
        The FP(s) the FAP moves.
    description : str
    """

    id: int
    name: str
    unit: str
    direction: str
    kind: str
    axis: str
    positive: str
    group: int
    feature_points: tuple[str, ...]
    description: str

    @property
    def axis_vector(self) -> np.ndarray | None:
        """(3,) float64 unit vector for ``axis``, or None when the FAP has no axis."""
        if not self.axis:
            return None
        v = np.zeros(3)
        v["xyz".index(self.axis[1])] = 1.0 if self.axis[0] == "+" else -1.0
        return v


@dataclass(frozen=True)
class Viseme:
    """A viseme of FAP 1 (0 is neutral)."""

    id: int
    name: str
    phonemes: tuple[str, ...]
    examples: str


@dataclass(frozen=True)
class Expression:
    """An expression of FAP 2 (0 is neutral)."""

    id: int
    name: str
    description: str


def _load() -> dict:
    with resources.files("mpeg4").joinpath("data/catalogue.toml").open("rb") as f:
        return tomllib.load(f)


_T = _load()
FEATURE_POINTS: dict[str, FeaturePoint] = {
    r["id"]: FeaturePoint(r["id"], r["group"], r["side"], r["front"], r["side_view"],
                          r["mirror"] or None, r["description"])
    for r in _T["feature_points"]
}
FP_IDS: tuple[str, ...] = tuple(FEATURE_POINTS)
FP_GROUP_SIZES: dict[int, int] = {
    g: sum(1 for fp in FEATURE_POINTS.values() if fp.group == g) for g in range(2, 12)
}
FAPU_DEFINITIONS: dict[str, FAPUnitDefinition] = {r["name"]: FAPUnitDefinition(**r) for r in _T["fapu"]}
ANGLE_UNIT: float = float(_T["angle_unit"])
FAPS: dict[int, FAP] = {
    r["id"]: FAP(r["id"], r["name"], r["unit"], r["direction"], r["kind"], r["axis"], r["positive"],
                 r["group"], tuple(r["feature_points"]), r["description"])
    for r in _T["faps"]
}
VISEMES: dict[int, Viseme] = {r["id"]: Viseme(r["id"], r["name"], tuple(r["phonemes"]), r["examples"])
                              for r in _T["visemes"]}
EXPRESSIONS: dict[int, Expression] = {r["id"]: Expression(**r) for r in _T["expressions"]}
_FAP_BY_NAME = {f.name: f for f in FAPS.values()}
del _T


def check_fp_id(fp_id: str, where: str | None = None) -> str:
    """Return ``fp_id`` if it is one of the 84 MPEG-4 feature points, else raise InputError.

    Parameters
    ----------
    fp_id : str
        E.g. ``"2.1"``.
    where : str, optional
        The file and place the id came from, for the message.
    """
    if not isinstance(fp_id, str) or fp_id not in FEATURE_POINTS:
        hint = "MPEG-4 feature points are 'group.index' with groups 2..11, e.g. '2.1' or '3.5'"
        if isinstance(fp_id, str) and fp_id.startswith(("1.", "12.", "13.", "14.", "15.", "16.", "17.")):
            hint += "; groups 1 and 12+ are not standard points (some vendors add private groups)"
        raise InputError(f"unknown feature point {fp_id!r}", where=where, fix=hint)
    return fp_id


def feature_point(fp_id: str) -> FeaturePoint:
    """The catalogue entry of one feature point; InputError for an unknown id.

    Examples
    --------
    >>> feature_point("3.5").description
    'centre of the left pupil'
    """
    return FEATURE_POINTS[check_fp_id(fp_id)]


def fap(key: int | str) -> FAP:
    """The FAP with this number (1..68) or name; InputError otherwise.

    Examples
    --------
    >>> fap(3).name, fap("open_jaw").unit
    ('open_jaw', 'MNS')
    """
    if isinstance(key, str) and key in _FAP_BY_NAME:
        return _FAP_BY_NAME[key]
    try:
        return FAPS[int(key)]
    except (KeyError, ValueError, TypeError):
        raise InputError(f"unknown FAP {key!r}", fix="FAPs are numbered 1..68 (see mpeg4.FAPS)") from None
