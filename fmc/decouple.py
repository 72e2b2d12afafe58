"""Lip FAP values as the tables must play them: the lips' own motion, not the jaw's.

``open_jaw`` moves the jaw, "not the lips themselves" (the reference, section 3): a lip FAP
moves its point by value × FAPU from where the neutral face has it, whatever the jaw does.
A head's jaw table carries the lower lip down with the chin (the sculpted jaw opening, the
muscle model's jaw), so a stream that opens the jaw by 713 and lowers the lower lip by 866
(Xface's ``fear.fap``) played as given moved the lip by both, about 1,500 units, and tore
the mouth.

:class:`Decoupler` takes out of each lip FAP's value what the jaw FAPs (3, 14, 15) of the
frame already do to its point along its axis, so the jaw and the lip FAPs together move
the point by its own value. The jaw tables are piecewise linear in their values and the
lip tables do not move the chin, so this is exact and needs no iteration. Only the lip
FAPs a frame sets are so corrected: a stream that never sets them (one that opens the
mouth with ``open_jaw`` alone, as many players write) keeps its lips on the jaw, where a
literal reading (unset = 0) would keep the mouth shut while the chin drops. The other
FAPs' tables leave these points alone (:mod:`fmc.separate`), so nothing else needs taking
out (solving a frame's values for all the points at once, with tables that moved each
other's points, was ill-conditioned: neighbouring points asked for opposed values). The
chin boss (2.10) rides on the jaw too but is left there: taking the jaw's carry out of
``depress_chin`` as well put 1 % more of the points where the standard says and turned
over two to four times as many triangles in the Xface streams (their chin is raised by
300 while the jaw opens; measured when 2.10 sat on the lower lip's underside, before it
moved to the chin's most prominent point).

The jaw's own FAPs share one point, the chin (2.1), each along its axis: ``open_jaw`` down,
``thrust_jaw`` forward, ``shift_jaw`` sideways. A jaw that opens by turning (the sculpted
jaw, the muscle model's) also draws the chin back, and a thrust lowers it a little, so a
frame that opens and thrusts the jaw put the chin 6 mm behind where the thrust says (jaw
400, thrust 100). When a frame sets two or three of them, each loses what the others do to
the chin along its axis: a small linear system (the couplings are a fraction of each table's
own motion), solved by Gauss–Seidel sweeps, before the lips' correction, which then sees the
jaw as it will be played. A frame that sets one keeps that one's side motions (an opening's
natural draw), which no FAP of the frame says otherwise about.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FAPS
from mpeg4.fat import fap_unit, signed_overlaps
from mpeg4.head import Head

from .author import JAW_FAPS

__all__ = ["LIP_FAPS", "table_effect", "effect_of", "Decoupler"]


#: The lip FAPs whose points the jaw carries: inner and outer lip contours, lips' depth.
LIP_FAPS = tuple(range(4, 14)) + (16, 17) + tuple(range(51, 61))


def table_effect(head: Head, table, points) -> list[tuple[np.ndarray, np.ndarray]]:
    """How one table moves some points: per mesh, its borders and a (P, n) array of each
    point's motion along its direction per FAP unit of overlap of each interval (metres).

    Parameters
    ----------
    head : Head
    table : mpeg4.fat.FaceDefTable
    points : sequence of (FeaturePointBinding, (3,) direction)
    """
    unit = fap_unit(table.fap, head.fapu)
    blocks = []
    for m in table.meshes:
        effect = np.zeros((len(points), len(m.borders) - 1))
        for r, (binding, direction) in enumerate(points):
            if binding.part != m.part or not len(m.indices):
                continue
            pos = np.minimum(np.searchsorted(m.indices, binding.vertices), len(m.indices) - 1)
            hit = m.indices[pos] == np.asarray(binding.vertices)
            if hit.any():
                effect[r] = np.asarray(binding.weights)[hit] @ (m.displacements[pos[hit]] @ direction) * unit
        blocks.append((np.asarray(m.borders, dtype=np.float64), effect))
    return blocks


def effect_of(effects: Mapping, values: Mapping, n_points: int) -> np.ndarray:
    """(P,) motion of the points at the frame's values of the tables in ``effects``
    (key → :func:`table_effect`)."""
    out = np.zeros(n_points)
    for key, blocks in effects.items():
        v = float(values.get(key, 0.0) or 0.0)
        if v:
            for borders, effect in blocks:
                out += effect @ signed_overlaps(borders, v)
    return out


_SWEEPS = 20  # Gauss-Seidel sweeps at most for the jaw's values (they settle in a few)


class Decoupler:
    """Jaw FAP values without each other's side motions at the chin, lip FAP values without
    the jaw's carry (see the module's docstring).

    Parameters
    ----------
    head : Head
        With ``head.fat`` and the lip points.
    """

    def __init__(self, head: Head):
        fat = head.fat if head.fat is not None else {}
        self.faps = [n for n in LIP_FAPS if (n, 0) in fat and FAPS[n].feature_points[0] in head.feature_points]
        self.units = np.array([fap_unit(n, head.fapu) for n in self.faps])
        # Per jaw FAP: its meshes' borders and the motion of each lip point along its FAP's
        # axis per FAP unit of overlap of each interval (metres).
        points = [(head.feature_points[FAPS[n].feature_points[0]], FAPS[n].axis_vector) for n in self.faps]
        self._jaw = {j: table_effect(head, fat[(j, 0)], points) for j in JAW_FAPS if (j, 0) in fat and self.faps}
        # Per jaw FAP: how it moves the chin along each jaw FAP's axis.
        self.jaw_faps = [n for n in JAW_FAPS if (n, 0) in fat and FAPS[n].feature_points[0] in head.feature_points]
        self.jaw_units = np.array([fap_unit(n, head.fapu) for n in self.jaw_faps])
        chin = [(head.feature_points[FAPS[n].feature_points[0]], FAPS[n].axis_vector) for n in self.jaw_faps]
        self._chin = {n: table_effect(head, fat[(n, 0)], chin) for n in self.jaw_faps}

    def _jaw_values(self, values: Mapping) -> dict:
        """A copy of ``values`` with the jaw FAPs it sets (two or more) each less what the
        others do to the chin along its axis."""
        out = dict(values)
        given = {n: float(values[n]) for n in self.jaw_faps if values.get(n)}
        if len(given) < 2:
            return out
        v = dict(given)
        rows = {n: k for k, n in enumerate(self.jaw_faps)}
        for _ in range(_SWEEPS):
            change = 0.0
            for n in given:
                k = rows[n]
                others = sum(effect_of({m: self._chin[m]}, {m: v[m]}, len(self.jaw_faps))[k] for m in v if m != n)
                new = given[n] - others / self.jaw_units[k]
                change, v[n] = max(change, abs(new - v[n])), new
            if change < 1e-3:  # FAP units
                break
        out.update(v)
        return out

    def carry(self, values: Mapping) -> np.ndarray:
        """(K,) motion, metres, of each lip FAP's point along its axis that the frame's jaw
        FAPs make (K = len(:attr:`faps`))."""
        return effect_of(self._jaw, values, len(self.faps))

    def __call__(self, values: Mapping) -> dict:
        """A copy of one frame's values with the jaw FAPs it sets each less what the others
        do to the chin, and each lip FAP it sets less the jaw's carry."""
        out = self._jaw_values(values)
        if not self._jaw or not any(out.get(j) for j in self._jaw):
            return out
        for n, c, unit in zip(self.faps, self.carry(out), self.units):
            if c and n in values:
                out[n] = float(values[n] or 0.0) - c / unit
        return out
