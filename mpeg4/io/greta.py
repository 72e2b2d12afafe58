"""Greta's expression tables: action units as FAP values, expressions as action units.

Greta, an open conversational agent that speaks MPEG-4, keeps its facial expressions in two
XML files in one folder:

- ``aulibrary.xml`` declares each action unit as low-level FAP values,
  ``<actiondeclaration name="AU12"><fap num="12" value="156"/>…``;
- ``facelibrary.xml`` makes each expression from action units at intensities,
  ``<expression instance="joy"><action name="AU6" intensity="0.5" side="LEFT"/>…``.

An expression's FAP values are the sum over its actions of intensity × the unit's values
(intensity 1 when none is given). An action with a ``side`` keeps that side's FAPs (those
whose name says ``l``/``lm`` or ``r``/``rm``: the face's own left and right, as MPEG-4 names them) and the
FAPs of neither side. An action naming a unit the library does not declare moves nothing,
and the expression lists it (Greta's own library has such: its ``disgust`` names AU9,
which its ``aulibrary.xml`` does not declare).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from ..catalogue import FAPS
from .fap import N_FAPS
from ..errors import InputError, require_file

__all__ = ["BASIC_EXPRESSIONS", "GretaExpression", "fap_side", "read_action_units", "read_expressions"]

#: The six basic expressions, as Greta's library names them.
BASIC_EXPRESSIONS = ("anger", "disgust", "fear", "joy", "sadness", "surprise")


@dataclass(frozen=True)
class GretaExpression:
    """One expression of Greta's library.

    Attributes
    ----------
    name : str
    values : dict
        FAP number → value (FAP units), the sum over its action units.
    undeclared : tuple of str
        Action units it names that ``aulibrary.xml`` does not declare (left out).
    """

    name: str
    values: dict
    undeclared: tuple = ()


def fap_side(n: int) -> str | None:
    """``"LEFT"``, ``"RIGHT"`` or None: the side of the face low-level FAP ``n`` moves."""
    tokens = set(FAPS[n].name.split("_"))
    return "LEFT" if tokens & {"l", "lm"} else "RIGHT" if tokens & {"r", "rm"} else None


def _parse(path: str) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as e:
        raise InputError(f"not well-formed XML ({e})", where=path,
                         fix="give Greta's aulibrary.xml and facelibrary.xml as Greta writes them") from None


def _number(text: str | None, where: str, what: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise InputError(f"{what} {text!r} is not a number", where=where) from None
    if value != value or abs(value) == float("inf"):
        raise InputError(f"{what} {text!r} is not a finite number", where=where)
    return value


def read_action_units(path: str | os.PathLike) -> dict[str, dict[int, float]]:
    """Action unit name → {FAP number: value} from Greta's ``aulibrary.xml``."""
    path = require_file(path, "Greta action-unit library")
    units: dict[str, dict[int, float]] = {}
    for decl in _parse(path).iter("actiondeclaration"):
        name = decl.get("name")
        where = f"{path}, action unit {name!r}"
        values: dict[int, float] = {}
        for fap in decl.iter("fap"):
            n = _number(fap.get("num"), where, "FAP number")
            if not n.is_integer() or not 1 <= n <= N_FAPS:
                raise InputError(f"FAP number {fap.get('num')!r} is not one of 1..{N_FAPS}", where=where)
            values[int(n)] = values.get(int(n), 0.0) + _number(fap.get("value"), where, f"the value of FAP {int(n)}")
        units[name] = values
    return units


def read_expressions(folder: str | os.PathLike, names=None) -> dict[str, GretaExpression]:
    """Expression name → :class:`GretaExpression` from Greta's two tables in ``folder``.

    Parameters
    ----------
    folder : path
        Holding ``aulibrary.xml`` and ``facelibrary.xml``.
    names : iterable of str, optional
        The expressions wanted (e.g. :data:`BASIC_EXPRESSIONS`); all of them when None.
        A name the library lacks is an error.
    """
    folder = Path(folder)
    units = read_action_units(folder / "aulibrary.xml")
    library = require_file(folder / "facelibrary.xml", "Greta expression library")
    wanted = None if names is None else list(names)
    out: dict[str, GretaExpression] = {}
    for exp in _parse(library).iter("expression"):
        name = exp.get("instance")
        if wanted is not None and name not in wanted:
            continue
        where = f"{library}, expression {name!r}"
        values: dict[int, float] = {}
        undeclared = []
        for action in exp.iter("action"):
            unit = action.get("name")
            if unit not in units:
                undeclared.append(unit)
                continue
            intensity = _number(action.get("intensity", "1"), where, f"the intensity of {unit}")
            side = action.get("side")
            if side not in (None, "LEFT", "RIGHT"):
                raise InputError(f"side {side!r} of {unit} is neither LEFT nor RIGHT", where=where)
            for n, v in units[unit].items():
                if side is None or fap_side(n) in (None, side):
                    values[n] = values.get(n, 0.0) + intensity * v
        out[name] = GretaExpression(name, values, tuple(undeclared))
    if wanted is not None and (missing := [n for n in wanted if n not in out]):
        raise InputError(f"no expression named {', '.join(map(repr, missing))}", where=library,
                         fix=f"choose among {', '.join(sorted(e.get('instance') for e in _parse(library).iter('expression')))}")
    return out
