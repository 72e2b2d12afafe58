"""Facial Motion Cloning: the source's morph targets and animation tables on another head.

:func:`correspond` matches the two heads once (the steps of the method, each its own
function in this package); the :class:`Correspondence` then carries any number of
morph targets across, and :func:`clone` does the whole job for a head's morph targets
and Facial Animation Tables.

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse

from mpeg4.catalogue import FAPS, FAPU_DEFINITIONS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import Head, SparseDisplacement
from mpeg4.surface import inverted_triangles

from ..unfold import unfold_tables, unfold_targets
from .align import align_heads, triangulation_for
from .calibrate import LIMITS, calibrate_tables
from .followers import JAW_ROLES, jaw_anchors, jaw_riders, surface_followers
from .parts import PART_ROLES, PartRef, find_parts, part_correspondence, transfer_part_motion
from .regions import face_scale, lip_sides, normalisation, region_scales
from .skin import pin_feature_points, skin_weights
from .space import SPACE_FPS, alignment_space

__all__ = ["REQUIRED_FPS", "check_head", "Correspondence", "correspond", "clone_targets", "clone"]

#: Feature points the method cannot do without: the FAPU and the alignment space.
REQUIRED_FPS = tuple(sorted({p for d in FAPU_DEFINITIONS.values() for p in (d.first, d.second)} | set(SPACE_FPS),
                            key=FP_IDS.index))


# Eye separation (ES0) of a head in metres lies well inside this range; outside it the
# head is in other units.
_ES0_RANGE = (0.03, 0.15)


def check_head(head: Head, name: str) -> None:
    """Raise :class:`InputError` if ``head`` lacks a feature point the method needs (all
    of them named) or is not in metres."""
    missing = [i for i in REQUIRED_FPS if i not in head.feature_points]
    if missing:
        raise InputError(f"the {name} head lacks the feature points {', '.join(missing)}, which cloning needs "
                         "(the FAPU and the alignment space)",
                         fix="place them (recon annotate, or in its fdp.json) before cloning")
    es = float(abs(head.fp_position("3.5")[0] - head.fp_position("3.6")[0]))
    lo, hi = _ES0_RANGE
    if not lo <= es <= hi:
        unit = "centimetres" if 100 * lo <= es <= 100 * hi else "millimetres" if 1000 * lo <= es <= 1000 * hi else None
        guess = f"; it looks like {unit}" if unit else ""
        factor = {"centimetres": "0.01", "millimetres": "0.001"}.get(unit, "the right factor")
        raise InputError(f"the {name} head's pupils are {es:.4g} units apart, not 0.03-0.15 m{guess}",
                         fix=f"give the head in metres (scale it by {factor})")


@dataclass
class Correspondence:
    """How every target vertex takes its motion from the source.

    Attributes
    ----------
    source, target : Head
    skin : scipy.sparse.csr_matrix
        (target skin vertices, source skin vertices) interpolation weights.
    source_scale, target_scale : (N, 3) float64
        Per-vertex normalisation of the two skins.
    parts : list of (PartRef, PartRef, scipy.sparse.csr_matrix)
        Source part, target part and their correspondence.
    support : float
        Anti-aliasing radius used (0: none, the default).
    warnings : list of str
        What the heads lack and what was done about it; :meth:`transfer` adds the
        source parts it had to leave out.
    unmatched : set of str
        Source parts the target has nothing for.
    followers : dict of str to scipy.sparse.csr_matrix
        Target parts the source has nothing for that lie on the skin
        (:func:`fmc.clone.followers.surface_followers`): (their vertices, target skin
        vertices) weights; they move as the skin under them.
    riders : tuple of str
        Target parts in a jaw role (:data:`fmc.clone.followers.JAW_ROLES`) the source has
        nothing for: they turn with the jaw (:func:`fmc.clone.followers.jaw_riders`).
    jaw : scipy.sparse.csr_matrix or None
        The target's jaw points on its skin (:func:`fmc.clone.followers.jaw_anchors`),
        when there are riders.
    """

    source: Head
    target: Head
    skin: sparse.csr_matrix
    source_scale: np.ndarray
    target_scale: np.ndarray
    parts: list[tuple[PartRef, PartRef, sparse.csr_matrix]] = field(default_factory=list)
    support: float = 0.0
    warnings: list[str] = field(default_factory=list)
    unmatched: set[str] = field(default_factory=set)
    followers: dict[str, sparse.csr_matrix] = field(default_factory=dict)
    riders: tuple[str, ...] = ()
    jaw: sparse.csr_matrix | None = None

    def transfer(self, targets: Mapping[str, Mapping[str, SparseDisplacement]], tol: float = 1e-7,
                 unfold: bool = False) -> dict[str, dict[str, SparseDisplacement]]:
        """The morph targets ``targets`` of the source (name → part → displacement, metres)
        on the target; vertices moving less than ``tol`` metres are left out. With
        ``unfold``, the folds the cloning adds are relaxed: a target whose skin motion turns
        a larger share of the target's triangles over than of the source's is relaxed
        (:func:`fmc.unfold.unfold_targets`) before the parts that follow the skin take
        theirs. (What folds after that is not warned of: on an ICT identity of the tests,
        the source's mesh, the jaw's opening still turns 47 triangles over where its source
        turns 32 of the generic head's, which says nothing a user can act on.)"""
        names = list(targets)
        n_s = self.source.skin.n_vertices
        left_out = sorted({p for t in targets.values() for p, d in t.items()
                           if p in self.unmatched and np.abs(d.vectors).max(initial=0) > 0})
        if left_out:
            note = f"the target has no {', '.join(left_out)}: their motion is left out"
            if note not in self.warnings:
                self.warnings.append(note)
        result: dict[str, dict[str, np.ndarray]] = {n: {} for n in names}
        for start in range(0, len(names), 32):  # a block at a time keeps the dense arrays small
            block = names[start:start + 32]
            motion = np.zeros((n_s, 3 * len(block)))
            for j, n in enumerate(block):
                if "skin" in targets[n]:
                    motion[:, 3 * j:3 * j + 3] = targets[n]["skin"].dense(n_s) / self.source_scale
            moved = self.skin @ motion
            skins = {n: moved[:, 3 * j:3 * j + 3] * self.target_scale for j, n in enumerate(block)}
            if unfold:
                allowed = self._source_folds({n: targets[n] for n in block})
                skins, _ = unfold_targets(self.target, skins, allowed)
            for n in block:
                result[n]["skin"] = skins[n]
                for part, w in self.followers.items():
                    result[n][part] = w @ result[n]["skin"]
                if self.jaw is not None:
                    result[n].update(jaw_riders(self.target, self.jaw, result[n]["skin"], self.riders))
        for s, t, w in self.parts:
            src_pts, tgt_pts = s.points(self.source), t.points(self.target)
            n_part = self.source.parts[s.part].n_vertices
            for n in names:
                d = targets[n].get(s.part)
                if d is None:
                    continue
                disp = d.dense(n_part)[s.vertices]
                if not np.abs(disp).max(initial=0) > 0:
                    continue
                out = result[n].setdefault(t.part, np.zeros((self.target.parts[t.part].n_vertices, 3)))
                out[t.vertices] = transfer_part_motion(src_pts, disp, s, tgt_pts, t, w)
        return {n: {p: SparseDisplacement.from_dense(v, tol=tol) for p, v in parts.items()} for n, parts in result.items()}

    def _source_folds(self, targets: Mapping[str, Mapping[str, SparseDisplacement]]) -> dict[str, float]:
        """Name → triangles of the target's skin a morph target may turn over: as large a
        share of them as it turns over of the source's skin."""
        s, t = self.source.skin, self.target.skin
        share = len(t.triangles) / max(len(s.triangles), 1)
        out = {}
        for n, d in targets.items():
            motion = d["skin"].dense(s.n_vertices) if "skin" in d else np.zeros((s.n_vertices, 3))
            out[n] = share * float(inverted_triangles(s.vertices, s.triangles, motion).sum())
        return out


def correspond(source: Head, target: Head, antialias: float | None = 0.0, triangulation: str = "mpeg4",
               alignment: str = "surface") -> Correspondence:
    """Match ``target`` to ``source``: the steps of the method up to the interpolation weights.

    Parameters
    ----------
    source, target : Head
        Both with the :data:`REQUIRED_FPS`, in metres.
    antialias : float, optional
        Radius of an anti-aliasing disc in the alignment space (Pandžić's: each target
        vertex takes the motion averaged over the disc, :func:`interpolation_matrix`); 0 or
        None, the default, for none. A sparse target needs none: the interpolation takes
        each vertex's motion at its own place, so a target re-meshed to a third gets at its
        vertices exactly what the full-density target gets there, and its own linear
        interpolation between vertices is the low-pass; averaging over a disc only blurs
        further. On an ICT identity re-meshed to a third, the disc that was the default
        (4 % of each vertex's edges) changed the error from 4.512 % to 4.502 %, discs of
        0.2 to 1 times the edges raised it to 5.0-14.6 %, and averaged samples of the
        ground truth itself carry it worse over the surface than its point samples (5.90 %
        and up against 5.77 %; the least-squares best, 4.95 %, sharpens rather than
        averages): ``benchmarks/clone_antialiasing.py``.
    triangulation : {"mpeg4", "delaunay"}
        The feature-point triangulation for the alignment (see :mod:`fmc.clone.align`).
    alignment : {"surface", "affine"}
        How the points between the feature points follow them (:func:`align_heads`).
    """
    check_head(source, "source")
    check_head(target, "target")
    notes: list[str] = []
    # 1. Normalisation.
    s_scale, t_scale = normalisation(source), normalisation(target)
    # 2. The alignment space.
    s_space, t_space = alignment_space(source, source.skin.vertices), alignment_space(target, target.skin.vertices)
    # 3. Feature-point alignment of both heads, half-way.
    tri, more = triangulation_for(source, target, triangulation)
    notes += more
    s_aligned, t_aligned, more = align_heads(source, target, tri, s_space, t_space, alignment)
    notes += more
    # 7. Parts (found first: pieces of the skin that are eyes or teeth leave the skin's step).
    s_parts, more = find_parts(source)
    notes += [f"source: {m}" for m in more]
    t_parts, more = find_parts(target)
    notes += [f"target: {m}" for m in more]
    # 6. Lips.
    s_lip, t_lip, more = lip_sides(source, target, s_space, t_space)
    notes += more
    # 5. Anti-aliasing: only when asked for (see the docstring's figures).
    support = float(antialias or 0.0)
    if not (np.isfinite(support) and support >= 0):
        raise InputError(f"anti-aliasing radius {antialias} is not a non-negative number",
                         fix="give 0 (none) or a radius in the alignment space, such as 0.01")
    # 4. Interpolation.
    skin = pin_feature_points(skin_weights(source, s_aligned, t_aligned[:, :2], t_aligned[:, 2], s_lip, t_lip,
                                           _in_skin(source, s_parts), _in_skin(target, t_parts), support),
                              source, target)
    pairs = [(s, t_parts[k], part_correspondence(source, s, target, t_parts[k]))
             for k, s in s_parts.items() if k in t_parts]
    unmatched = {s_parts[k].part for k in set(s_parts) - set(t_parts) if s_parts[k].part != "skin"}
    # Target parts with no source counterpart that lie on the skin (lids, brow and lash
    # cards, a beard) move with it; the rigid roles keep still without one.
    lone = [t_parts[k].part for k in set(t_parts) - set(s_parts) if k not in PART_ROLES and t_parts[k].part != "skin"]
    followers, more = surface_followers(target, sorted(lone))
    notes += more
    # The lower teeth and the tongue, if the source has none, turn with the jaw.
    riders = tuple(t_parts[k].part for k in JAW_ROLES
                   if k in t_parts and k not in s_parts and t_parts[k].part != "skin")
    jaw = jaw_anchors(target) if riders else None
    if jaw is None:
        riders = ()
    if riders:
        notes.append(f"the source has no {', '.join(riders)}: on the target they turn with the jaw")
    return Correspondence(source, target, skin, s_scale, t_scale, pairs, support, notes, unmatched, followers,
                          riders, jaw)


def _in_skin(head: Head, parts: Mapping[str, PartRef]) -> np.ndarray:
    """(N,) bool: skin vertices that belong to a part (an eyeball meshed with the skin)."""
    out = np.zeros(head.skin.n_vertices, bool)
    for p in parts.values():
        if p.part == "skin":
            out[p.vertices] = True
    return out


def clone_targets(source: Head, target: Head, names: Iterable[str] | None = None, antialias: float | None = 0.0,
                  triangulation: str = "mpeg4", alignment: str = "surface", unfold: bool = True
                  ) -> dict[str, dict[str, SparseDisplacement]]:
    """The source's morph targets cloned onto the target, each relaxed where it turns the
    target's skin over more than the source's (:func:`fmc.unfold.unfold_targets`, feature
    points held; MakeHuman's targets on the generic head, ``benchmarks/foreign_heads.py``:
    the jaw drop turned 356 triangles over and stretched an edge 197 times before, 220 and
    11.8 after; the smile and the happy face 139 and 165 before, none after).

    Parameters
    ----------
    source, target : Head
        Both with the :data:`REQUIRED_FPS`, in metres; the source with morph targets.
    names : iterable of str, optional
        Targets to clone (all by default).
    antialias, triangulation, alignment
        See :func:`correspond`.
    unfold : bool
        Relax each target's skin motion where it folds (default).

    Returns
    -------
    dict
        Target name → part → displacement, for the target head.
    """
    names = list(source.morph_targets if names is None else names)
    if not names:
        raise InputError("the source head has no morph targets to clone", fix="give a source with motion")
    unknown = [n for n in names if n not in source.morph_targets]
    if unknown:
        raise InputError(f"the source head has no morph targets {', '.join(unknown)}",
                         fix=f"choose from {', '.join(sorted(source.morph_targets)[:8])} ...")
    corr = correspond(source, target, antialias=antialias, triangulation=triangulation, alignment=alignment)
    return corr.transfer({n: source.morph_targets[n] for n in names}, unfold=unfold)


def _unit_correction(source: Head, target: Head, fap: int) -> np.ndarray:
    """(3,) per-axis factor making a cloned table of low-level ``fap`` move its feature
    point by the target's own FAP unit.

    A table's displacements are per FAP unit (reference section 5): the FP must move by
    the same multiple of the target's unit as of the source's. The region normalisation
    scales by the region's FAPU instead (e.g. the lids' IRISD0 against the region's
    ENS0); this factor is the ratio of the two at the FP. Angle units (AU) need none,
    but for the tongue roll, a mesh table: its lift is the angle times the tongue's half
    width, so that ratio replaces the region's in y.
    """
    entry = FAPS[fap]
    if fap < 3 or not entry.unit:
        return np.ones(3)
    fp = entry.feature_points[0]
    if fp not in source.feature_points or fp not in target.feature_points:
        return np.ones(3)
    # The scale the cloning used at the FP (parts inside the head take their region's).
    scales = [region_scales(h, h.fp_position(fp)[None])[0] for h in (source, target)]
    if entry.kind == "roll":
        # An angle: the sides lift by the angle times the tongue's half width (6.3 to 6.2).
        if "6.2" not in source.feature_points or "6.2" not in target.feature_points:
            return np.ones(3)
        half = [abs(h.fp_position(fp)[0] - h.fp_position("6.2")[0]) for h in (source, target)]
        return np.r_[1.0, (half[1] / half[0]) / (scales[1][1] / scales[0][1]), 1.0]
    if entry.unit == "AU":
        return np.ones(3)
    units = source.fapu.unit(entry.unit), target.fapu.unit(entry.unit)
    return (units[1] / units[0]) / (scales[1] / scales[0])


def clone(source: Head, target: Head, antialias: float | None = 0.0, triangulation: str = "mpeg4",
          alignment: str = "surface", unfold: bool = True) -> tuple[Head, list[str]]:
    """The target with the source's morph targets and Facial Animation Tables cloned onto it.

    A target whose mesh joins its lips (:func:`fmc.clone.seal.sealed_mouth`) is first
    ripped open along its lip line, so that the jaw can part them; a warning says so.

    Morph targets keep their names. The FAT's mesh tables travel as morph targets
    (:func:`mpeg4.fat.fat_to_morph_targets`, in the source's FAPU), are cloned, scaled per
    FAP so its feature point moves by the target's FAP unit, and rebuilt in the target's
    FAPU; its transforms are re-centred on the target: the eyes about the target's eye
    centres, the head about the target's 7.1 (both installed when the target has none).
    Each cloned low-level table is then scaled so that its own feature point moves by
    value × FAPU on the target (:func:`fmc.clone.calibrate.calibrate_tables`; a warning
    lists those whose point moves too far off to be scaled), and unfolded on the target's mesh (:func:`fmc.unfold.unfold_tables`):
    on the example's head, over the real streams of ``benchmarks/fap_conformance.py``, the
    longest stretched edge went from 13.9 times its length to 5.7 and the most triangles
    turned over from 88 to 75, for about 4 s.

    Parameters
    ----------
    source, target : Head
    antialias, triangulation, alignment
        See :func:`correspond`.
    unfold : bool
        Relax the cloned tables and morph targets where they turn the target's skin over
        (:func:`fmc.unfold.unfold_tables`, :func:`fmc.unfold.unfold_targets`). (The tables'
        regions' motion is not capped again, :mod:`fmc.bound`: where the cloning put a point
        off its motion the cap squeezed the region, the MediaPipe mask's longest edge 5.7 → 8.3.)

    Returns
    -------
    head : Head
    warnings : list of str
        What the target lacks and what was done about it.
    """
    from mpeg4.fat import FAT, FaceDefTable, FaceDefTransform, fat_from_morph_targets, fat_to_morph_targets

    from .seal import rip_mouth

    target, ripped = rip_mouth(target)
    targets = dict(source.morph_targets)
    specs, fat_targets = [], {}
    if source.fat is not None and len(source.fat):
        fat_targets, specs = fat_to_morph_targets(source.fat, source.fapu)
        targets.update(fat_targets)
    has_transforms = source.fat is not None and any(t.transforms for t in source.fat.values())
    moving = any(np.abs(d.vectors).max(initial=0) > 0 for t in targets.values() for d in t.values())
    if not moving and not has_transforms:
        raise InputError("the source head has no morph targets or animation tables to clone"
                         + (" (its morph targets move nothing)" if targets else ""),
                         fix="give a source with motion (fmc author, or a GLB with morph targets)")
    corr = correspond(source, target, antialias=antialias, triangulation=triangulation, alignment=alignment)
    # The morph targets are unfolded whole; the tables' pieces later, as tables.
    own = {n: d for n, d in targets.items() if n not in fat_targets}
    cloned = corr.transfer(own, unfold=unfold) if own else {}
    if fat_targets:
        cloned.update(corr.transfer(fat_targets))
    warnings = list(corr.warnings)
    if ripped:
        warnings.append(f"the mesh joins the lips, so the jaw could not part them: the mouth was opened along its "
                        f"line ({ripped} vertices duplicated; 2.3, 2.8 and 2.9 put on the lower lip's side)")
    out = target.copy()
    out.morph_targets = {n: cloned[n] for n in source.morph_targets}
    if source.fat is not None and len(source.fat):
        s_parts = {p.part: p for p, _, _ in corr.parts}
        t_of = {p.part: t for p, t, _ in corr.parts}
        turns_head = any(t.part is None for table in source.fat.values() for t in table.transforms)
        centre_71 = _head_centre(source, target, warnings) if turns_head else None
        transforms = FAT()
        for key, table in source.fat.items():
            moved = []
            for t in table.transforms:
                if t.part is None:
                    if centre_71 is None:
                        continue
                    moved.append(FaceDefTransform(None, t.kind, centre_71, t.axis, t.amount))
                    continue
                if t.part not in s_parts or t.part not in t_of or t_of[t.part].part == "skin":
                    warnings.append(f"FAP {key[0]}: the target has no part for '{t.part}'; its {t.kind} is left out")
                    continue
                src, dst = s_parts[t.part], t_of[t.part]
                # The centre kept where it is relative to the part's own (an eyeball turns
                # about its centre; a pupil would scale about a point in front of it).
                centre = dst.centre + (t.centre - src.centre) / src.scale * dst.scale
                moved.append(FaceDefTransform(dst.part, t.kind, centre, t.axis, t.amount))
            transforms.add(FaceDefTable(table.fap, table.high_level, [], moved))
        fat_targets, factors = {}, {}
        for s in specs:
            if s.fap not in factors:
                factors[s.fap] = _unit_correction(source, target, s.fap) if s.fap > 2 else np.ones(3)
            k = factors[s.fap]
            fat_targets[s.target] = {p: SparseDisplacement(d.indices, d.vectors * k) for p, d in cloned[s.target].items()}
        out.fat = fat_from_morph_targets(fat_targets, specs, target.fapu, transforms)
        for key, table in transforms.items():
            if key not in out.fat:
                out.fat.add(table)
        out.fat, off = calibrate_tables(out)
        if off:
            warnings.append(f"{len(off)} cloned FAPs move their point on the target further from value × FAPU "
                            f"than the {1 / LIMITS[1]:.2f}–{1 / LIMITS[0]:.2f} times that can be scaled away, and were "
                            "left as cloned (FAP: times value × FAPU: "
                            + ", ".join(f"{n}: {1 / f:.2f}" if f > 0 else f"{n}: the wrong way"
                                        for n, f in sorted(off.items())) + ")")
        if unfold:
            out.fat, _ = unfold_tables(out)
    out.metadata = dict(out.metadata, cloned_from=str(source.metadata.get("name", "source head")))
    return out, sorted(set(warnings))


def _head_centre(source: Head, target: Head, warnings: list[str]) -> np.ndarray | None:
    """The target's head rotation centre 7.1; installed from the source's when missing."""
    if "7.1" in target.feature_points:
        return target.fp_position("7.1")
    if "7.1" not in source.feature_points:
        warnings.append("neither head has 7.1 (the head rotation centre): head rotations are left out")
        return None
    # The source's 7.1 relative to the two pupils' midpoint, in the upper face's FAPU terms.
    o_s = 0.5 * (source.fp_position("3.5") + source.fp_position("3.6"))
    o_t = 0.5 * (target.fp_position("3.5") + target.fp_position("3.6"))
    c = o_t + (source.fp_position("7.1") - o_s) / face_scale(source) * face_scale(target)
    warnings.append("the target has no 7.1 (the head rotation centre): installed at "
                    + ", ".join(f"{x * 1000:.1f}" for x in c) + " mm, placed as on the source")
    return c
