"""The mesh brought to the MPEG-4 neutral frame: its unit, left-right, forward and up axes.

:func:`check_mesh` refuses what is not a surface; :func:`estimate_frame` finds the frame
from the geometry alone (the unit from the head's size, left-right as the best mirror
plane's normal, forward towards the narrowest cap, the nose; up where the slice beyond the
nose is the forehead's, not the chin's); :func:`refine_frame` turns it so that the found
feature points sit as the generic head's do (Umeyama).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import Head
from recon.shape.deform import fit_similarity

__all__ = ["UNITS", "AXES", "check_mesh", "Frame", "estimate_frame", "refine_frame", "unit_from_face", "FACE_EYES_M"]

#: Units a mesh may be in (metres per unit). Detection chooses among m, cm and mm.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}

#: Axis names for the up and forward flags.
AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}
_HEAD_SIZE = 0.3  # metres: a head with some neck, for choosing the unit
_UNIT_SLACK = 4.0  # a head (with or without neck and hair) is within this factor of _HEAD_SIZE
_NOSE_CAP = 0.015  # metres: depth of the cap in which the nose ends
_SLICE = 0.105  # metres beyond the nose: the forehead and skull above, under the chin below
_CLOSE_CALL = 0.03  # metres: up scores nearer than this leave it to the feature points
_NOT_A_NOSE = 0.8  # a narrowest end at least this share of the next one is no nose

#: The distance between the centres of an adult's eyes (each the midpoint of its corners,
#: 3.7-3.11 and 3.8-3.12), metres: 63 mm on the generic head, and adult pupils are 54-74 mm
#: apart. The face's proportions set a mesh's unit by it (:func:`unit_from_face`).
FACE_EYES_M = 0.063
#: A unit is taken when it puts the eyes within this factor of :data:`FACE_EYES_M` (a
#: child's or a stylised head's eyes too); units a factor of 10 apart cannot both be.
_EYES_SLACK = 2.0


def _axis_name(v: np.ndarray) -> str:
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "xyz"[k]


def _axis(name: str, flag: str) -> np.ndarray:
    if name not in AXES:
        raise InputError(f"unknown axis {name!r} for {flag}", fix=f"use one of {', '.join(AXES)}")
    return np.array(AXES[name], dtype=np.float64)


def _combined(head: Head):
    """All parts as one vertex and triangle array, and each triangle's part and local index."""
    names = list(head.parts)
    verts, tris, part_of, local = [], [], [], []
    offset = 0
    for k, n in enumerate(names):
        p = head.parts[n]
        verts.append(p.vertices)
        tris.append(p.triangles + offset)
        part_of.append(np.full(len(p.triangles), k))
        local.append(np.arange(len(p.triangles)))
        offset += p.n_vertices
    return (names, np.concatenate(verts), np.concatenate(tris).reshape(-1, 3),
            np.concatenate(part_of), np.concatenate(local))


def check_mesh(head: Head, where: str = "mesh") -> list[str]:
    """Refuse a mesh that is not a surface; warnings for small defects.

    Raises
    ------
    InputError
        No triangles; every triangle on its own (a triangle soup, unwelded); more than 1 %
        of the edges shared by three or more triangles (non-manifold); no area.

    Returns
    -------
    list of str
        Warnings (a few non-manifold edges, degenerate triangles).
    """
    _, v, t, _, _ = _combined(head)
    if not len(t):
        raise InputError("the mesh has no triangles", where=where, fix="export the head as a polygon mesh")
    area = 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)
    if not area.sum() > 0:
        raise InputError("the mesh has no area (all triangles are degenerate)", where=where,
                         fix="export the head's surface, not points or lines")
    warnings = []
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    shared = counts >= 2
    if len(t) >= 8 and not shared.any():
        raise InputError(f"none of the {len(t)} triangles shares an edge with another: the surface is a triangle "
                         "soup (unwelded vertices)", where=where,
                         fix="weld (merge) vertices by distance in the modelling tool and export again")
    many = counts > 2
    share = many.sum() / len(counts)
    if share > 0.01:
        raise InputError(f"{many.sum()} of {len(counts)} edges ({share:.0%}) are shared by three or more triangles: "
                         "the mesh is not a surface (non-manifold)", where=where,
                         fix="remove duplicate faces and internal geometry (e.g. Blender: Mesh > Clean Up), "
                             "then export again")
    if many.any():
        warnings.append(f"{many.sum()} non-manifold edges (shared by three or more triangles) were ignored")
    if (area <= 0).any():
        warnings.append(f"{int((area <= 0).sum())} degenerate triangles were ignored")
    return warnings


