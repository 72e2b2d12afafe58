"""Cloned tables whose own feature point moves by value × FAPU on the target.

A FAP moves its feature point by its value times its FAPU along its axis (ISO/IEC 14496-2;
the reference, section 3). Cloning scales each table by the ratio of the two heads' units
at the point (:func:`fmc.clone.cloning._unit_correction`), but what reaches the target's
point is the source's motion where the correspondence puts that point, and on a coarse
or differently drawn mesh that is beside the source's point: cloned onto MakeHuman, the
lip corners' raise moved its point 7.2 to 9.0 mm where the FAPU asked 9.6, and half of the
low-level FAPs missed by more than 5 %.

:func:`calibrate_tables` measures, per table and interval, how far the target's own point
moves along the FAP's axis and scales that interval's motion so that it moves exactly as
far, when the needed factor lies within :data:`LIMITS`. A lip FAP played alone brings its
other contour's partner at the same value (:func:`mpeg4.io.fap.fill_lip_contours`), so
what the partner's table moves the point is counted in: scaled alone, the lower lip's
inner FAPs moved MakeHuman's 2.8 and 2.9 10 % too far with the outer ones' share. A factor beyond them means the
point sits in another motion than its own (the correspondence put it elsewhere): scaling
the whole region by that much stretched the MediaPipe mask's skin to 18.7 times its edge
lengths with limits of 0.5 to 2; those tables are left as cloned and reported.

Measured with ``benchmarks/foreign_heads.py`` (each low-level FAP alone at ±512, its point
within 5 % of value × FAPU): MakeHuman 46 % before, 70 % after; the MediaPipe mask 28 % and
53 %, its longest stretched edge 5.3 and 5.7 times its length; the example's head, cloned
from the generic head it was built from, unchanged (98.0 % of the real streams' feature
point frames where the standard puts them, before and after). Measured since as the
tables are (no limits; +512 only for unidirectional FAPs; no eyeball FAPs on a head
without eyeballs): MakeHuman 83.3 %, the mask 65.6 %; with the lip partners counted in,
96.9 % and 72.9 %. Most of what was left came before this step: a point bound inside a
coarse triangle took its vertices' motion, some millimetres from the source's point. With
those vertices shifted so that the point moves as the source's
(:func:`fmc.clone.skin.shift_bound_points`): MakeHuman 100 %, the mask 97.9 % (left: the
right ear's raise, 0.58 of value × FAPU: the mask has no ears, and the marking puts 10.2
and 10.10 on one vertex of its rim, which takes 10.10's motion).
"""

from __future__ import annotations

import numpy as np

from mpeg4.catalogue import FAPS
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable
from mpeg4.head import Head
from mpeg4.io.fap import LIP_CONTOUR_PAIRS

__all__ = ["LIMITS", "calibrate_tables"]

#: Smallest and largest factor a table's interval is scaled by.
LIMITS = (0.8, 1.25)


def calibrate_tables(head: Head, fat: FAT | None = None, limits: tuple[float, float] = LIMITS
                     ) -> tuple[FAT, dict[int, float]]:
    """A copy of ``fat`` (default ``head.fat``) whose low-level translation tables move
    their own feature point by value × FAPU along the FAP's axis.

    Tables with transforms (the point's motion is not theirs alone), without a mesh on the
    point's part, or for a point the head lacks, are left as they are.

    Parameters
    ----------
    head : Head
    fat : FAT, optional
    limits : (float, float)
        See :data:`LIMITS`.

    Returns
    -------
    fat : FAT
        Tables left as they were share their objects with the input.
    off : dict
        FAP → the factor its worst interval would have needed, for the tables left as they
        were because it lies beyond ``limits``.
    """
    given = (head.fat if fat is None else fat) or {}
    out, off = FAT(given), {}
    dense = {}
    for (n, hl), table in given.items():
        if hl or not 3 <= n <= 68 or FAPS[n].kind != "translation" or table.transforms:
            continue
        binding = head.feature_points.get(FAPS[n].feature_points[0])
        meshes = [m for m in table.meshes if binding is not None and m.part == binding.part]
        if len(meshes) != 1:
            continue
        d = np.zeros((len(head.parts[binding.part].vertices),) + meshes[0].displacements.shape[1:])
        d[meshes[0].indices] = meshes[0].displacements
        dense[n] = (table, meshes[0], d, binding)
    partner = {**LIP_CONTOUR_PAIRS, **{o: i for i, o in LIP_CONTOUR_PAIRS.items()}}
    # Per table and interval, its point's motion along the FAP's axis per FAP unit (in units
    # of the FAP's unit) by its own table, and by its lip partner's: a lip FAP played alone
    # brings its other contour's partner with it at the same value
    # (mpeg4.io.fap.fill_lip_contours), so the point moves by both tables.
    along, lent = {}, {}
    for n, (table, mesh, d, binding) in dense.items():
        axis = np.asarray(FAPS[n].axis_vector, dtype=np.float64)
        along[n] = binding.position(d) @ axis
        lent[n] = np.zeros(len(along[n]))
        if partner.get(n) in dense:
            _, other_mesh, other_d, other_binding = dense[partner[n]]
            if np.array_equal(other_mesh.borders, mesh.borders) and other_binding.part == binding.part:
                lent[n] = binding.position(other_d) @ axis
    factors = {}
    for n in dense:
        factor = np.ones(len(along[n]))
        for i, (a, b) in enumerate(zip(along[n], lent[n])):
            if a == 0.0:  # this interval moves nothing (a unidirectional FAP's other side)
                continue
            need = _joint_factor(n, partner.get(n), i, along, lent, limits)
            need = (1.0 - b) / a if need is None else need
            if limits[0] <= need <= limits[1]:
                factor[i] = need
            elif n not in off or _farther(need, off[n]):
                off[n] = need
        factors[n] = factor
    for n, factor in factors.items():
        if np.all(factor == 1.0):
            continue
        table, mesh = dense[n][:2]
        scaled = [FaceDefMesh(m.part, m.borders, m.indices, m.displacements * factor[None, :, None])
                  if np.array_equal(m.borders, mesh.borders) else m for m in table.meshes]
        out.add(FaceDefTable(table.fap, table.high_level, scaled, []))
    return out, off


def _farther(a: float, b: float) -> bool:
    """Factor ``a`` is further from 1 than ``b`` (a negative one, the point moving the wrong
    way, furthest of all)."""
    def score(x):
        return np.inf if x <= 0 else abs(np.log(x))
    return score(a) > score(b)


def _joint_factor(n: int, m: int | None, i: int, along: dict, lent: dict, limits) -> float | None:
    """Table ``n``'s factor for interval ``i`` scaled together with its lip partner ``m``:
    the 2×2 solve that moves both points by exactly one unit each, when both factors lie
    within ``limits``; None when there is no partner sharing the interval or the solve
    falls outside (then each table is scaled with its partner's motion as it is)."""
    if m is None or m not in along or len(along[m]) != len(along[n]) or along[m][i] == 0.0 \
            or not (lent[n][i] or lent[m][i]):
        return None
    a = np.array([[along[n][i], lent[n][i]], [lent[m][i], along[m][i]]])
    if abs(np.linalg.det(a)) < 1e-9 * abs(a).max() ** 2:
        return None
    s_n, s_m = np.linalg.solve(a, np.ones(2))
    if limits[0] <= s_n <= limits[1] and limits[0] <= s_m <= limits[1]:
        return float(s_n)
    return None
