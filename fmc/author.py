"""Author Facial Animation Tables for a head from its sculpted expression shapes.

For each low-level FAP the head's morph targets (e.g. the 53 ARKit-named shapes of the
generic head) are combined with non-negative weights, found by non-negative least squares,
so that the FAP's feature point moves along the FAP's axis by ``value × FAPU`` while the
feature points of other regions, and those on the other side of the face, stay still.
Bidirectional FAPs get one combination per direction (interval borders
``[-value, 0, value]``), unidirectional ones one (``[0, value]``). Rotations are
FaceDefTransforms: the head about 7.1 and the eyeballs about their centres. The brow
raisers 31-36, one point each where the shapes raise a whole brow, cut the sculpted raise
into pieces by a smooth partition across the brows (:mod:`fmc.brow_raise`). The visemes
and expressions are :mod:`fmc.high_level`'s.

Where no combination of shapes does the job (the ears, the nose wings, the tongue when
the shapes never move it), the FAP falls back to a smooth local displacement field around
its feature point: a compact bump ``(1 − (r/R)²)²`` over the FP's own part, with R set by
the region. Which route each FAP took, and how well it meets the FAP, is reported.

References
----------
.. [1] ISO/IEC 14496-2, Face Animation (FAP semantics, FaceDefTables); the project's
   reference ``mpeg4-fba.md`` sections 3 and 5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from mpeg4.catalogue import FAPS, FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.fat import FAT, FaceDefTable, FaceDefTransform, fap_unit
from mpeg4.head import Head, SparseDisplacement

from .bound import bound_tables
from .brow_raise import _BROW_RAISE, BROW_POINTS, BROW_RAISE_SHAPES, _brow_piece
from .chin import CHIN_FAPS
from .lip_contours import MOUTH_LINE_FPS, lip_side, mouth_line, share_lips, smooth_partition
from .mesh_tables import combine_shapes, fp_motion, mesh_table
from .puff import PUFF_FAPS, puff_field
from .push import PUSH_FAPS, along_axis
from .separate import separate_tables
from .unfold import unfold_tables

__all__ = ["JAW_PARTS", "JAW_FAPS", "WEIGHT_COST", "governed_axes", "moving_parts", "REGIONS", "ADJACENT",
           "region_of", "unrelated", "MOUTH_LINE_FPS", "mouth_line", "lip_side", "FapFit", "smooth_partition",
           "author_from_shapes", "unfold_report"]

#: FP group → face region. Regions follow the muscles that move them together: the soft
#: cheeks (5.1/5.2) move with the mouth, the forehead's hairline with the brows (see
#: :func:`region_of` for the single points that differ from their group).
REGIONS = {2: "mouth", 8: "mouth", 6: "mouth", 3: "eyes", 4: "brows", 5: "cheeks", 9: "nose", 10: "ears",
           11: "skull", 7: "skull"}

# Falloff radius (metres per unit of ES0) of the fallback displacement field, per region.
_RADIUS = {"mouth": 0.25, "eyes": 0.12, "brows": 0.3, "cheeks": 0.3, "nose": 0.2, "ears": 0.35, "skull": 0.6}


def region_of(fp_id: str) -> str:
    """The face region a feature point belongs to.

    The teeth points 9.8–9.11 and the soft cheeks 5.1/5.2 belong to the mouth; the lid
    folds 3.13/3.14 and the hairline 11.1–11.3 to the brows, whose muscles lift them (the
    lid margins stay with the eyes).
    """
    if fp_id in ("9.8", "9.9", "9.10", "9.11", "5.1", "5.2"):
        return "mouth"
    if fp_id in ("3.13", "3.14", "11.1", "11.2", "11.3"):
        return "brows"
    return REGIONS[FEATURE_POINTS[fp_id].group]


# The jaw FAPs use the sculpted jaw shapes alone (the chin follows an arc, not the axis).
_JAW_SHAPES = {3: ("jawOpen",), 14: ("jawForward",), 15: ("jawLeft", "jawRight")}

# Lip points: which lip each lies on (the other lip must not follow it).
_UPPER_LIP = {"2.2", "2.6", "2.7", "8.1", "8.5", "8.6", "8.9", "8.10"}
_LOWER_LIP = {"2.3", "2.8", "2.9", "8.2", "8.7", "8.8"}


@dataclass
class FapFit:
    """How one FAP was authored.

    Attributes
    ----------
    fap : int
    route : {"shapes", "falloff", "puff", "hat", "transform", "none"}
    error : float
        Relative error of the feature point's motion at the authoring value (0 = exact).
    leak : float
        Largest motion of an unrelated feature point relative to the FAP's own motion.
    weights : dict of str to float
        Shape name → weight (positive direction), for ``route == "shapes"``; for the brow
        raisers, the weight where the FAP's piece of the raise is whole.
    folds : int
        Skin triangles the table alone still turns over at its worst border or (but for
        the lips', :data:`fmc.unfold.CONTOUR_FAPS`) at the value :data:`fmc.unfold.EXTENT`,
        after :func:`fmc.unfold.unfold_tables`.
    """

    fap: int
    route: str
    error: float = 0.0
    leak: float = 0.0
    weights: dict | None = None
    folds: int = 0


#: The parts that move with the lower jaw (the jaw FAPs 3, 14 and 15 carry them along).
JAW_PARTS = ("teeth_lower", "gums_lower", "tongue")
#: The jaw FAPs (open, thrust, shift), whose tables move those parts.
JAW_FAPS = (3, 14, 15)


def moving_parts(head: Head, n: int) -> frozenset[str]:
    """The parts FAP ``n``'s table may move.

    Eyeballs only turn (FAPs 23-28, transforms) and dilate (29/30, their own part); teeth,
    gums and tongue only follow the jaw (3, 14, 15) or, for the tongue, its own FAPs. Every
    other FAP moves the part of its feature point alone (the skin): a sculpted shape's
    small motions of other parts (the ICT FaceKit's mouth shapes nudge the gums, its pupil
    dilation the skin) are noise there, and a combination of shapes must not move an
    eyeball to fit a lip corner.
    """
    own = head.feature_points[FAPS[n].feature_points[0]].part
    if n in JAW_FAPS:
        return frozenset({own, *(p for p in JAW_PARTS if p in head.parts)})
    return frozenset({own})


def _fp_matrix(head: Head, names: list[str], ids: list[str], parts=None) -> np.ndarray:
    """(3 K, S): motion of each FP (rows x, y, z per FP) under each shape at weight 1,
    counting only the motion of ``parts`` (all parts if None)."""
    a = np.zeros((3 * len(ids), len(names)))
    for s, name in enumerate(names):
        target = head.morph_targets[name]
        for k, i in enumerate(ids):
            b = head.feature_points[i]
            if parts is not None and b.part not in parts:
                continue
            d = target.get(b.part)
            if d is None:
                continue
            pos = np.searchsorted(d.indices, b.vertices)
            hit = (pos < len(d.indices)) & (d.indices[np.minimum(pos, len(d.indices) - 1)] == b.vertices)
            if hit.any():
                a[3 * k:3 * k + 3, s] = np.asarray(b.weights)[hit] @ d.vectors[pos[hit]]
    return a


def _peak(head: Head, name: str, parts) -> float:
    """Largest vertex motion of shape ``name`` over ``parts`` (all parts if None), metres."""
    return max((float(np.abs(d.vectors).max(initial=0.0)) for p, d in head.morph_targets[name].items()
                if parts is None or p in parts), default=0.0)


def _falloff(head: Head, fp_id: str, motion: np.ndarray) -> dict[str, SparseDisplacement]:
    """A smooth bump moving the FP's part around the FP by ``motion`` at its centre."""
    b = head.feature_points[fp_id]
    part = head.parts[b.part]
    centre = head.fp_position(fp_id)
    radius = _RADIUS[region_of(fp_id)] * head.fapu.ES0
    r = np.linalg.norm(part.vertices - centre, axis=1) / radius
    w = np.where(r < 1, (1 - r ** 2) ** 2, 0.0)
    if fp_id in _UPPER_LIP or fp_id in _LOWER_LIP:
        side = lip_side(head, b.part)
        if side is not None:  # a lip point moves its own lip, not the one it touches
            w = np.where(side == (-1.0 if fp_id in _UPPER_LIP else 1.0), 0.0, w)
    # The bound vertices carry the FP: make its own motion exact.
    w_fp = float(np.asarray(b.weights) @ w[list(b.vertices)])
    dense = np.outer(w / max(w_fp, 1e-12), motion)
    return {b.part: SparseDisplacement.from_dense(dense, tol=1e-9)}


#: Regions whose muscles pull on each other (a smile lifts the cheekbones, a raised brow
#: the upper lids and the root of the nose); motion there is not a leak.
ADJACENT = {"mouth": {"cheeks", "nose"}, "cheeks": {"mouth", "eyes"}, "eyes": {"brows", "cheeks"},
            "brows": {"eyes", "nose"}, "nose": {"mouth", "brows"}, "ears": set(), "skull": set()}


def unrelated(fp_id: str, ids: list[str]) -> np.ndarray:
    """Mask of the FPs ``ids`` that must stay still when ``fp_id``'s FAP acts: those of
    regions neither the same nor adjacent, those on the other side of the face, and those
    of the other lip."""
    side = FEATURE_POINTS[fp_id].side
    region = region_of(fp_id)
    out = []
    for i in ids:
        s = FEATURE_POINTS[i].side
        other_side = side != "C" and s != "C" and s != side
        r = region_of(i)
        # The lips move apart: a FAP of one lip must leave the other lip's points still.
        other_lip = (fp_id in _UPPER_LIP and i in _LOWER_LIP) or (fp_id in _LOWER_LIP and i in _UPPER_LIP)
        out.append((r != region and r not in ADJACENT[region]) or other_side or other_lip)
    return np.array(out)


def author_from_shapes(head: Head, value: float = 512.0, tol: float = 0.10, leak_tol: float = 0.20,
                       faps=None, separate: bool = True, unfold: bool = True,
                       bound: bool = True) -> tuple[FAT, list[FapFit]]:
    """FATs for the low-level FAPs of ``head`` from its morph targets.

    Parameters
    ----------
    head : Head
        With feature points (all those the FAPs use) and morph targets.
    value : float
        FAP value the tables are authored at (the interval borders ±value).
    tol, leak_tol : float
        A shape combination is accepted when the FP's motion is within ``tol`` of the
        target (relative) and no unrelated FP moves more than ``leak_tol`` of it;
        otherwise the FAP falls back to a local displacement field.
    faps : iterable of int, optional
        FAPs to author (default 3..68).
    separate : bool
        Take out of each table what it does to other FAPs' points
        (:func:`fmc.separate.separate_tables`); False keeps the shapes' motion as it is.
    unfold : bool
        Relax the motion around the triangles each table turns over
        (:func:`fmc.unfold.unfold_tables`, feature points held).
    bound : bool
        Cap each table's skin motion at :data:`fmc.bound.RATIO` times its own point's
        (:func:`fmc.bound.bound_tables`; the jaw's tables excepted).

    Returns
    -------
    fat : FAT
    report : list of FapFit
    """
    fapu = head.fapu
    ids = [i for i in FP_IDS if i in head.feature_points]
    names = sorted(head.morph_targets)
    a_by_parts: dict[frozenset, tuple[list[str], np.ndarray]] = {}

    def shapes_for(parts: frozenset) -> tuple[list[str], np.ndarray]:
        # The candidate shapes move these parts: a shape whose motion there is under a
        # tenth of its largest motion is about another part (a pupil dilation for a
        # lip corner) and would only be scaled up to use its noise.
        if parts not in a_by_parts:
            keep = [nm for nm in names if _peak(head, nm, parts) >= 0.1 * _peak(head, nm, None) > 0]
            a_by_parts[parts] = (keep, _fp_matrix(head, keep, ids, parts) if keep
                                 else np.zeros((3 * len(ids), 0)))
        return a_by_parts[parts]

    fat, report = FAT(), []
    for n in (range(3, 69) if faps is None else faps):
        fap = FAPS[n]
        fp_id = fap.feature_points[0]
        if fp_id not in head.feature_points:
            raise InputError(f"FAP {n} ({fap.name}) needs feature point {fp_id}, which the head lacks",
                             fix="place the point (fmc mark) before authoring")
        if fap.kind == "rotation":
            fat.add(_rotation_table(head, n))
            report.append(FapFit(n, "transform"))
            continue
        if fap.kind in ("scale", "roll"):
            table, fit = _special(head, n, value)
            if table is not None:
                fat.add(table)
            report.append(fit)
            continue
        unit = fap_unit(n, fapu)
        axis = fap.axis_vector
        signs = (1.0,) if fap.direction == "U" else (-1.0, 1.0)
        # No shape swells the cheek along x (fmc.puff), and the shapes' chin raise sheared the
        # lip corners (fmc.chin): the point's own smooth hat, both ways.
        if n in PUFF_FAPS or n in CHIN_FAPS:
            disp = puff_field(head, fp_id, value * unit * axis)
            fat.add(mesh_table(head, n, {s: {p: d.scaled(s) for p, d in disp.items()} for s in signs}, value, unit))
            report.append(FapFit(n, "puff" if n in PUFF_FAPS else "hat"))
            continue
        k = ids.index(fp_id)
        bad = unrelated(fp_id, ids)
        parts = moving_parts(head, n)
        names, a = shapes_for(parts)
        meshes_by_sign, route, err_all, leak_all, weights = {}, "shapes", 0.0, 0.0, None
        jaw = [s for s in _JAW_SHAPES.get(n, ()) if s in names]
        brow = n in _BROW_RAISE and all(s in head.morph_targets for s in BROW_RAISE_SHAPES) \
            and all(i in head.feature_points for i in BROW_POINTS)
        for sign in signs:
            goal = sign * value * unit * axis
            if brow:
                disp, fit_err, leak, scale = _brow_piece(head, n, goal, ids, k, bad)
                w = np.zeros(len(names))
                w[[names.index(s) for s in BROW_RAISE_SHAPES]] = scale
            elif jaw:
                # The jaw turns as it opens: keep the sculpted motion, scaled so the chin
                # moves by the FAP's amount along its axis, whatever it does across it.
                cols = [names.index(s) for s in jaw]
                disp, fit_err, leak, w_sub = _solve(head, jaw, a[:, cols], ids, k, bad, goal, parts)
                w = np.zeros(len(names))
                w[cols] = w_sub
                if np.isfinite(fit_err):
                    fit_err = 0.0  # along the axis it is exact by construction
            else:
                disp, fit_err, leak, w = _solve(head, names, a, ids, k, bad, goal, parts)
                if n in PUSH_FAPS:  # a lip pushed forward moves in depth, not sideways (fmc.push)
                    disp = along_axis(disp, axis)
            if fit_err > tol or leak > leak_tol:
                disp = _falloff(head, fp_id, goal)
                motion = fp_motion(head, disp, ids)
                fit_err = float(np.linalg.norm(motion[k] - goal) / np.linalg.norm(goal))
                leak = float(np.linalg.norm(motion[bad], axis=1).max(initial=0) / np.linalg.norm(goal))
                route = "falloff"
            elif sign > 0:
                weights = {names[j]: float(x) for j, x in enumerate(w) if x > 1e-6}
            meshes_by_sign[sign] = disp
            err_all, leak_all = max(err_all, fit_err), max(leak_all, leak)
        fat.add(mesh_table(head, n, meshes_by_sign, value, unit))
        report.append(FapFit(n, route, err_all, leak_all, weights))
    # Each of the sculpted shapes moves the whole lip: the lip FAPs share it (fmc.lip_contours);
    # and much more than its own point: each table leaves the others' points (fmc.separate).
    # What is left still folds the fine creases (the lip corners): fmc.unfold smooths it
    # there; and some regions outrun their point (the cheek beside a stretched corner): fmc.bound.
    fat = share_lips(head, fat)
    fat = separate_tables(head, fat, keep=JAW_FAPS) if separate else fat
    fat = unfold_report(head, fat, report) if unfold else fat
    return (bound_tables(head, fat, keep=JAW_FAPS) if bound else fat), report


def unfold_report(head: Head, fat: FAT, report: list[FapFit]) -> FAT:
    """``fat`` unfolded (:func:`fmc.unfold.unfold_tables`), each FAP's folds left noted in
    ``report`` (changed in place)."""
    fat, left = unfold_tables(head, fat)
    for fit in report:
        fit.folds = left.get(fit.fap, 0)
    return fat


#: What a shape's unit weight costs in the fit, as a share of the goal's length the own
#: point could miss by instead: the default tolerance a fit is accepted at (``tol``). Without it the
#: fit cancelled shapes against each other at weights far past the sculpts' range (the
#: cheek's lift took ``eyeSquint_L`` at 13.6; the lip corner's stretch ``cheekPuff_L`` at
#: 2.2 to hold the corner's depth), and their sum balloons the face between its points.
WEIGHT_COST = 0.10


def governed_axes(fp_id: str) -> np.ndarray:
    """(3,) bool: the axes along which some translation FAP moves feature point ``fp_id``
    (8.3, the outer left lip corner: x by its stretch, y by its raise; its depth no FAP
    sets)."""
    out = np.zeros(3, dtype=bool)
    for fap in FAPS.values():
        if fap.kind == "translation" and fap.feature_points[0] == fp_id:
            out |= np.asarray(fap.axis_vector) != 0
    return out


def _solve(head, names, a, ids, k, bad, goal, parts=None):
    """NNLS for the shape weights; the displacement, its FP error, leak and weights.

    The own point is fitted along the axes some FAP governs (:func:`governed_axes`) and
    left free along the others: a stretched lip corner follows the face back in depth, as
    the sculpted stretch moves it, where holding its depth still made the fit puff the
    cheek out to push the corner forward again (the cheek moved 8 mm out of the face at a
    stretch of 150, the corner 7.4 mm). Each shape's weight is paid for
    (:data:`WEIGHT_COST`, a ridge on the non-negative least squares).
    """
    if a.shape[1] == 0:
        return {}, np.inf, np.inf, np.zeros(0)
    weights = np.where(bad, 1.0, 0.1)
    weights[k] = 3.0
    row_w = np.repeat(weights, 3)
    axes = governed_axes(ids[k])
    row_w[3 * k:3 * k + 3] *= axes
    target = np.zeros(3 * len(ids))
    target[3 * k:3 * k + 3] = goal
    # A unit weight costs as much as the own point (row weight 3) missing by WEIGHT_COST of the goal.
    cost = WEIGHT_COST * 3.0 * float(np.linalg.norm(goal))
    a_w = np.vstack([a * row_w[:, None], cost * np.eye(a.shape[1])])
    t_w = np.concatenate([target * row_w, np.zeros(a.shape[1])])
    w, _ = nnls(a_w, t_w, maxiter=2000)
    along = a[3 * k:3 * k + 3] @ w
    g = np.linalg.norm(goal)
    # Scale so the motion along the FAP's axis is exactly the target.
    proj = float(along @ goal) / g ** 2
    if proj <= 1e-9:
        return {}, np.inf, np.inf, w
    w = w / proj
    motion = (a @ w).reshape(-1, 3)
    err = float(np.linalg.norm((motion[k] - goal)[axes]) / g)
    leak = float(np.linalg.norm(motion[bad], axis=1).max(initial=0) / g)
    return combine_shapes(head, names, w, parts), err, leak, w


def _rotation_table(head: Head, n: int) -> FaceDefTable:
    fap = FAPS[n]
    axis = fap.axis_vector
    if n in (48, 49, 50):
        return FaceDefTable(n, transforms=[FaceDefTransform(None, "rotation", head.fp_position("7.1"), axis, 1.0)])
    part = "eye_l" if "_l_" in fap.name else "eye_r"
    if part not in head.parts or head.parts[part].centre is None:
        raise InputError(f"FAP {n} ({fap.name}) turns part '{part}', which the head lacks or has no rotation centre",
                         fix="give the eyeballs as parts eye_l/eye_r with centres")
    return FaceDefTable(n, transforms=[FaceDefTransform(part, "rotation", head.parts[part].centre, axis, 1.0)])


def _special(head: Head, n: int, value: float):
    """Pupil dilation (scale of the iris ring about the pupil) and tongue roll."""
    fap = FAPS[n]
    if fap.kind == "roll":  # tongue sides up: a falloff on 6.3 and 6.4 along +y
        unit = fap_unit(n, head.fapu)  # AU: the side lifts by the tongue's half width times the angle
        lift = {}
        for fp_id in fap.feature_points:
            half_width = abs(head.fp_position(fp_id)[0] - head.fp_position("6.2")[0])
            motion = np.array([0.0, half_width * value * unit, 0.0])
            for part, d in _falloff(head, fp_id, motion).items():
                lift[part] = lift[part] + d if part in lift else d
        return mesh_table(head, n, {1.0: lift}, value, unit), FapFit(n, "falloff")
    # Pupil dilation: the sculpted dilation shape, scaled so that at ``value`` the pupil's
    # diameter grows by value x IRISD (its rim moves by half that); negative values
    # constrict it along the same shape.
    side = "L" if "_l_" in fap.name else "R"
    shape = f"PupilDilate_{side}"
    if shape not in head.morph_targets:
        return None, FapFit(n, "none")
    unit = fap_unit(n, head.fapu)
    part = "eye_l" if side == "L" else "eye_r"
    d = head.morph_targets[shape].get(part)
    if d is None or not len(d.indices):
        return None, FapFit(n, "none")
    rim = float(np.linalg.norm(d.vectors, axis=1).max())
    w = 0.5 * value * unit / rim
    # The eyeball alone: the sculpted dilation also nudges the skin and gums (noise).
    disp = {part: d.scaled(w)}
    neg = {p: dd.scaled(-1.0) for p, dd in disp.items()}
    return mesh_table(head, n, {1.0: disp, -1.0: neg}, value, unit), FapFit(n, "shapes", weights={shape: w})
