"""The cheek puffs (FAPs 39 and 40): the cheek swells out, or is drawn in, around its point.

``puff_l_cheek`` / ``puff_r_cheek`` move the soft cheek's point 5.1 / 5.2 horizontally,
outwards for positive values, by value × ES (the reference, section 3). The generic head's
sculpted ``cheekPuff`` shapes cannot give that: they swell the cheek mostly forwards (at
weight 1 they move 5.1 by 2.3 mm in x and 10 mm in z) and their largest motion is at the
lip corner, not the cheek. A combination of shapes that does move 5.1 by 512 × ES
(33.6 mm) in x had to overdrive the mouth's shapes tenfold (frown, press, lower-lip down)
and moved the skin beside the lip corner 83 mm; the leak check let it through because 5.1
belongs to the mouth's region, and the separation (:mod:`fmc.separate`) only holds the
lip corner along the axes its FAPs govern, not in depth. No non-negative combination draws
the cheek in, so the inward half fell back to a bump of radius 0.3 ES0 (20 mm) carrying
33.6 mm, which folds.

Here the puff is one smooth field along the FAP's own axis: the point's bi-harmonic hat
among the feature points (:func:`fmc.separate.correction_basis`: 1 at the cheek point, 0
at every other FAP's point, smooth in between), so the table moves no other FAP's point
and nothing moves further than the cheek point itself. A field of amplitude ``A`` folds
the skin where it falls faster than ``1 / A`` along the surface; a smooth hat falls by
about 1.5 / R at its steepest, so its reach is at least 1.5 A (:data:`REACH_PER_MOTION`;
with the separation's 35 mm alone two triangles beside 5.1 turned over at +512).
Inwards the lip corner bounds it: the corner's x is held by ``stretch_cornerlip_o``, and
once the cheek point passes it (about −200 on the generic head) the skin between must
turn over, whatever the field.
"""

from __future__ import annotations

import numpy as np

from mpeg4.catalogue import FAPS
from mpeg4.head import Head, SparseDisplacement

from .separate import REACH, correction_basis

__all__ = ["PUFF_FAPS", "REACH_PER_MOTION", "governed_points", "puff_field"]

#: The cheek puffs.
PUFF_FAPS = (39, 40)

#: The hat's reach over the largest motion it carries: wide enough not to fold.
REACH_PER_MOTION = 1.5


def governed_points(head: Head) -> list[str]:
    """The skin feature points some translation FAP moves (sorted): those every other
    FAP's table must leave where they are."""
    out = set()
    for n in range(3, 69):
        fp = FAPS[n].feature_points[0]
        b = head.feature_points.get(fp)
        if FAPS[n].kind == "translation" and b is not None and b.part == "skin":
            out.add(fp)
    return sorted(out)


def puff_field(head: Head, fp_id: str, goal: np.ndarray) -> dict[str, SparseDisplacement]:
    """The skin displacement of a cheek puff whose point ``fp_id`` moves by ``goal``.

    Parameters
    ----------
    head : Head
        With the feature points the FAPs use on its skin.
    fp_id : str
        The cheek point (5.1 or 5.2).
    goal : (3,) float
        The point's motion at the table's value, metres (value × ES along the FAP's axis).

    Returns
    -------
    dict
        ``{"skin": SparseDisplacement}``: ``goal`` times the point's hat, which is 1 at the
        point, 0 at every other governed point and beyond ``max(REACH, 1.5 |goal|)`` of
        them all.
    """
    goal = np.asarray(goal, dtype=np.float64)
    points = governed_points(head)
    reach = max(REACH, REACH_PER_MOTION * float(np.linalg.norm(goal)))
    hat = correction_basis(head, points, reach)[:, points.index(fp_id)]
    # The hat is 1 at the point's own vertices, so the point moves by ``goal`` exactly; motions
    # under 10 µm at the table's value are dropped, as in fmc.mesh_tables.combine_shapes.
    return {"skin": SparseDisplacement.from_dense(np.outer(hat, goal), tol=1e-5)}
