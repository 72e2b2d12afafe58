"""Tables whose skin moves no further than a little more than their own feature point.

A FAP moves its feature point and "its region with it" (ISO/IEC 14496-2; the reference,
section 5). Fitted from sculpted shapes, some regions outran their point: the outer lip
corner's stretch at 300 moved the cheek 26 mm from the corner by 24 mm while the corner
moved 14.9 (1.6 times), the outer corner's raise 1.54 times, the upper lip's push 1.67
times; in a stream that smiles (Greta's joy: both corners raised by 300 and stretched by
150) the cheeks balloon sideways past the jaw.

:func:`bound_tables` caps each vertex's motion in a table, at each interval border, at
:data:`RATIO` times the motion of the table's own point, smoothly: motion up to the
point's is kept, beyond it it saturates, ``m → a + (c − a) tanh((m − a)/(c − a))`` with
``a`` the point's motion and ``c`` the cap, so the field keeps its direction everywhere and
its slope where it joins. Scaling a vector keeps a component that is zero at zero, so the
other FAPs' points stay still along their axes (:mod:`fmc.separate`); the own point's
vertices are not touched. The jaw's tables, whose chin arcs far beyond any point, are left
as authored (:data:`fmc.author.JAW_FAPS`).

Measured on the generic head (``benchmarks/fap_conformance.py``, each FAP the streams use at
its largest value there): the largest skin motion over its point's 1.64 before, 1.29 after;
the other figures of the nine Xface and six Greta streams unchanged at their worst (78
triangles turned over, the longest edge 5.0, 98.5 % of the feature-point frames where the
standard puts them), though five streams turn more triangles over in their worst frame
(Xface's anger 0 to 26, pride 10 to 48: the capped cheek squeezes the skin beside the
corner).
"""

from __future__ import annotations

import numpy as np

from mpeg4.catalogue import FAPS
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable, fap_unit
from mpeg4.head import Head

__all__ = ["RATIO", "bound_motion", "bound_tables"]

#: Largest skin motion of a table over its own point's (the issue's yardstick: a region
#: that outruns its point by more bulges or tears).
RATIO = 1.3


def bound_motion(offsets: np.ndarray, own: float, ratio: float = RATIO, held: np.ndarray | None = None
                 ) -> np.ndarray:
    """``offsets`` (V, 3) with each row longer than ``own`` metres shortened smoothly
    towards ``ratio × own`` (see the module's docstring); rows in ``held`` (bool (V,)) kept.
    A new array."""
    out = np.array(offsets, dtype=np.float64)
    if own <= 0.0:
        return out
    m = np.linalg.norm(out, axis=1)
    over = m > own
    if held is not None:
        over &= ~held
    span = (ratio - 1.0) * own
    out[over] *= ((own + span * np.tanh((m[over] - own) / span)) / m[over])[:, None]
    return out


def bound_tables(head: Head, fat: FAT | None = None, *, ratio: float = RATIO, keep=()) -> FAT:
    """A copy of ``fat`` (default ``head.fat``) whose low-level translation tables move no
    skin vertex more than ``ratio`` times their own feature point, at any value.

    Parameters
    ----------
    head : Head
    fat : FAT, optional
    ratio : float
        See :data:`RATIO`.
    keep : iterable of int
        FAPs whose tables stay as they are (the jaw's).

    Returns
    -------
    FAT
        Tables left as they were share their objects with the input.
    """
    keep = frozenset(keep)
    given = (head.fat if fat is None else fat) or {}
    out = FAT(given)
    n_skin = len(head.skin.vertices)
    for (n, hl), table in given.items():
        if hl or n in keep or not 3 <= n <= 68 or FAPS[n].kind != "translation":
            continue
        binding = head.feature_points.get(FAPS[n].feature_points[0])
        meshes = [m for m in table.meshes if m.part == "skin"]
        if binding is None or binding.part != "skin" or len(meshes) != 1:
            continue
        mesh, unit = meshes[0], fap_unit(n, head.fapu)
        own_rows = np.zeros(n_skin, bool)
        own_rows[list(binding.vertices)] = True
        at = mesh.border_offsets(unit, n_skin)
        bounded = np.stack([bound_motion(o, float(np.linalg.norm(binding.position(o))), ratio, own_rows) for o in at])
        if np.array_equal(bounded, at):
            continue
        new = FaceDefMesh.from_border_offsets("skin", mesh.borders, bounded, unit, mesh.indices)
        out.add(FaceDefTable(table.fap, table.high_level, [new if m is mesh else m for m in table.meshes],
                             list(table.transforms)))
    return out