def _samples(head: Head, n: int = 20000, seed: int = 0) -> np.ndarray:
    """(n, 3) points spread over the surface by area (the mesh's density does not weigh in)."""
    _, v, t, _, _ = _combined(head)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(t), size=n, p=area / area.sum())
    r1, r2 = np.sqrt(rng.random(n)), rng.random(n)
    return (1 - r1)[:, None] * a[pick] + (r1 * (1 - r2))[:, None] * b[pick] + (r1 * r2)[:, None] * c[pick]


@dataclass
class Frame:
    """How a mesh file's coordinates map to the MPEG-4 neutral frame.

    ``neutral = scale * rotation @ file + offset``: metres, +x the face's left, +y up, +z
    towards the viewer.

    Attributes
    ----------
    rotation : (3, 3) float64
        Rows: the face's left, up and forward directions in file coordinates.
    scale : float
        Metres per file unit.
    offset : (3,) float64
        Metres.
    unit : str
        Name of the file's unit (a key of :data:`UNITS`).
    up, forward : str
        The file axes nearest the head's up and the face's forward direction (``"+z"`` ...).
    notes : list of str
        What was detected, given or assumed, one sentence each.
    nose : (3,) float64 or None
        Where the surface ends in the nose, neutral frame (the renders frame the head
        around it).
    close_call : bool
        Up was detected on weak evidence: :func:`mark` lets the feature points decide.
    """

    rotation: np.ndarray
    scale: float
    offset: np.ndarray
    unit: str
    up: str
    forward: str
    notes: list[str] = field(default_factory=list)
    nose: np.ndarray | None = None
    close_call: bool = False

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) float64 file → neutral similarity."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.offset
        return m

    def apply(self, points) -> np.ndarray:
        """(K, 3) neutral-frame metres of (K, 3) file coordinates."""
        return np.asarray(points, dtype=np.float64).reshape(-1, 3) @ (self.scale * self.rotation).T + self.offset

    def inverse(self, points) -> np.ndarray:
        """(K, 3) file coordinates of (K, 3) neutral-frame metres."""
        return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.offset) @ self.rotation / self.scale

    def turned(self, rotation: np.ndarray, offset: np.ndarray, note: str | None = None) -> Frame:
        """This frame followed by ``x -> rotation @ x + offset`` in the neutral frame."""
        r = rotation @ self.rotation
        notes = self.notes + ([note] if note else [])
        nose = None if self.nose is None else rotation @ self.nose + offset
        return Frame(r, self.scale, rotation @ self.offset + offset, self.unit, _axis_name(r[1]), _axis_name(r[2]),
                     notes, nose)

    def scaled(self, factor: float, unit: str, note: str) -> Frame:
        """This frame followed by a scaling of the neutral frame by ``factor`` about its
        origin (a new unit for the file, named ``unit``; the earlier unit's note replaced)."""
        notes = [n for n in self.notes if not n.startswith("unit:")] + [note]
        nose = None if self.nose is None else self.nose * factor
        return Frame(self.rotation, self.scale * factor, self.offset * factor, unit, self.up, self.forward, notes,
                     nose, self.close_call)


