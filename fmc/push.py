"""The lips' pushes (FAPs 16 and 17): the lip moves forward or back, not sideways.

``push_b_lip`` / ``push_t_lip`` move the centre of the lower / upper inner lip (2.3 / 2.2)
in depth, forwards for positive values, by value × MNS (the reference, section 3), and the
lip's region with it. No sculpted shape of the generic head pushes a lip forward alone: the
fit (:func:`fmc.author._solve`) gets the depth by opposing shapes, for ``push_b_lip`` the
lower lip's drop (``mouthLowerDown``, weight 2.8 at 512) against its shrug
(``mouthShrugLower``, 1.9), whose vertical and sideways motions cancel at the fitted points
only. Between them the lower lip spreads sideways (its midpoint 2.8 by 2.8 mm at 300, half
as much as it moves forward) while the separation (:mod:`fmc.separate`) holds the lip
corners' x: the spread piles into the corner's crease, and ``push_b_lip`` alone at 300
turned 54 skin triangles over there (121 at 600); in Greta's disgust (340) and Xface's
fear (282) it gave all the worst frame's 78 and 69.

:func:`along_axis` keeps of such a field its motion along the FAP's axis only, as the
brow raisers keep their vertical motion (:func:`fmc.brow_raise.brow_partition`) and the cheek
puffs theirs (:mod:`fmc.puff`): the region moves with its point the way the point moves.
The point's own motion is unchanged (the fit makes it exact along the axis); its vertical
motion, which the lips' vertical FAPs govern, the separation took out already.
"""

from __future__ import annotations

import numpy as np

from mpeg4.head import SparseDisplacement

__all__ = ["PUSH_FAPS", "along_axis"]

#: The lips' depth FAPs: push_b_lip, push_t_lip.
PUSH_FAPS = (16, 17)


def along_axis(disp: dict[str, SparseDisplacement], axis: np.ndarray) -> dict[str, SparseDisplacement]:
    """Part → displacement with each vector replaced by its component along ``axis``.

    Parameters
    ----------
    disp : dict of str to SparseDisplacement
        Vectors in metres.
    axis : (3,) float
        The FAP's direction (any length; normalised here).

    Returns
    -------
    dict of str to SparseDisplacement
        Same vertices, vectors ``(v · a) a`` with ``a`` the unit axis.
    """
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return {p: SparseDisplacement(d.indices, np.outer(d.vectors @ a, a)) for p, d in disp.items()}
