"""The brows' tables relaxed whole, each way: a lowered brow does not fold the lid crease.

The brow FAPs 31-36 move their points vertically (the reference, section 3); their tables
are pieces of the sculpted whole-brow raise, cut by a smooth partition across the brows
(:func:`fmc.brow_raise.brow_partition`), so that all six together give the whole raise back.
That raise lifts the brow and fades out across the upper lid's crease, steeply: on the
generic head, at the x of the lid fold 3.13, the skin 3 mm above the crease rises 4 times
as much as the crease (10.1 against 2.6 mm with ``raise_l_m_eyebrow`` at 300). Raised, that
opens the crease. Lowered, the same table run backwards (a table is linear in the FAP
value), the skin above the crease passes through it: ``raise_l_m_eyebrow`` alone turned 12
skin triangles over at -150, 44 at -300, all in the crease by 3.13 and the lid margin
3.1/3.7 (the outer brows 46 at -300), and the four inner and middle brows at -156 (Greta's
anger) 39, most of that file's worst frame of 53. Raised far, the skin above the brows is
crushed the same way against the forehead: all six at Greta's surprise (410-560) turned 42
triangles over around 4.3/4.4, each middle brow alone at 600 18.

Relaxed one by one, the pieces would no longer add up (:data:`fmc.unfold.KEPT`), so
:func:`relaxed_brows` relaxes the brows' motion *whole*, for each direction of the FAPs
on its own (the tables hold one slope per side of 0, ``[-value, 0, value]``): the motion of
all six pieces at one value, their points moving alike, where it turns triangles over at
up to :data:`EXTENT` is replaced by the smoothest motion that meets the rest
(:func:`fmc.unfold.unfold_offsets`: bi-harmonic, over a region grown around the folds,
feature points held). Cut again by the same partition it gives the six pieces, which still
add up to it; a lowered brow now takes the skin between brow and crease down evenly instead
of piling it into the crease, and a raised one lifts the skin above it further up.

Measured on the generic head (``tests/fmc/test_brow_crease.py``,
``benchmarks/fap_conformance.py``): ``raise_l_m_eyebrow`` alone turns nothing over at
-150 or -300 (11 and 44 before), the outer brow nothing at -300 (46), all six at -200
nothing (112); all six at Greta's surprise 8 (41). Greta's anger's worst frame 53 -> 21
triangles turned over, her surprise's 50 -> 13 (63 -> 18 on the example's head); the
points' conformance (98.5 %) and the regions' motion over their points' (1.29) unchanged.
What it costs: the skin between a lowered brow and the crease bends more (the forehead's
fold growth 4 mm above the lid folds, all six at -200: 17.5 degrees, 9.6 run backwards,
which put its fold in the crease instead), and a raised brow pulls a little harder on the
crease above a wide-open lid (the longest edge in Greta's surprise 4.99 -> 5.02 times its
length, 5.70 -> 5.81 on the example's head).

Driven past its sculpted range (the sculpted raise lifts the middle brow 10 mm, Greta's
surprise asks 26), the raise still moved the forehead as one block up to the hairline, where
the skin stood in a ridge, and straight up, in front of the forehead sloping back (8.6 mm).
Before it is relaxed, :func:`forehead_motion` gives the forehead its own motion: above the
brows it fades smoothly to the top of the head, and a raised brow and forehead slide along
the neutral surface. All six at Greta's surprise now turn nothing over (8 before), the
middle brow alone at 600 nothing (12).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import LinearNDInterpolator

from mpeg4.head import Head
from mpeg4.seams import merged_surface
from mpeg4.surface import bilaplacian, smoothest_fill

from .unfold import unfold_offsets

__all__ = ["EXTENT", "SCALES", "FOREHEAD_BAND", "forehead_motion", "relaxed_brows"]

#: FAP value (ENS units, each way) up to which the brows' whole motion is relaxed: beyond
#: the authoring value 512, where each piece is whole, as far as the streams go (Greta's
#: surprise raises the middle brows by 560, 26 mm on the generic head).
EXTENT = 600.0
#: Shares of :data:`EXTENT` at which the relaxed motion must turn nothing over (the smaller
#: first: a try that unfolds a usual value at the cost of an extreme one is better).
SCALES = (0.25, 0.5, 1.0)
#: Metres above the highest brow point where the forehead's own motion starts
#: (:func:`forehead_motion`).
FOREHEAD_BAND = 0.005


def forehead_motion(head: Head, v: np.ndarray, t: np.ndarray, offsets: np.ndarray, brow_vertices,
                    slide: bool = True) -> np.ndarray:
    """The brows' vertical motion ``offsets`` (V, 3) with the forehead's own.

    Above the brows' band (:data:`FOREHEAD_BAND` over their highest point) the vertical
    motion is the smoothest (bi-harmonic) between the band, as given, and the top of the
    head, still: the sculpted raise moves the forehead as one block up to the hairline,
    where driven past its sculpted range it stood in a ridge. With ``slide`` (the raise),
    the skin also slides along the neutral surface, taking the depth of the surface where it
    arrives: straight up, the raised brow and forehead stood out in front of the sloping
    forehead (8.6 mm at Greta's surprise). The slide fades in (a smoothstep) from just
    above the upper lids' folds (3.13/3.14) to the top of the brows' band, so the lid and
    its crease keep moving vertically and the brows slide back part of the way, as the
    sculpted raise has them (the FAP fixes only their vertical motion).

    Parameters
    ----------
    head : Head
    v, t : (V, 3) float, (T, 3) int
        The part's surface, seam copies merged (:func:`mpeg4.seams.merged_surface`), metres.
    offsets : (V, 3) float
        The brows' motion, metres.
    brow_vertices : sequence of (k,) int
        Each brow point's vertices in ``v``.
    slide : bool

    Returns
    -------
    (V, 3) float
    """
    heights = [v[np.asarray(b), 1] for b in brow_vertices]
    top = max(float(h.max()) for h in heights) + FOREHEAD_BAND
    bottom = min(float(h.min()) for h in heights)
    crown = float(head.fp_position("11.4")[2]) if "11.4" in head.feature_points else float(v[:, 2].mean())
    out = np.array(offsets, dtype=np.float64)
    free = (v[:, 1] > top) & (v[:, 2] > crown)
    if free.any():
        try:
            out[:, 1] = smoothest_fill(bilaplacian(v, t), out[:, 1], free)
        except RuntimeError:  # no boundary around it: leave the motion as given
            pass
    if not slide:
        return out
    # The forehead seen from the front is a height field: depth at (x, y).
    folds = [float(head.fp_position(i)[1]) for i in ("3.13", "3.14") if i in head.feature_points]
    start = (max(folds) if folds else bottom - FOREHEAD_BAND) + FOREHEAD_BAND / 2
    face = (v[:, 1] > start - FOREHEAD_BAND) & (v[:, 2] > crown)
    sliding = (v[:, 1] > start) & (v[:, 2] > crown)
    depth = LinearNDInterpolator(v[face][:, :2], v[face, 2])
    dz = depth(v[sliding][:, :2] + np.c_[np.zeros(sliding.sum()), out[sliding, 1]]) - v[sliding, 2]
    ramp = np.clip((v[sliding, 1] - start) / (top - start), 0.0, 1.0)
    ramp = ramp * ramp * (3 - 2 * ramp)
    out[sliding, 2] = np.where(np.isfinite(dz), dz, 0.0) * ramp
    return out


def relaxed_brows(head: Head, part: str, field: np.ndarray, cuts: np.ndarray, points, sign: float,
                  unit: float, extent: float = EXTENT) -> np.ndarray:
    """The whole brows' vertical motion per metre of their points' motion, relaxed where it
    turns the skin over when the brows move ``sign`` (up: +1, down: -1) by up to ``extent``.

    Parameters
    ----------
    head : Head
        With the brow ``points`` and the other feature points (held) on ``part``.
    part : str
        The part the brows lie on (the skin).
    field : (N,) float
        The sculpted vertical raise over the part's vertices (any scale).
    cuts : (N, P) float
        The brow partition (:func:`fmc.brow_raise.brow_partition`), one column per point.
    points : sequence of str
        The P brow points, in the columns' order.
    sign : {1.0, -1.0}
    unit : float
        The FAPs' unit (ENS), metres.
    extent : float
        FAP value.

    Returns
    -------
    (N, 3) float
        The motion of each vertex, metres per metre, when every brow point moves 1 m up (its
        negative when they move down): vertical but for the forehead's slide
        (:func:`forehead_motion`); cut by ``cuts`` it gives each FAP's piece.
    """
    along = np.array([np.asarray(head.feature_points[i].weights) @ (cuts[:, j] * field)[list(head.feature_points[i].vertices)]
                      for j, i in enumerate(points)])
    # Each piece scaled so its point moves 1 m: the sum is what equal values of all six do.
    whole = (cuts * field[:, None] / along).sum(axis=1)
    reach = sign * extent * unit
    p = head.parts[part]
    first, inverse, v, t = merged_surface(p.vertices, p.triangles)
    offsets = np.zeros((len(v), 3))
    offsets[:, 1] = reach * whole[first]
    offsets = forehead_motion(head, v, t, offsets, [inverse[np.asarray(head.feature_points[i].vertices)]
                                                   for i in points], slide=sign > 0)
    held = np.zeros(len(v), bool)
    # Every feature point is held, the lid folds 3.13/3.14 too: let go, the crease moved
    # down onto the held lid margin and folded there (all six brows at -300: 50 triangles).
    for fp in head.feature_points.values():
        if fp.part == part:
            held[inverse[np.asarray(fp.vertices)]] = True
    relaxed, _ = unfold_offsets(v, t, offsets, held, SCALES)
    return relaxed[inverse] / reach