def unit_from_face(frame: Frame, points: Mapping[str, np.ndarray]) -> tuple[float, str, str] | None:
    """The mesh's unit read from the face's proportions: how far apart its eyes are.

    A mesh's size says little of its unit when it carries hair, a neck, shoulders or a body
    (a head-and-shoulders bust in its own units came out half a head's size); the eyes'
    distance varies far less between people. Among m, cm and mm, the unit that puts the
    eye centres (the midpoints of each eye's corners, 3.7-3.11 and 3.8-3.12) nearest
    :data:`FACE_EYES_M` apart is taken if within a factor of 2; failing all three (a model
    in its own units), the mesh is scaled so that they are that far apart.

    Parameters
    ----------
    frame : Frame
        The frame the points are in.
    points : mapping of str to (3,) float
        Feature points found on the mesh, ``frame``'s neutral coordinates, metres.

    Returns
    -------
    (factor, unit, note) or None
        The scaling of ``frame``'s neutral coordinates that makes them metres, the unit's
        name and a sentence saying why; None when the eyes' corners were not all found.
    """
    corners = ("3.7", "3.11", "3.8", "3.12")
    if not all(i in points for i in corners):
        return None
    p = {i: np.asarray(points[i], dtype=np.float64) for i in corners}
    eyes_file = float(np.linalg.norm(p["3.7"] + p["3.11"] - p["3.8"] - p["3.12"])) / 2 / frame.scale
    if not eyes_file > 0:
        return None
    unit = min(("m", "cm", "mm"), key=lambda u: abs(np.log(eyes_file * UNITS[u] / FACE_EYES_M)))
    if abs(np.log(eyes_file * UNITS[unit] / FACE_EYES_M)) <= np.log(_EYES_SLACK):
        metres = UNITS[unit]
        note = (f"unit: {unit} (from the face: its eyes are {eyes_file:.4g} units apart, "
                f"{eyes_file * metres * 1000:.0f} mm in {unit})")
    else:
        metres = FACE_EYES_M / eyes_file
        unit = f"{metres:.6g} m"
        note = (f"unit: none of m, cm, mm (the face's eyes are {eyes_file:.4g} units apart); scaled so that they are "
                f"{FACE_EYES_M * 1000:.0f} mm apart (give --unit if the file has one)")
    return metres / frame.scale, unit, note


def _mirror_residual(points: np.ndarray, normal: np.ndarray, tree) -> tuple[float, float]:
    """Mean distance from the points' mirror images (across the plane through their median
    along ``normal``) to the points themselves, and that plane's offset."""
    d = points @ normal
    c = float(np.median(d))
    mirrored = points - 2 * (d - c)[:, None] * normal
    dist, _ = tree.query(mirrored)
    return float(np.mean(dist)), c


def _cap_width(points: np.ndarray, direction: np.ndarray, lateral: np.ndarray, depth: float) -> float:
    """Spread across ``lateral`` (5th to 95th percentile) of the points within ``depth`` of the
    surface's end in ``direction``."""
    d = points @ direction
    cap = points[d > d.max() - depth]
    if len(cap) < 5:
        return 0.0
    x = cap @ lateral
    lo, hi = np.percentile(x, [5, 95])
    return float(hi - lo)


