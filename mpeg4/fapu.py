"""FAP units (FAPU): the face's own distances that FAP values are measured in.

Each displacement FAP value is a multiple of a FAPU, 1/1024 of a distance on the neutral
face (``mpeg4/data/catalogue.toml``, reference section 2); rotation FAPs use the fixed
angle unit AU = 1e-5 rad.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, asdict

import numpy as np

from .catalogue import ANGLE_UNIT, FAPU_DEFINITIONS, fap
from .errors import InputError

__all__ = ["FAPU", "fapu_from_points"]


@dataclass(frozen=True)
class FAPU:
    """The five FAPU distances of one neutral face, in metres.

    Attributes
    ----------
    IRISD0, ES0, ENS0, MNS0, MW0 : float
        Iris diameter, eye separation, eye–nose separation, mouth–nose separation and
        mouth width (metres). The FAP units are these divided by 1024.
    """

    IRISD0: float
    ES0: float
    ENS0: float
    MNS0: float
    MW0: float

    def unit(self, name: str) -> float:
        """Size of one FAP unit: metres for ``IRISD``/``ES``/``ENS``/``MNS``/``MW``, radians for ``AU``.

        Examples
        --------
        >>> FAPU(0.011, 0.064, 0.042, 0.016, 0.05).unit("MW") * 1024
        0.05
        """
        if name == "AU":
            return ANGLE_UNIT
        key = name + "0"
        if key not in FAPU_DEFINITIONS:
            raise InputError(f"unknown FAP unit {name!r}", fix="use IRISD, ES, ENS, MNS, MW or AU")
        return getattr(self, key) / FAPU_DEFINITIONS[key].divisor

    def of_fap(self, fap_id: int) -> float:
        """Size of one unit of FAP ``fap_id`` (metres, or radians for AU FAPs)."""
        unit = fap(fap_id).unit
        if not unit:
            raise InputError(f"FAP {fap_id} is high-level and has no unit", fix="use FAPs 3..68")
        return self.unit(unit)

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def fapu_from_points(points: Mapping[str, np.ndarray], where: str | None = None) -> FAPU:
    """Measure the FAPU on a neutral face from its feature points (reference section 2).

    Parameters
    ----------
    points : mapping of str to (3,) array
        FP id → position in metres, neutral frame (+x face's left, +y up).
    where : str, optional
        Where the points came from, for error messages.

    Returns
    -------
    FAPU

    Raises
    ------
    InputError
        If a point a FAPU needs is missing, or a distance is not positive (a swapped
        left/right pair or a mirrored model).
    """
    values = {}
    for name, d in FAPU_DEFINITIONS.items():
        for fp_id in (d.first, d.second):
            if fp_id not in points:
                raise InputError(f"feature point {fp_id} is missing; it is needed to measure {name}",
                                 where=where, fix=f"place {fp_id} ({d.description})")
        k = "xyz".index(d.axis)
        value = float(np.asarray(points[d.first], float)[k] - np.asarray(points[d.second], float)[k])
        if not value > 0:
            raise InputError(
                f"{name} = {d.first}.{d.axis} - {d.second}.{d.axis} = {value:.4g} is not positive",
                where=where,
                fix="check that left and right points are not swapped and the model is y-up with "
                    "+x on the face's own left")
        values[name] = value
    return FAPU(**values)
