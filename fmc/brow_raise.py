"""The brow raisers 31-36 from the sculpted whole-brow raise.

The shapes raise each brow whole; FAPs 31-36 move one of three points per brow. The summed
raise is cut into six pieces by a smooth partition of unity across the brows
(:func:`brow_partition`), one per FAP (:func:`_brow_piece`), which add up to the whole.
"""

from __future__ import annotations

import numpy as np

from mpeg4.errors import InputError
from mpeg4.fat import fap_unit
from mpeg4.head import Head, SparseDisplacement

from .brow_crease import relaxed_brows
from .lip_contours import smooth_partition
from .mesh_tables import fp_motion

__all__ = ["BROW_POINTS", "BROW_RAISE_SHAPES", "brow_partition"]

#: The brow points across the face, right to left (outer, middle, inner on each side), and
# the FAP raising each.
BROW_POINTS = ("4.6", "4.4", "4.2", "4.1", "4.3", "4.5")
_BROW_RAISE = {31: "4.1", 32: "4.2", 33: "4.3", 34: "4.4", 35: "4.5", 36: "4.6"}
#: The sculpted shapes that together raise both brows whole.
BROW_RAISE_SHAPES = ("browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R")


def brow_partition(head: Head, x: np.ndarray) -> np.ndarray:
    """(N, 6) smooth partition of unity across the brows, one column per :data:`BROW_POINTS`.

    Column j is 1 at the x of brow point j, 0 at the x of its neighbours, and blends
    between neighbours by the quintic smoothstep ``6t⁵ − 15t⁴ + 10t³`` (C², so the pieces
    are as smooth as the field they cut); beyond the outer points the outer columns stay 1.
    The columns sum to 1 everywhere, so equal FAP values give back the whole field.

    Parameters
    ----------
    head : Head
        With the brow points.
    x : (N,) float
        Left-right coordinates, metres (the face's left is +x).
    """
    nodes = np.array([head.fp_position(i)[0] for i in BROW_POINTS])
    if np.any(np.diff(nodes) <= 0):
        raise InputError("the brow points are not ordered across the face (4.6, 4.4, 4.2, 4.1, 4.3, 4.5 from "
                         f"right to left); their x are {', '.join(f'{v * 1e3:.1f}' for v in nodes)} mm",
                         fix="check the brow points (fmc mark)")
    return smooth_partition(nodes, x)


def _brow_piece(head, n, goal, ids, k, bad):
    """A brow-raise FAP from the sculpted whole-brow raise, cut by :func:`brow_partition`.

    The sculpted shapes raise each brow whole (inner, outer), while FAPs 31-36 move one of
    three points per brow. A combination of whole shapes cannot move one point alone
    without large opposed weights (raise against lower), and a local bump scaled to the
    FAP's amount folds the forehead where two of them overlap. Here the summed raise of
    :data:`BROW_RAISE_SHAPES` is cut into six pieces by a smooth partition of unity across
    the brows, so each FAP moves its own point and fades to nothing at its neighbours, and
    all six together give back the sculpted raise. The FAP is a vertical displacement
    (reference section 3): each piece keeps the field's vertical component, scaled so its
    point moves by ``goal``. (The sculpted brow also slides back and out over the skull, up
    to a third of its rise at the outer point, and its forehead wrinkles lie mostly in
    depth; both are left out: the point must move straight up, and wrinkles driven to the
    FAP's full range, three times their sculpted depth, fold the skin.) The lowering
    direction is the same field reversed (the sculpted frown also pulls the brow inwards,
    which is FAPs 37/38, and barely lowers the outer brow), but not the same table: each
    direction's whole field is relaxed where it folds the skin before it is cut
    (:func:`fmc.brow_crease.relaxed_brows`; run backwards, the raise pushed the skin above
    the lid crease through it).

    Returns the displacement, its FP error and leak (as :func:`fmc.author._solve`) and the
    scale of the shapes where the piece is whole.
    """
    fp_id = _BROW_RAISE[n]
    part = head.feature_points[fp_id].part
    nv = head.parts[part].n_vertices
    field = np.zeros((nv, 3))
    for name in BROW_RAISE_SHAPES:
        d = head.morph_targets[name].get(part)
        if d is not None:
            field[d.indices] += d.vectors
    cuts = brow_partition(head, head.parts[part].vertices[:, 0])
    piece = np.zeros((nv, 3))
    # Each way the whole brows' motion is relaxed where it folds, then cut (fmc.brow_crease).
    whole = relaxed_brows(head, part, field[:, 1], cuts, BROW_POINTS, np.sign(goal[1]), fap_unit(n, head.fapu))
    piece[:] = cuts[:, BROW_POINTS.index(fp_id), None] * whole
    unit = {part: SparseDisplacement.from_dense(piece)}
    along = float(fp_motion(head, unit, [fp_id])[0] @ goal) / float(goal @ goal)
    if abs(along) <= 1e-9:
        return {}, np.inf, np.inf, 0.0
    scale = 1.0 / along
    # Motions under 10 µm at the authoring value are dropped, as in
    # :func:`fmc.mesh_tables.combine_shapes`.
    disp = {part: SparseDisplacement.from_dense(piece * scale, tol=1e-5)}
    motion = fp_motion(head, disp, ids)
    g = np.linalg.norm(goal)
    # Along the FAP's axis only, as the conformance judges it: the brow slides back over the
    # skull as it rises (fmc.brow_crease.forehead_motion), which the FAP leaves free.
    err = float(abs(motion[k] @ goal / g - g) / g)
    leak = float(np.linalg.norm(motion[bad], axis=1).max(initial=0) / g)
    # The shapes' weight where the piece is whole: the sculpted piece's point rises by `raw`.
    piece[:, 1] = cuts[:, BROW_POINTS.index(fp_id)] * field[:, 1]
    raw = float(fp_motion(head, {part: SparseDisplacement.from_dense(piece)}, [fp_id])[0, 1])
    return disp, err, leak, abs(goal[1] / raw)