def estimate_frame(head: Head, unit: str | None = None, up: str | None = None, forward: str | None = None,
                   where: str = "mesh") -> Frame:
    """The neutral frame of a head mesh, from its shape and the flags given.

    Parameters
    ----------
    head : Head
        As the file has it.
    unit : str, optional
        A key of :data:`UNITS`; detected (m, cm or mm) from the head's size when None, and when
        none of them makes it head-sized (a model in its own units), scaled to a head's size.
    up, forward : str, optional
        File axes (``"+y"``, ``"-z"`` ...) of the head's up and the face's forward
        direction; detected when None.
    where : str
        The file, for messages.

    Returns
    -------
    Frame
        Axis-aligned to the file's nearest axes in the given directions, turned within the
        head's mirror plane; :func:`refine_frame` corrects small tilts once feature points
        are known.

    Raises
    ------
    InputError
        An unknown unit or axis; up and forward not at right angles; no direction in which
        the surface ends in a nose (not a head); a forward flag the nose contradicts (a head
        facing backwards).
    """
    from scipy.spatial import cKDTree

    notes = []
    pts = _samples(head)
    extent = float((pts.max(axis=0) - pts.min(axis=0)).max())
    if not extent > 0:
        raise InputError("the mesh has no extent (all its vertices at one place)", where=where,
                         fix="give a head mesh")
    if unit is None:
        unit = min(("m", "cm", "mm"), key=lambda u: abs(np.log(extent * UNITS[u] / _HEAD_SIZE)))
        if abs(np.log(extent * UNITS[unit] / _HEAD_SIZE)) > np.log(_UNIT_SLACK):
            # Neither metres, centimetres nor millimetres make it a head (a model in its own
            # units, e.g. CANDIDE's): scaled to a head's size, the feature points then set
            # its FAPU, which is all the animation needs.
            s = _HEAD_SIZE / extent
            notes.append(f"unit: none of m, cm, mm (the mesh is {extent:.4g} units across); scaled to a head "
                         f"{_HEAD_SIZE * 100:.0f} cm across (give --unit if the file has one)")
            unit = f"{s:.6g} m"
        else:
            notes.append(f"unit: {unit} (detected: the mesh is {extent:.4g} units across, "
                         f"{extent * UNITS[unit] * 100:.0f} cm in {unit})")
            s = UNITS[unit]
    elif unit not in UNITS:
        raise InputError(f"unknown unit {unit!r}", where=where, fix=f"use one of {', '.join(UNITS)}")
    else:
        notes.append(f"unit: {unit} (given)")
        s = UNITS[unit]
    pts = pts * s
    centre = pts.mean(axis=0)
    pts = pts - centre
    tree = cKDTree(pts)

    given_up = None if up is None else _axis(up, "--up")
    given_fwd = None if forward is None else _axis(forward, "--forward")
    if given_up is not None and given_fwd is not None and abs(given_up @ given_fwd) > 0.5:
        raise InputError(f"--up {up} and --forward {forward} are not at right angles", where=where,
                         fix="give two different axes, e.g. --up +z --forward -y")
    # Left-right: the normal of the best mirror plane, among the head's principal axes and
    # the file's axes (a mesh is usually near its file's axes; a head without a neck is as
    # deep as it is tall, which makes its principal axes in that plane arbitrary).
    if given_up is not None and given_fwd is not None:
        lateral = np.cross(given_up, given_fwd)
    else:
        _, _, vt = np.linalg.svd(pts[::4], full_matrices=False)
        candidates = list(vt) + [np.eye(3)[k] for k in range(3)]
        if given_up is not None:
            candidates = [c - (c @ given_up) * given_up for c in candidates if abs(c @ given_up) < 0.5]
        if given_fwd is not None:
            candidates = [c - (c @ given_fwd) * given_fwd for c in candidates if abs(c @ given_fwd) < 0.5]
        candidates = [c / np.linalg.norm(c) for c in candidates]
        lateral = min(candidates, key=lambda c: _mirror_residual(pts, c, tree)[0])
    res, plane = _mirror_residual(pts, lateral, tree)
    # Forward and up in the mirror plane: the file's axes there, or the flags.
    basis = [np.eye(3)[k] for k in np.argsort(-np.abs(np.eye(3) @ lateral))[1:]]
    basis = [b - (b @ lateral) * lateral for b in basis]
    basis = [b / np.linalg.norm(b) for b in basis]
    dirs, widths = [], []
    for d in (sgn * b for b in basis for sgn in (1.0, -1.0)):
        # A tilted face ends in its nose a little off the file's axis: look around it.
        side = np.cross(lateral, d)
        turned = [np.cos(a) * d + np.sin(a) * side for a in np.radians(np.arange(-15, 16, 5))]
        w = [_cap_width(pts, e, lateral, _NOSE_CAP) for e in turned]
        dirs.append(turned[int(np.argmin(w))])
        widths.append(min(w))
    order = np.argsort(widths)
    nose = dirs[order[0]]
    ratio = widths[order[0]] / max(widths[order[1]], 1e-12)
    if given_fwd is not None:
        f = given_fwd - (given_fwd @ lateral) * lateral
        f /= np.linalg.norm(f)
        if nose @ f < -0.5 and ratio < _NOT_A_NOSE:
            raise InputError(f"the head faces backwards for --forward {forward}: the surface ends in a nose "
                             f"towards {_axis_name(nose)}, and the view from {forward} shows the back of the head",
                             where=where, fix=f"give --forward {_axis_name(nose)}, or leave --forward out to "
                                              "detect it")
        notes.append(f"forward: {forward} (given)")
    else:
        if ratio > _NOT_A_NOSE:
            raise InputError(f"no face found: in no direction does the surface end in a nose (its narrowest end "
                             f"is {widths[order[0]] * 100:.1f} cm wide, the next {widths[order[1]] * 100:.1f} cm)",
                             where=where, fix="give a head mesh (a face with a nose), or --up and --forward")
        f = nose
        # (A low-poly nose may end in one vertex: a width of 0.)
        narrower = f"{1 / ratio:.1f}x narrower" if ratio > 0 else "narrower"
        notes.append(f"forward: {_axis_name(f)} (detected: the surface ends in a nose "
                     f"{widths[order[0]] * 100:.1f} cm wide that way, {narrower} than any other end)")
    if given_up is not None:
        u = given_up - (given_up @ f) * f
        u /= np.linalg.norm(u)
        notes.append(f"up: {up} (given)")
    else:
        u = np.cross(f, lateral)  # either sign; decided below
        u /= np.linalg.norm(u)
        # A hand's breadth above the nose the slice crosses the forehead and the skull: it
        # comes near the front and is deep; below, it crosses under the chin (the neck, or
        # nothing): far behind the nose and shallow.
        tip = pts[np.argmax(pts @ f)]
        score, said = [], []
        for sgn in (1.0, -1.0):
            h = (pts - tip) @ (sgn * u)
            band = pts[np.abs(h - _SLICE) < 0.01]
            if len(band) < 5:
                score.append(-np.inf)
                said.append("nothing")
                continue
            depth, gap = float(np.ptp(band @ f)), float(tip @ f - (band @ f).max())
            score.append(depth - gap)
            said.append(f"{depth * 100:.1f} cm deep, its front {gap * 100:.1f} cm behind the nose")
        close = abs(score[0] - score[1]) < _CLOSE_CALL
        if score[1] > score[0]:
            u, said = -u, said[::-1]
        notes.append(f"up: {_axis_name(u)} (detected: {_SLICE * 100:.1f} cm above the nose the head is {said[0]}; "
                     f"below it {said[1]})")
    left = np.cross(u, f)
    rot = np.stack([left, u, f])
    # The mirror plane at x = 0 (the plane's offset is along the lateral axis, which is
    # +-left); the rest centred on the samples.
    offset = -rot @ centre
    offset[0] = -(plane + centre @ lateral) * (left @ lateral)
    tip = pts[np.argmax(pts @ f)]
    frame = Frame(rot, s, offset, unit, _axis_name(u), _axis_name(f), notes, rot @ (tip + centre) + offset,
                  given_up is None and close)
    frame.notes.append(f"mirror plane found {res * 1000:.1f} mm from symmetric (mean)")
    return frame


