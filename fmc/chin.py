"""The chin raiser (FAP 18): the chin boss rises with the skin around it, the lips stay.

``depress_chin`` moves the chin boss 2.10 vertically, up for positive values, by
value × MNS (the reference, section 3). No sculpted shape of the generic head raises the
chin alone: the fit (:func:`fmc.author._solve`) combined the lower lip's shrug with the
mouth's other shapes, whose motion spreads over the whole lower lip and into the lip
corners. The separation (:mod:`fmc.separate`) holds the lip points only along their FAPs'
axes, so what was left sheared the lip corners' crease (triangles 0.06 mm across): at 300,
within 2 mm of the inner corner 2.4, by 1.3 mm in depth and 0.45 mm vertically, and moved
the lower lip's edge 8.2 0.8 mm back.

A real stream raises the chin while the corners are stretched and the jaw opens and
thrusts: in Xface's ``pride`` (frame 74: ``depress_chin`` 300, the inner and outer
stretches 113, ``open_jaw`` 235 and ``thrust_jaw`` 265 after the jaw's decoupling,
:mod:`fmc.decouple`) 50 skin triangles turned over, 40 in the inner lip corners' crease. The
stretches alone fold 24 there (their tables are kept as authored,
:data:`fmc.unfold.KEPT`); the chin raiser's shear added 20 (the thrust's, the lower jaw
sliding forward under the upper lip, about as many). Keeping only its vertical motion
(as :mod:`fmc.push` keeps the pushes' depth) left the lower lip rising between its held
points and still shearing the crease vertically (0.66 mm): 42.

Its table is now the point's own smooth hat, as the cheek puffs' are
(:func:`fmc.puff.puff_field`, which :func:`fmc.author.author_from_shapes` calls for both):
1 at 2.10, 0 at every other governed feature point and along the lip contours between them (:func:`fmc.separate.correction_basis`), bi-harmonic
in between. The chin boss moves by exactly value × MNS along its axis, the skin around it
with it, the lips and their corners not at all, and no skin moves further than the point.

The chin boss is where the reference puts it, the chin's most prominent point
(``scripts/build_generic_head.py``: the frontmost point of the midline profile below the
mentolabial sulcus, 17.1 mm below 8.2 and 14.8 mm above 2.1 on the generic head). It sat
on the lower lip's underside before, 1.9 mm below 8.2 (the frontmost midline vertex
between 2.1 and 8.2 was the lip's bulge), so that a chin raised by more than about 90
units passed its point over the held lip's edge and the skin between turned over:
``depress_chin`` alone turned 6 triangles over at 300 and 20 at 512, pride's frame 74 34
(``tests/fmc/test_chin.py``). With the sulcus between them the hat has room: none turns
over alone at ±300 or 512, no skin moves further than the point, and frame 74 turns the 20
over that the stretches and the jaw turn without it.
"""

from __future__ import annotations

__all__ = ["CHIN_FAPS"]

#: The chin's vertical FAP: depress_chin (2.10, +y, MNS).
CHIN_FAPS = (18,)
