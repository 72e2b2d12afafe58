"""Feature points on any 3D head: ``fmc mark``.

A head from a sculpting tool, a scan or an asset store has no MPEG-4 feature points, and
comes in its own units and axes. :func:`mark` gives it both:

1. :func:`check_mesh` refuses what is not a surface (no faces, a triangle soup, edges
   shared by many triangles).
2. :func:`estimate_frame` brings the mesh to the MPEG-4 neutral frame (+x the face's left,
   +y up, +z towards the viewer, metres): the unit from the head's size (once the points
   are found, the face's proportions decide it: :func:`unit_from_face`), the left-right
   axis as the normal of the best mirror plane, the forward axis as the direction in which
   the surface ends in the narrowest cap (the nose), and up as the side where the slice a
   hand's breadth beyond the nose is deep and near the front (forehead and skull), not
   shallow and far behind (under the chin). Flags override each; a flag the geometry
   contradicts (a head facing backwards) is an error. When up is a close call, the head is
   also looked at the other way up and the feature points decide.
3. :func:`render_views` draws the head from the front and the left side with the
   project's renderer (orthographic, so each pixel is a ray along the view axis), framed
   on the head around the nose.
4. A 2D detector finds the feature points in the two renders: by default
   :func:`recon.landmarks.detect`, the same landmark and profile analysis as the photo
   annotation (:func:`landmark_detector`).
5. :func:`lift` casts each 2D point back onto the surface (trimesh ray queries): front
   points along the front ray, profile points where the side ray meets the mirror plane
   (on the mesh's midline cut), side-only points along the side ray (grazing rays take the
   rim they graze; their right partners mirrored and snapped), pupils on a separate
   eyeball at its front.
6. :func:`refine_frame` turns the frame so the points sit as the generic head's do (a
   Umeyama rotation), and the head is rendered and lifted once more in that frame.
7. :func:`find_parts` finds the eyes (the pieces the pupils' rays hit), teeth, gums and
   tongue (the pieces nearest the generic head's, brought onto the mesh by the points) by
   the points and the mesh's connectivity; roles a person gives (``--part ROLE=PART``,
   :func:`given_parts`) take their place.
8. :func:`fitted_points` fits the generic head's skin to the surface, following the
   points found on it (:func:`recon.shape.template_fit.fit_generic`: a similarity, then a
   thin-plate-spline field refined by non-rigid closest-point matching). A grey render
   shows no eyebrows, hairline or ear detail, so the points a detector can only guess
   there (:func:`untextured_guesses`) are the fitted generic head's, with lower
   confidences; the found points are smoothed by the fit as far as the detector says its
   noise needs (its ``give``). The guessed ear points then go to the ear's free rim
   (:func:`ears_by_outline`), and the inner lip contour's half-way points to where the
   standard puts them, halfway to the corners on the contour a front scan finds
   (:func:`inner_lip_halfway`).
9. :func:`hidden_points` places the points no view shows and no fit reached (teeth,
   tongue; 7.1 on a mesh without a skin) from the generic head.
10. :func:`check_points` checks that the points look like a face (the midline's vertical
   order, left points left of their partners, the FAPU's proportions, the pupils in the
   eye openings and on the eyeballs); a result that fails is still returned and written,
   its problems recorded in it and in the file (:mod:`recon.mark.checks`).

The result is an ``fdp.json`` that binds every point to the file's own vertices and says
how to bring the mesh to the neutral frame and name its parts
(:func:`mpeg4.io.fdp_json.place_mesh`), so that :func:`mpeg4.io.load_head` reads the mesh
as a head ready for cloning.

References
----------
.. [1] S. Umeyama, "Least-squares estimation of transformation parameters between two
   point patterns", IEEE TPAMI 13(4) (1991).
.. [2] I. S. Pandžić, R. Forchheimer (eds.), "MPEG-4 Facial Animation: The Standard,
   Implementation and Applications", Wiley (2002): the feature points.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import FeaturePointBinding, Head
from mpeg4.io.fdp_json import FdpFile, place_mesh
from recon.shape.deform import fit_similarity

from .checks import CHECKS, Problem, check_points
from .decimate import MAX_MARK_TRIANGLES, carry_back, decimate
from .ears import ears_by_outline
from .frame import AXES, UNITS, Frame, check_mesh, estimate_frame, refine_frame, unit_from_face
from .lift import Hit, _Surface, lift
from .parts import _inside_binding, check_given_parts, find_parts, given_parts, parse_part_options
from .points import fitted_points, hidden_points, inner_lip_halfway, lips_on_their_own_side, pupils_in_openings
from .views import Views, landmark_detector, render_views, untextured_guesses

__all__ = ["UNITS", "AXES", "Frame", "check_mesh", "estimate_frame", "refine_frame", "Views", "render_views",
           "landmark_detector", "untextured_guesses", "Hit", "lift", "find_parts", "given_parts", "check_given_parts",
           "parse_part_options",
           "unit_from_face", "fitted_points", "ears_by_outline", "inner_lip_halfway", "lips_on_their_own_side",
           "pupils_in_openings",
           "hidden_points",
           "Problem", "CHECKS", "check_points", "Marking", "mark", "mark_file", "load_mesh", "default_fdp_path",
           "MIN_POINTS", "MAX_MARK_TRIANGLES"]

#: Fewest front-view points the detector must find for the render to count as a face.
MIN_POINTS = 12


def default_fdp_path(mesh) -> Path:
    """``<mesh without extension>.fdp.json`` beside the mesh (where :func:`mpeg4.io.load_head` looks)."""
    mesh = Path(mesh)
    return mesh.with_suffix(".fdp.json")


def load_mesh(path) -> Head:
    """The mesh of a head file as the file has it (GLB, glTF, OBJ, PLY; no sidecar applied)."""
    from mpeg4.io import load_head

    return load_head(path, feature_points=False)


@dataclass
class Marking:
    """A marked mesh.

    Attributes
    ----------
    head : Head
        In the neutral frame, parts named (skin, eye_l ...), feature points bound.
    fdp : FdpFile
        What ``fmc mark`` writes: bindings to the file's vertices, 3D points, FAPU, frame,
        parts, and in ``metadata["mark3d"]`` the confidences, how each point was placed and
        (``"unreliable"``) the messages of the consistency checks the points fail.
    frame : Frame
    hits : dict of str to Hit
    notes : list of str
        What was detected or assumed.
    warnings : list of str
    problems : list of Problem
        The consistency checks the points fail (:func:`check_points`); empty when the
        result looks like a face. A result with problems is unreliable.
    """

    head: Head
    fdp: FdpFile
    frame: Frame
    hits: dict[str, Hit]
    notes: list[str]
    warnings: list[str]
    problems: list[Problem] = field(default_factory=list)

    @property
    def reliable(self) -> bool:
        """Whether the points pass every consistency check."""
        return not self.problems

    @property
    def confidence(self) -> dict[str, float]:
        return {i: h.confidence for i, h in self.hits.items()}


def _face_misfit(hits: Mapping[str, Hit]) -> float:
    """RMS distance (m) of the points from the generic head's after the best similarity
    (scaled to the generic head's size); infinite with too few points or eyes below the mouth."""
    from mpeg4.generic_head import load_generic_head

    if _upside_down(hits):
        return np.inf
    g = load_generic_head().fp_positions()
    ids = [i for i, h in hits.items() if i in g and h.confidence > 0 and FEATURE_POINTS[i].group not in (6, 7)]
    if len(ids) < 6:
        return np.inf
    p, q = np.array([hits[i].point for i in ids]), np.array([g[i] for i in ids])
    return float(np.sqrt(np.mean(np.sum((fit_similarity(p, q)(p) - q) ** 2, axis=1))))


def _upside_down(hits: Mapping[str, Hit]) -> bool:
    """Whether the eyes were found below the mouth."""
    eyes = [hits[i].point[1] for i in ("3.5", "3.6", "3.7", "3.12") if i in hits]
    mouth = [hits[i].point[1] for i in ("8.3", "8.4", "8.1", "8.2") if i in hits]
    return bool(eyes and mouth and np.mean(eyes) < np.mean(mouth))


def _detect(detect, views: Views, name: str, where: str) -> FdpFile:
    """The detector on the renders; what it says of a render is said of the mesh."""
    try:
        return detect(views)
    except InputError as e:
        raise InputError(f"no face found in the renders ({name}: {e.what})", where=where,
                         fix="check that the mesh is a head; give --up and --forward if its axes are unusual") from None


def mark(mesh, detect: Callable[[Views], FdpFile] | None = None, unit: str | None = None, up: str | None = None,
         forward: str | None = None, size: int = 1024, passes: int = 2, progress: Callable[[str], None] | None = None,
         where: str | None = None, max_triangles: int = MAX_MARK_TRIANGLES,
         parts: Mapping[str, str | None] | None = None) -> Marking:
    """Feature points on a head mesh (see the module docstring).

    Parameters
    ----------
    mesh : path or Head
        A head file (GLB, glTF, OBJ, PLY; read without any ``fdp.json`` beside it), or the
        mesh as read.
    detect : callable, optional
        ``detect(views) -> FdpFile`` with ``front`` and ``side`` pixels and confidences;
        :func:`landmark_detector` (the photo annotation's) when None. Optional attributes:
        ``detect.guessed(found) -> set`` of the points it can only guess on a grey render
        (placed from the shape instead), ``detect.give`` how far the generic head's shape
        may smooth its points (:func:`fitted_points`; 0, the points kept, when absent).
    unit, up, forward : str, optional
        See :func:`estimate_frame`. Without ``unit``, the unit the mesh's size suggests is
        checked against the face's proportions once the points are found, which decide
        (:func:`unit_from_face`).
    size : int
        Render height, pixels.
    passes : int
        1: points from the first renders; 2: the frame turned by those points, rendered and
        lifted again (true front and profile views for a tilted head).
    progress : callable, optional
        Called with a short message before each step.
    where : str, optional
        The file's name for messages.
    max_triangles : int
        A mesh with more triangles is marked on a decimated copy, the points then bound to
        the file's own triangles (:mod:`recon.mark.decimate`), which bounds the memory.
    parts : mapping of str to str or None, optional
        Roles a person gives: role (``teeth_upper``, ``eye_l`` ...) → the file's part that
        takes it whole, or None for none (:func:`given_parts`; ``--part ROLE=PART``).

    Returns
    -------
    Marking
        With ``problems``, the consistency checks the points fail (:func:`check_points`):
        an unreliable result is returned, and says so, rather than refused.

    Raises
    ------
    InputError
        Not a surface (:func:`check_mesh`), not a head or facing backwards
        (:func:`estimate_frame`), no face found in the renders, no detector.
    """
    say = progress or (lambda m: None)
    if isinstance(mesh, Head):
        raw, where = mesh, where or "mesh"
    else:
        raw, where = load_mesh(mesh), where or os.fspath(mesh)
    warnings = check_mesh(raw, where)
    if parts:
        check_given_parts(raw, parts)  # before the long work, not after it
    n = sum(len(p.triangles) for p in raw.parts.values())
    if n <= max_triangles:
        return _checked(_mark(raw, where, warnings, detect, unit, up, forward, size, passes, say, parts), say)
    say(f"decimating the mesh's {n} triangles to at most {max_triangles} for marking")
    small, dec = decimate(raw, max_triangles)
    result = _mark(small, where, warnings, detect, unit, up, forward, size, passes, say, parts)
    say("binding the points to the file's own triangles")
    head, bindings, parts = carry_back(result.head, dict(result.head.feature_points), result.fdp.parts, raw,
                                       result.frame.matrix, dec, where)
    fdp = result.fdp
    fdp.bindings, fdp.parts, fdp.points3d = dict(bindings), parts, head.fp_positions()
    try:
        fdp.fapu = head.fapu
    except InputError:
        fdp.fapu = None
    notes = result.notes + [f"marked on a copy decimated from {dec.triangles[0]} to {dec.triangles[1]} triangles"]
    fdp.metadata["mark3d"]["notes"] = notes
    head.metadata = dict(raw.metadata, mark3d={"reviewed": False})
    return _checked(Marking(head, fdp, result.frame, result.hits, notes, result.warnings), say)


def _checked(result: Marking, say: Callable[[str], None]) -> Marking:
    """The marking with the consistency checks its points fail, in ``problems`` and the file's metadata."""
    say("checking that the points look like a face")
    result.problems = check_points(result.head.fp_positions(), result.head)
    result.fdp.metadata["mark3d"]["unreliable"] = [p.message for p in result.problems]
    return result


def _mark(raw: Head, where: str, warnings: list[str], detect, unit, up, forward, size: int, passes: int,
          say: Callable[[str], None], given: Mapping[str, str | None] | None = None) -> Marking:
    """:func:`mark` on a mesh as read (and checked)."""
    say("finding the neutral frame")
    frame = estimate_frame(raw, unit, up, forward, where)
    detect = landmark_detector() if detect is None else detect
    name = getattr(detect, "__name__", type(detect).__name__)
    with tempfile.TemporaryDirectory(prefix="mark3d-") as tmp:
        head = place_mesh(raw, frame.matrix, None, where)
        for k in range(max(1, passes)):
            say(f"rendering the front and side views ({'first' if k == 0 else 'turned'} frame)")
            views = render_views(head, tmp, size, frame.matrix, frame.nose)
            say(f"finding the points in the renders ({name})")
            try:
                found = _detect(detect, views, name, where)
            except InputError:
                if k > 0 or up is not None:
                    raise
                # Upside down? A detector finds no face then: turn the head over once.
                say("no face found: trying the head the other way up")
                frame = frame.turned(np.diag([-1.0, -1.0, 1.0]), np.zeros(3),
                                     "turned over: no face was found the other way up")
                head = place_mesh(raw, frame.matrix, None, where)
                views = render_views(head, tmp, size, frame.matrix, frame.nose)
                found = _detect(detect, views, name, where)
            n_front = len(found.views.get("front").points) if "front" in found.views else 0
            if n_front < MIN_POINTS:
                raise InputError(f"no face found in the front render ({n_front} points, {name})", where=where,
                                 fix="check that the mesh is a head; give --up and --forward if its axes are unusual")
            surface = _Surface(head)
            hits = lift(head, views, found, surface)
            if k == 0 and (frame.close_call or _upside_down(hits)):
                # Up was a close call (or the eyes came out below the mouth): look at the head
                # the other way up too, and keep the way the points sit more like a face's.
                say("up is uncertain: looking at the head the other way up too")
                other = frame.turned(np.diag([-1.0, -1.0, 1.0]), np.zeros(3),
                                     "turned over: the points sit more like a face's that way up")
                o_head = place_mesh(raw, other.matrix, None, where)
                o_views = render_views(o_head, tmp, size, other.matrix, other.nose)
                try:
                    o_found = _detect(detect, o_views, name, where)
                except InputError:
                    o_found = None
                if o_found is not None:
                    o_surface = _Surface(o_head)
                    o_hits = lift(o_head, o_views, o_found, o_surface)
                    if _face_misfit(o_hits) < _face_misfit(hits):
                        frame, head, views, found, surface, hits = other, o_head, o_views, o_found, o_surface, o_hits
            if k + 1 < max(1, passes):
                frame, angle = refine_frame(frame, {i: h.point for i, h in hits.items()},
                                            {i: h.confidence for i, h in hits.items()})
                head = place_mesh(raw, frame.matrix, None, where)
        if unit is None:
            # The size suggested the unit; the face's proportions decide it.
            found_unit = unit_from_face(frame, {i: h.point for i, h in hits.items() if h.confidence > 0})
            if found_unit is not None and abs(np.log(found_unit[0])) > 1e-9:
                factor, name_u, note = found_unit
                say(note)
                frame = frame.scaled(factor, name_u, note)
                head = place_mesh(raw, frame.matrix, None, where)
                hits = {i: replace(h, point=h.point * factor) for i, h in hits.items()}
        say("finding the eyes, teeth, gums and tongue")
        parts, part_notes = find_parts(head, hits)
        if given:
            parts, part_notes = given_parts(head, parts, part_notes, given)
        head = place_mesh(raw, frame.matrix, parts, where)
        views = render_views(head, tmp, size, frame.matrix, frame.nose)
        found = _detect(detect, views, name, where)
    surface = _Surface(head)
    hits = lift(head, views, found, surface)
    say("fitting the generic head to the surface")
    guessed = getattr(detect, "guessed", None)
    hits = fitted_points(head, hits, set() if guessed is None else guessed(found), getattr(detect, "give", 0.0),
                         surface)
    hits = ears_by_outline(hits, surface)
    hits = inner_lip_halfway(head, hits, surface)
    hits = lips_on_their_own_side(head, hits, surface)
    hits = pupils_in_openings(head, hits, surface)
    hits = hidden_points(head, hits, surface=surface)
    bindings = {}
    for i, h in hits.items():
        if h.triangle < 0:
            part = head.parts.get(h.part)
            if part is not None:
                bindings[i] = _inside_binding(part, h.point)
            continue
        tri = head.parts[h.part].triangles[h.triangle]
        keep = h.weights > 1e-9
        w = h.weights[keep] / h.weights[keep].sum()
        bindings[i] = FeaturePointBinding(h.part, tuple(int(x) for x in tri[keep]), tuple(float(x) for x in w))
    head.feature_points = bindings
    fapu = None
    try:
        fapu = head.fapu
    except InputError as e:
        warnings.append(f"FAPU not measurable: {e.what}")
    notes = frame.notes + [f"frame: the file's unit is {frame.unit}, its up axis {frame.up}, the face looks along "
                           f"{frame.forward}"] + part_notes
    missing = [i for i in FP_IDS if i not in bindings]
    if missing:
        warnings.append(f"not placed: {', '.join(missing)}")
    head.metadata = dict(raw.metadata, mark3d={"reviewed": False})
    # The bindings name the placed head's parts, which the file's `parts` define.
    fdp = FdpFile(points3d=head.fp_positions(), bindings=dict(bindings), fapu=fapu,
                  frame=frame.matrix, parts=parts,
                  metadata={"mark3d": {"source": os.path.basename(where), "detector": name, "reviewed": False,
                                       "unit": frame.unit, "up": frame.up, "forward": frame.forward,
                                       "notes": notes, "warnings": warnings,
                                       "confidence": {i: round(h.confidence, 4) for i, h in hits.items()},
                                       "placed_by": {i: h.how for i, h in hits.items()}}})
    return Marking(head, fdp, frame, hits, notes, warnings)


def mark_file(mesh, out=None, detect=None, unit=None, up=None, forward=None, passes: int = 2,
              progress: Callable[[str], None] | None = None,
              parts: Mapping[str, str | None] | None = None) -> tuple[Path, Marking]:
    """``fmc mark``: mark a head mesh and write its ``fdp.json``.

    A file already at ``out`` is kept as ``out.bak`` before it is replaced (atomically).
    A result that fails the consistency checks is written too (to be put right in
    ``recon annotate``), its problems in ``metadata["mark3d"]["unreliable"]`` and in
    ``marking.problems``.

    Returns
    -------
    path : Path
        The ``fdp.json`` written (``<mesh>.fdp.json`` beside the mesh by default, where
        :func:`mpeg4.io.load_head` finds it).
    marking : Marking
    """
    from mpeg4.io.atomic import atomic_write
    from mpeg4.io.fdp_json import write_fdp_json

    out = default_fdp_path(mesh) if out is None else Path(out)
    if out.is_dir():
        raise InputError("expected a file name, found a folder", where=out, fix="give a name such as head.fdp.json")
    result = mark(mesh, detect=detect, unit=unit, up=up, forward=forward, passes=passes, progress=progress,
                  parts=parts)
    swapped = [p for p in result.problems if p.check == "left_right"]
    if swapped:
        # An fdp.json with the face's sides swapped is refused by every reader: say what to
        # do about the mesh rather than write a file nothing can open.
        raise InputError(f"the marked points have the face's sides swapped ({swapped[0].message}), so they are not "
                         f"written", where=os.fspath(mesh),
                         fix="the mesh may face the other way or be mirrored: mark it again with --forward (the "
                             "direction the face looks, e.g. --forward -z) or --up, or place the points by hand with "
                             f"recon annotate {os.fspath(mesh)}")
    if out.exists():
        backup = out.with_name(out.name + ".bak")
        with atomic_write(backup, "wb", permissions=out.stat().st_mode) as f:  # a private file's copy stays private
            f.write(out.read_bytes())
    write_fdp_json(out, result.fdp)
    return out, result