def refine_frame(frame: Frame, points: Mapping[str, np.ndarray], weights: Mapping[str, float] | None = None,
                 generic: Head | None = None) -> tuple[Frame, float]:
    """The frame turned so that feature points sit as the generic head's do.

    Parameters
    ----------
    frame : Frame
    points : mapping of str to (3,)
        Feature points in ``frame``'s neutral coordinates, metres.
    weights : mapping of str to float, optional
        Per-point weights (confidences); 1 when None.
    generic : Head, optional
        The shipped generic head by default.

    Returns
    -------
    frame : Frame
        Rotated (and moved) by the weighted Umeyama similarity [1]_ from the points to the
        generic head's, without its scale (the mesh keeps its size).
    angle_deg : float
        How far it turned.
    """
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    g = generic.fp_positions()
    ids = [i for i in points if i in g and FEATURE_POINTS[i].group not in (6, 7) and not i.startswith("9.8")
           and i not in ("9.9", "9.10", "9.11") and (weights is None or weights.get(i, 0) > 0)]
    if len(ids) < 6:
        return frame, 0.0
    p = np.array([points[i] for i in ids])
    q = np.array([g[i] for i in ids])
    w = np.ones(len(ids)) if weights is None else np.array([max(weights[i], 1e-3) for i in ids])
    sim = fit_similarity(p, q, w)
    r, t, s = sim.rotation, sim.translation, sim.scale
    angle = float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))
    note = f"turned {angle:.1f} degrees to sit as the generic head (by {len(ids)} points)"
    return frame.turned(r, t / s, note), angle
