"""Tables that turn the skin over as little as they can: folds relaxed out of each table.

Authored from sculpted shapes and separated so that FAPs add up (:mod:`fmc.separate`), a
table still folds the skin where its motion changes faster than the mesh is fine: the
generic head's lip corners are a crease of triangles 0.06 mm across, and a lip corner's
stretch at 300 turned 157 of them over (an edge stretched to 14 times its length), the
corner's raise 131, the jaw's shift 73. A real stream sums a dozen such tables, and the
folds add up: 473 triangles turned over in one frame of Greta's anger.

:func:`unfold_offsets` takes one displacement field and, where it turns triangles over,
replaces it by the bi-harmonic interpolation of the field around the fold (the smoothest
motion that meets the rest), over a region grown from 1 to 16 mm around the fold until
nothing is turned over, keeping the try with the fewest folds. Feature points' vertices
are held: the motion the standard defines (a FAP's own point, the points
:mod:`fmc.separate` keeps still) does not change. :func:`unfold_tables` does this for every
low-level skin table of a FAT at each interval border and, beyond the outer ones, at the
value :data:`EXTENT` that streams reach (the lips' tables excepted, :data:`CONTOUR_FAPS`).

At the lip corners the two lips' vertices lie a few hundredths of a millimetre apart: every
table moves the other lip's corner vertex with the corner's (:func:`corner_glue`), so that
no sum of tables tears the sliver between them (the streams' worst frame on the generic
head 11 triangles turned over before, 8 after; on the example's head 24 and 20, its
longest edge 5.5 and 4.8 times its length).

Some folds cannot go while the feature points are held, and some tables are left as
authored (:data:`KEPT`: the brow raisers; the lip corners' stretches, unfolded as inner and
outer pairs, :data:`CORNER_PAIRS`, as streams play them). Measured on the
generic head (``tests/fmc/test_unfold.py``, ``benchmarks/fap_conformance.py``): the tables
it relaxes, each alone at ±300, turned 1674 triangles over in all before, 323 after; the
nine Xface and six Greta streams' worst frame 473 before, 78 after, the longest edge 19.3
times its length before, 5.0 after, the feature points' conformance unchanged (98.5 %).
The folds left come from tables added together (at the lip corners in Greta's disgust, on
the forehead over the raised brows in her surprise). What it costs: relaxed around its held
point, a table peaks more sharply there (the lip corner's lowering at 512, its skin 1 mm
from the point: 0.59 of the point's motion, 0.85 before), and cloned onto MakeHuman's
coarser mesh, which samples beside the peak, the corners' raise moved its point 6 to 25 %
short (the FAPU conformance of ``benchmarks/foreign_heads.py`` 51 to 46 %; the cloning
now scales each table back to its point's motion, :mod:`fmc.clone.calibrate`: 70 %).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable, fap_unit
from mpeg4.head import Head
from mpeg4.io.fap import LIP_CONTOUR_PAIRS
from mpeg4.seams import merged_surface
from mpeg4.surface import bilaplacian, inverted_triangles, smoothest_fill

__all__ = ["REACHES", "EXTENT", "CONTOUR_FAPS", "KEPT", "CORNER_PAIRS", "CORNERS", "GLUE_SHARE", "corner_glue",
           "unfold_offsets", "unfold_tables", "unfold_targets"]

#: Distance, metres, around the folds within which the motion is relaxed, at each try.
REACHES = (0.001, 0.002, 0.004, 0.008, 0.016)
#: FAP value (each way) up to which a table's motion is unfolded beyond its outer borders:
#: streams go beyond the usual ±512 (the lids close at 1024, the jaw opens past 512).
EXTENT = 1024.0
#: The lips' contour FAPs (inner 4-13, outer 51-60: :data:`mpeg4.io.fap.LIP_CONTOUR_PAIRS`),
#: unfolded up to their interval border only (512 MNS, a lip point 10.6 mm; :mod:`fmc.limits`
#: stops lips that meet). A lip point lies 3.5 to 10 mm from the next lip point its table
#: holds still: relaxed at 1024, where a corner lowered 21 mm folds the crease between the
#: two corners, the outer corner's lowering was given a cone at the inner corner that every
#: value then played, and the crease's 0.3 mm edges stretched four times in Greta's
#: sadness (4.28, 1.84 now) and disgust (3.87, 1.98).
CONTOUR_FAPS = frozenset(LIP_CONTOUR_PAIRS) | frozenset(LIP_CONTOUR_PAIRS.values())
#: FAPs left as authored by default. The brow raisers 31-36 are pieces of one sculpted raise
#: (:func:`fmc.brow_raise.brow_partition`) that add up to it; relaxed one by one they no longer
#: do: all six at 200 creased the forehead by 12 to 19 degrees of fold growth, not 7 (their
#: whole motion is relaxed each way before it is cut into pieces, :mod:`fmc.brow_crease`). The
#: lip corners' stretches 6, 7, 53 and 54 move one corner point 25 mm at 512 while the
#: other contour's, 3.3 mm away, stays: that fold cannot go, and relaxing around it left a
#: steep slope between the two points that cloning carried onto other heads (MakeHuman's
#: longest edge at ±512 went from 11.6 to 24.3 times its length). A stream sets both
#: contours' stretch (the player fills the one it leaves out): the pairs are unfolded
#: together instead (:data:`CORNER_PAIRS`).
KEPT = frozenset(range(31, 37)) | {6, 7, 53, 54}
#: The inner and outer lip corners' stretches, each side: kept apart (:data:`KEPT`), they
#: are unfolded together, as a stream plays them (:func:`unfold_tables`). Together at +300
#: they turned 75 triangles over on the generic head, 4 now; at +100 10, now 0. Pulled in
#: (negative), their folds (249 at -300) do not go without folding more elsewhere: kept.
CORNER_PAIRS = ((6, 53), (7, 54))
#: Shares of a border's value at which a pair's sum is checked for folds (streams set the
#: corners' stretches at a tenth to a third of the border; not :data:`EXTENT`: a corner
#: pulled the mouth's width cannot be unfolded, and trying made the usual values fold).
PAIR_SHARES = (0.2, 0.5, 1.0)
#: The lip corners, where the two lips meet.
CORNERS = ("2.4", "2.5")
#: A lip corner's nearest vertex closer than this share of the corner's median edge is the
#: other lip's vertex at the corner, and moves with it (see :func:`corner_glue`).
GLUE_SHARE = 0.5


def unfold_offsets(vertices: np.ndarray, triangles: np.ndarray, offsets: np.ndarray, held: np.ndarray,
                   scales=(1.0,), bilap: sparse.csr_matrix | None = None, no_worse: bool = False
                   ) -> tuple[np.ndarray, int]:
    """``offsets`` with the motion around each fold replaced by a smooth one.

    Parameters
    ----------
    vertices : (V, 3) float
        Rest positions, metres (seam copies merged: one row per surface point).
    triangles : (T, 3) int
    offsets : (V, 3) float
        The motion, metres.
    held : (V,) bool
        Vertices whose motion must not change (feature points).
    scales : sequence of float
        The motion must turn nothing over at each of these multiples of ``offsets``.
    bilap : (V, V) sparse, optional
        :func:`mpeg4.surface.bilaplacian` of the mesh, when the caller has it.
    no_worse : bool
        Take a try only when it turns no more triangles over at any scale than the best so
        far (and fewer at some); by default a try is judged by its folds at the first
        scale, then the next (a smaller motion weighs first).

    Returns
    -------
    offsets : (V, 3) float
        The relaxed motion (a new array; the input is not changed).
    left : int
        Triangles still turned over at the worst scale (0 when unfolded).
    """
    out = np.array(offsets, dtype=np.float64)

    def folds(d):
        each = [inverted_triangles(vertices, triangles, d, (s,)) for s in scales]
        return np.unique(triangles[np.logical_or.reduce(each)]), tuple(int(b.sum()) for b in each)

    corners, count = folds(out)
    if not len(corners):
        return out, 0
    q = bilaplacian(vertices, triangles) if bilap is None else bilap
    # The smaller motions come first: a try that unfolds a smaller one at the cost of a
    # larger one is better.
    best, fewest = out, count
    region = np.zeros(len(vertices), bool)
    for reach in REACHES:
        region |= cKDTree(vertices[corners]).query(vertices, distance_upper_bound=reach)[0] <= reach
        try:
            trial = smoothest_fill(q, offsets, region & ~held)
        except RuntimeError:  # a piece of mesh with nothing held around it: no unique smooth motion
            continue
        corners, count = folds(trial)
        better = (all(c <= f for c, f in zip(count, fewest)) and count != fewest) if no_worse else count < fewest
        if better:
            best, fewest = trial, count
        if not any(fewest):
            break
    return best, max(fewest)


def unfold_tables(head: Head, fat: FAT | None = None, *, keep=KEPT) -> tuple[FAT, dict[int, int]]:
    """A copy of ``fat`` (default ``head.fat``) whose low-level skin tables turn as few
    triangles over as they can, feature points held (:func:`unfold_offsets`), at each of
    their interval borders and at the value :data:`EXTENT` beyond the outer ones.

    Parameters
    ----------
    head : Head
    fat : FAT, optional
    keep : iterable of int
        FAPs whose tables stay as they are (default :data:`KEPT`).

    Returns
    -------
    fat : FAT
        Tables left as they were share their objects with the input.
    left : dict
        FAP → triangles its table alone still turns over at the worst of those values, for
        the tables that could not be unfolded entirely.
    """
    keep = frozenset(keep)
    given = (head.fat if fat is None else fat) or {}
    out = FAT(given)
    skin = head.skin
    first, inverse, v, t = merged_surface(skin.vertices, skin.triangles)
    held = _held(head, inverse, len(v))
    relax = _Relaxer(v, t, held, corner_glue(head, inverse, v, t))
    left = {}
    for (n, hl), table in given.items():
        if hl or not any(m.part == "skin" for m in table.meshes):
            continue
        unit = fap_unit(n, head.fapu)
        meshes, changed = [], False
        for mesh in table.meshes:
            if mesh.part != "skin":
                meshes.append(mesh)
                continue
            b = mesh.borders
            at = mesh.border_offsets(unit, len(skin.vertices))[:, first]
            for k, o in enumerate(at):
                if b[k] == 0:
                    continue
                # Every table, kept or not, moves the glued vertices with their corners:
                # tables add up, and only then do their sums keep them together too.
                glued = relax.glue(o)
                if not np.array_equal(glued, o):
                    at[k], changed = glued, True
                if n in keep:
                    continue
                # Beyond the outer borders the slope goes on: streams go that far.
                far = max(1.0, EXTENT / abs(b[k])) if k in (0, len(b) - 1) and n not in CONTOUR_FAPS else 1.0
                relaxed, bad = relax(far * glued, (1.0 / far, 1.0))
                if relaxed is None:
                    continue
                at[k], changed = relaxed / far, True
                if bad:
                    left[n] = max(left.get(n, 0), bad)
            meshes.append(FaceDefMesh.from_border_offsets("skin", b, at[:, inverse], unit, mesh.indices)
                          if changed else mesh)
        if changed:
            out.add(FaceDefTable(table.fap, table.high_level, meshes, list(table.transforms)))
    for pair in CORNER_PAIRS:
        if all(n in keep and (n, 0) in given for n in pair):
            bad = _unfold_pair(head, out, pair, first, inverse, relax)
            for n in pair:
                if bad:
                    left[n] = max(left.get(n, 0), bad)
    return out, left


def unfold_targets(head: Head, offsets: dict[str, np.ndarray], allowed: dict[str, float] | None = None,
                   scales=(1.0,)) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """Skin motions of whole morph targets (name → (V, 3) metres, ``head.skin``'s vertices)
    relaxed where they turn the skin over, feature points held (:func:`unfold_offsets`, at
    the target's ``scales`` of its full weight, over regions up to 16 mm).

    ``allowed`` (name → triangles) leaves a target as it is while it turns no more
    triangles over than that: a cloned target may fold where its source did (a corrective
    shape such as ARKit's mouthClose folds alone and is made to be played with the jaw's
    opening; relaxed alone, the two would no longer add up to closed lips).

    Measured with MakeHuman's targets cloned onto the generic head
    (``benchmarks/foreign_heads.py``): the jaw drop turned 356 triangles over before, 220
    after (the rest under the chin, which its drop takes 47 mm back: relaxed over regions up
    to 64 mm, 44 were left, but the lower lip's outer skin came away from the lip, so the
    regions stop at 16 mm as for tables); its longest edge 197 times its length before,
    11.8 after; the smile 139 and 6.0 before, 0 and 3.3 after; the happy face 165 and 7.9
    before, 0 and 2.7 after; the B/M/P viseme 68 and 9.5, 2 and 2.8. The stripes that
    spanned the open mouth's corners are gone (``test-artifacts``' renders).

    Returns
    -------
    offsets : dict
        Name → relaxed (V, 3) motion (the input's array where nothing folded).
    left : dict
        Name → triangles still turned over at the worst scale, for those not unfolded
        entirely.
    """
    skin = head.skin
    first, inverse, v, t = merged_surface(skin.vertices, skin.triangles)
    held = _held(head, inverse, len(v))
    allowed = allowed or {}
    q, out, left = None, {}, {}
    for name, d in offsets.items():
        merged = np.asarray(d, dtype=np.float64)[first]
        if inverted_triangles(v, t, merged, scales).sum() <= allowed.get(name, 0):
            out[name] = d
            continue
        q = bilaplacian(v, t) if q is None else q
        relaxed, bad = unfold_offsets(v, t, merged, held, scales, q)
        out[name] = relaxed[inverse]
        if bad:
            left[name] = bad
    return out, left


def _held(head: Head, inverse: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool: the merged surface's points that hold a skin feature point."""
    held = np.zeros(n, bool)
    for fp in head.feature_points.values():
        if fp.part == "skin":
            held[inverse[np.asarray(fp.vertices)]] = True
    return held


def corner_glue(head: Head, inverse: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> dict[int, int]:
    """Merged surface vertex → lip corner vertex it moves with.

    The generic head's mouth corners hold the two lips' vertices 0.06 mm apart (0.12 mm on
    the example's head), where the corner's other edges are 0.2 to 0.5 mm: moved apart by a
    few hundredths of a millimetre (the lower lip pushed out, FAP 16 at 340, while the upper
    stays), the sliver between them turned over, and held on one side only, it could not be
    relaxed. The corner's nearest neighbour, when closer than :data:`GLUE_SHARE` of its
    median edge, is that other vertex.
    """
    out = {}
    for fp in CORNERS:
        b = head.feature_points.get(fp)
        if b is None or b.part != "skin" or len(b.vertices) != 1:
            continue
        c = int(inverse[b.vertices[0]])
        ring = np.unique(triangles[(triangles == c).any(axis=1)])
        ring = ring[ring != c]
        if len(ring) < 3:
            continue
        d = np.linalg.norm(vertices[ring] - vertices[c], axis=1)
        if d.min() < GLUE_SHARE * np.median(d):
            out[int(ring[np.argmin(d)])] = c
    return out


class _Relaxer:
    """:func:`unfold_offsets` on one merged surface, called only for offsets that fold at
    one of their scales (the surface's bi-Laplacian built at the first such call). The
    vertices glued to a lip corner (:func:`corner_glue`) are held; the caller gives offsets
    that move them with it (:meth:`glue`)."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, held: np.ndarray,
                 glued: dict[int, int] | None = None):
        self.v, self.t, self.q = vertices, triangles, None
        glued = glued or {}
        self.glued = np.array(list(glued), dtype=np.int64)
        self.anchor = np.array([glued[g] for g in glued], dtype=np.int64)
        self.held = held.copy()
        self.held[self.glued] = True

    def glue(self, offsets: np.ndarray) -> np.ndarray:
        """``offsets`` (V, 3) with each glued vertex moved as its corner (a copy)."""
        out = np.array(offsets, dtype=np.float64)
        out[self.glued] = out[self.anchor]
        return out

    def __call__(self, offsets: np.ndarray, scales, **options) -> tuple[np.ndarray | None, int]:
        """``(relaxed, still_inverted)``, or ``(None, 0)`` when ``offsets`` (already
        glued, :meth:`glue`) fold nowhere."""
        if not inverted_triangles(self.v, self.t, offsets, scales).any():
            return None, 0
        self.q = bilaplacian(self.v, self.t) if self.q is None else self.q
        return unfold_offsets(self.v, self.t, offsets, self.held, scales, self.q, **options)


def _unfold_pair(head: Head, fat: FAT, pair: tuple[int, int], first, inverse, relax: _Relaxer) -> int:
    """Unfold the inner and outer lip corner's stretches of ``pair`` together, in ``fat``
    (replaced in place): their sum, as a stream plays them, relaxed at each border's
    :data:`PAIR_SHARES` (a try taken only when it folds no more at any of them), the change
    shared between the two tables by each vertex's share of their motion. Returns the
    triangles the sum still turns over at its worst."""
    tables = [fat[(n, 0)] for n in pair]
    skins = [[m for m in tb.meshes if m.part == "skin"] for tb in tables]
    if any(len(s) != 1 for s in skins) or not np.array_equal(skins[0][0].borders, skins[1][0].borders):
        return 0
    units = [fap_unit(n, head.fapu) for n in pair]
    b = skins[0][0].borders
    n_v = len(head.skin.vertices)
    at = [m[0].border_offsets(u, n_v)[:, first] for m, u in zip(skins, units)]
    worst, changed = 0, False
    for k in range(len(b)):
        if b[k] == 0:
            continue
        both = at[0][k] + at[1][k]
        relaxed, bad = relax(both, PAIR_SHARES, no_worse=True)
        if relaxed is None:
            continue
        change = relaxed - both
        size = [np.linalg.norm(a[k], axis=1) for a in at]
        share = size[0] / np.maximum(size[0] + size[1], 1e-12)
        at[0][k] += share[:, None] * change
        at[1][k] += (1.0 - share)[:, None] * change
        worst, changed = max(worst, bad), True
    if changed:
        for tb, m, a, u in zip(tables, skins, at, units):
            meshes = [FaceDefMesh.from_border_offsets("skin", b, a[:, inverse], u, m[0].indices) if x.part == "skin"
                      else x for x in tb.meshes]
            fat.add(FaceDefTable(tb.fap, tb.high_level, meshes, list(tb.transforms)))
    return worst
