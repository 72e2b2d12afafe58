"""Feature points on any 3D head: ``fmc mark`` and ``recon mark3d``.

A head from a sculpting tool, a scan or an asset store has no MPEG-4 feature points, and
comes in its own units and axes. :func:`mark` gives it both:

1. :func:`check_mesh` refuses what is not a surface (no faces, a triangle soup, edges
   shared by many triangles).
2. :func:`estimate_frame` brings the mesh to the MPEG-4 neutral frame (+x the face's left,
   +y up, +z towards the viewer, metres): the unit from the head's size, the left-right
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
7. :func:`find_parts` finds the eyes (the pieces the pupils' rays hit), teeth and tongue
   (the pieces inside the mouth) by the points and the mesh's connectivity.
8. :func:`fitted_points` fits the generic head's skin to the surface, following the
   points found on it (:func:`recon.shape.template_fit.fit_generic`: a similarity, then a
   thin-plate-spline field refined by non-rigid closest-point matching). A grey render
   shows no eyebrows, hairline or ear detail, so the points a detector can only guess
   there (:func:`untextured_guesses`) are the fitted generic head's, with lower
   confidences; the found points are smoothed by the fit as far as the detector says its
   noise needs (its ``give``).
9. :func:`hidden_points` places the points no view shows and no fit reached (teeth,
   tongue; 7.1 on a mesh without a skin) from the generic head.

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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import FeaturePointBinding, Head
from mpeg4.io.fdp_json import FdpFile, PartSource, place_mesh

from recon.shape.deform import fit_similarity

__all__ = ["UNITS", "AXES", "Frame", "check_mesh", "estimate_frame", "refine_frame", "Views", "render_views",
           "landmark_detector", "untextured_guesses", "Hit", "lift", "find_parts", "fitted_points", "hidden_points",
           "Marking", "mark", "mark_file", "load_mesh", "default_fdp_path", "MIN_POINTS"]

#: Units a mesh may be in (metres per unit). Detection chooses among m, cm and mm.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
#: Axis names for the up and forward flags.
AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}
#: Fewest front-view points the detector must find for the render to count as a face.
MIN_POINTS = 12

_HEAD_SIZE = 0.3  # metres: a head with some neck, for choosing the unit
_NOSE_CAP = 0.015  # metres: depth of the cap in which the nose ends
_SLICE = 0.105  # metres beyond the nose: the forehead and skull above, under the chin below
_CLOSE_CALL = 0.03  # metres: up scores nearer than this leave it to the feature points
_NOT_A_NOSE = 0.8  # a narrowest end at least this share of the next one is no nose
# Points a photo shows by colour or the face's oval, not by the shape a render shows.
_TEXTURE_POINTS = ("2.10", "2.11", "2.12", "2.13", "2.14", "11.1", "11.2", "11.3", "11.5")
# How far the generic head's shape may overrule recon.landmarks' points on a render
# (template_fit.fit_generic's give): best of 1e-4, 1e-3, 1e-2 on ICT identities 20-27,
# which the benchmark (0-19) does not use.
_LANDMARK_GIVE = 1e-3
_SKIN, _WHITE, _PINK = (0.86, 0.68, 0.56), (0.92, 0.92, 0.9), (0.75, 0.4, 0.42)


def _axis_name(v: np.ndarray) -> str:
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "xyz"[k]


def _axis(name: str, flag: str) -> np.ndarray:
    if name not in AXES:
        raise InputError(f"unknown axis {name!r} for {flag}", fix=f"use one of {', '.join(AXES)}")
    return np.array(AXES[name], dtype=np.float64)


# --- the mesh ------------------------------------------------------------------------------

def default_fdp_path(mesh) -> Path:
    """``<mesh without extension>.fdp.json`` beside the mesh (where :func:`mpeg4.io.load_head` looks)."""
    mesh = Path(mesh)
    return mesh.with_suffix(".fdp.json")


def load_mesh(path) -> Head:
    """The mesh of a head file as the file has it (GLB, glTF, OBJ, PLY; no sidecar applied)."""
    from mpeg4.io import load_head

    return load_head(path, feature_points=False)


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


# --- the frame -----------------------------------------------------------------------------

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
        A key of :data:`UNITS`; detected (m, cm or mm) from the head's size when None.
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
    if unit is None:
        unit = min(("m", "cm", "mm"), key=lambda u: abs(np.log(extent * UNITS[u] / _HEAD_SIZE)))
        notes.append(f"unit: {unit} (detected: the mesh is {extent:.4g} units across, "
                     f"{extent * UNITS[unit] * 100:.0f} cm in {unit})")
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
        notes.append(f"forward: {_axis_name(f)} (detected: the surface ends in a nose "
                     f"{widths[order[0]] * 100:.1f} cm wide that way, {1 / ratio:.1f}x narrower than any other end)")
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


# --- rendering -----------------------------------------------------------------------------

@dataclass
class Views:
    """The front and left-side renders of a head in the neutral frame.

    Attributes
    ----------
    images : dict of str to (H, W, 3) uint8
    depth : dict of str to (H, W) float64
    cameras : dict of str to Camera
        Orthographic: each pixel is a ray along the view axis.
    paths : dict of str to Path
        The images as PNG files (what a photo detector reads).
    frame : (4, 4) float64
        File → render-world (neutral) similarity, so that points known in the file's
        coordinates can be projected (:func:`recon.evaluate.synthetic.perfect_detector`).
    """

    images: dict
    depth: dict
    cameras: dict
    paths: dict
    frame: np.ndarray


def render_views(head: Head, folder, size: int = 1024, frame: np.ndarray | None = None,
                 focus: np.ndarray | None = None) -> Views:
    """Front and left-side renders of a head in the neutral frame, written as PNGs to ``folder``.

    Orthographic, lit from above the viewer's left shoulder; untextured parts in the
    default grey are drawn in a skin tone (eyes and teeth white).

    Parameters
    ----------
    head : Head
        In the neutral frame, metres.
    folder : path
        Where ``front.png`` and ``side.png`` go.
    size : int
        Image height in pixels (the width is 4/5 of it, like a portrait photo).
    frame : (4, 4) float, optional
        File → neutral similarity the head was moved by (kept in the result).
    focus : (3,) float, optional
        The nose tip, neutral frame: the views frame the head from 13 cm below it to 15 cm
        above (not the shoulders); everything when None.
    """
    from PIL import Image

    from mpeg4.preview import head_meshes
    from mpeg4.render import Camera, render

    folder = Path(folder)
    meshes = head_meshes(head)
    # An untextured mesh in the renderer's default grey is drawn in a skin tone (eyes and
    # teeth white, the tongue pink): photo detectors look for skin.
    for name, m in zip(head.parts, meshes):
        if m.texture is None and np.allclose(m.colour, 0.8):
            m.colour = (_WHITE if name.startswith(("eye", "teeth")) else _PINK if name.startswith("tongue")
                        else _SKIN)
    allv = np.concatenate([p.vertices for p in head.parts.values()])
    if focus is not None:
        near = allv[(allv[:, 1] > focus[1] - 0.13) & (allv[:, 1] < focus[1] + 0.15)]
        allv = near if len(near) >= 100 else allv
    out = Views({}, {}, {}, {}, np.eye(4) if frame is None else np.asarray(frame, dtype=np.float64))
    w = int(round(size * 0.8))
    for name, yaw in (("front", 0.0), ("side", 90.0)):
        cam = Camera.fit(allv, w, size, yaw_deg=yaw, margin=0.04)
        img, depth = render(meshes, cam, background=(0.86, 0.87, 0.89), return_depth=True, samples=4,
                            ambient=0.42, light=(-0.35, 0.45, 1.0))
        path = folder / f"{name}.png"
        Image.fromarray(img).save(path)
        out.images[name], out.depth[name], out.cameras[name], out.paths[name] = img, depth, cam, path
    return out


def landmark_detector() -> Callable[[Views], FdpFile]:
    """The photo annotation's detector (:func:`recon.landmarks.detect`) applied to the renders.

    The detector carries ``guessed`` (:func:`untextured_guesses`) and ``give`` (how far
    the generic head fitted to the surface may smooth its points; measured on ICT
    identities that ``benchmarks/mark3d_accuracy.py`` does not use) for :func:`mark`.

    Raises
    ------
    InputError
        When recon.landmarks is not installed, or the models it runs (mediapipe) are not.
    """
    from recon.landmarks import detector

    detect, why = detector()
    if detect is None:
        raise InputError(f"no 2D landmark detector: {why}", where="fmc mark",
                         fix="run bash install.sh, or place the points by hand: recon annotate MESH")

    def run(views: Views) -> FdpFile:
        return detect(os.fspath(views.paths["front"]), os.fspath(views.paths["side"]))

    run.__name__ = "recon.landmarks.detect"
    run.guessed = untextured_guesses
    run.give = _LANDMARK_GIVE
    return run


def untextured_guesses(found: FdpFile) -> set[str]:
    """The points a photo detector can only guess on the render of an untextured mesh.

    Those a photo shows by colour, which a grey render does not have: the eyebrows (4.x),
    the hairline and the hair (11.1-11.3, 11.5); those the face mesh guesses from the
    face's oval, not from anything it sees (the chin boss and corners, the jaw angles
    2.10-2.14, the cheeks 5.x); and whatever :func:`recon.landmarks.detect` found in the
    front view by the silhouette or by rule rather than by its face mesh (the ears, the top
    of the skull). :func:`fitted_points` places them from the shape instead.
    """
    source = (found.metadata.get("landmarks") or {}).get("source", {}).get("front", {})
    out = {i for i in FP_IDS if FEATURE_POINTS[i].group in (4, 5) or i in _TEXTURE_POINTS}
    return out | {i for i, s in source.items() if s != "model"}


# --- lifting -------------------------------------------------------------------------------

@dataclass
class Hit:
    """A feature point on the surface.

    Attributes
    ----------
    point : (3,) float64
        Neutral frame, metres.
    part : str
    triangle : int
        In the part.
    weights : (3,) float64
        Barycentric weights of the triangle's corners.
    confidence : float
        In [0, 1].
    how : str
        Which rule placed it (``front ray``, ``profile``, ``side ray``, ``mirrored``,
        ``eye front``; after :func:`fitted_points` ``fitted`` for a found point smoothed by
        the fitted generic head and ``shape`` for the fitted generic head's own; ``teeth``,
        ``tongue``, ``generic``).
    """

    point: np.ndarray
    part: str
    triangle: int
    weights: np.ndarray
    confidence: float
    how: str


class _Surface:
    """Ray and closest-point queries on all parts of a head (trimesh, built once)."""

    def __init__(self, head: Head):
        import trimesh

        self.names, v, t, self.part_of, self.local = _combined(head)
        self.mesh = trimesh.Trimesh(v, t, process=False, validate=False)
        self.vertices, self.triangles = v, t

    def cast(self, origins: np.ndarray, directions: np.ndarray, radius: float = 0.001):
        """First hit of each ray: (K,) triangle (−1 for none) and (K, 3) locations.

        A ray that passes within ``radius`` of the surface before it hits it (a point on a
        silhouette, such as the rim of an ear, seen edge-on) takes the surface point
        nearest to where it passes closest.
        """
        from scipy.spatial import cKDTree

        tri = np.full(len(origins), -1, dtype=np.int64)
        loc = np.full((len(origins), 3), np.nan)
        if not len(origins):
            return tri, loc
        t, r, p = self.mesh.ray.intersects_id(origins, directions, multiple_hits=False, return_locations=True)
        tri[r], loc[r] = t, p
        if radius <= 0:
            return tri, loc
        if not hasattr(self, "_tree"):
            self._tree = cKDTree(self.vertices)
        reach = 4 * radius  # vertices this near the ray may carry a face nearer than radius
        for k in range(len(origins)):
            o, d = origins[k], directions[k] / np.linalg.norm(directions[k])
            far = np.inf if tri[k] < 0 else float((loc[k] - o) @ d)
            # The stretch of the ray inside the mesh's bounding sphere, up to the hit.
            mid = float((self.mesh.bounds.mean(axis=0) - o) @ d)
            half = 0.5 * float(np.linalg.norm(self.mesh.extents))
            stretch = np.arange(max(mid - half, 0.0), min(far, mid + half) + reach, reach)
            steps = o + np.outer(stretch, d)
            near = set()
            for ids in self._tree.query_ball_point(steps, 1.5 * reach):
                near.update(ids)
            if not near:
                continue
            ids = np.fromiter(near, dtype=np.int64)
            rel = self.vertices[ids] - o
            along = rel @ d
            off = np.linalg.norm(rel - np.outer(along, d), axis=1)
            ok = (off < reach) & (along < far - 2 * radius)
            if not ok.any():
                continue
            # Along the stretch where the ray passes those vertices, how near is the surface?
            a = along[ok]
            t_near = np.arange(max(a.min() - reach, 0.0), min(a.max() + reach, far - 2 * radius), radius / 2)
            if not len(t_near):
                continue
            c_tri, c_pt = self.closest(o + np.outer(t_near, d))
            gap = np.linalg.norm(c_pt - (o + np.outer(t_near, d)), axis=1)
            close = np.flatnonzero(gap < radius)
            if len(close):
                tri[k], loc[k] = c_tri[close[0]], c_pt[close[0]]
        return tri, loc

    def on_midline(self, points: np.ndarray):
        """Nearest point of the mesh's cut by the plane x = 0 (the profile curve) to each of
        (K, 3) points on that plane: (K,) triangles, (K, 3) points; the closest surface
        point where nothing crosses the plane."""
        import trimesh

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        try:
            seg, faces = trimesh.intersections.mesh_plane(self.mesh, [1.0, 0.0, 0.0], [0.0, 0.0, 0.0],
                                                          return_faces=True)
        except (ValueError, IndexError):
            seg = np.zeros((0, 2, 3))
        if not len(seg):
            return self.closest(points)
        a, b = seg[:, 0, 1:], seg[:, 1, 1:]  # (y, z) of each piece of the profile
        ab = b - a
        tri = np.empty(len(points), dtype=np.int64)
        out = np.empty_like(points)
        for k, q in enumerate(points[:, 1:]):
            s = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30), 0, 1)
            near = a + s[:, None] * ab
            j = int(np.argmin(np.sum((near - q) ** 2, axis=1)))
            tri[k], out[k] = faces[j], np.r_[seg[j, 0, 0] + s[j] * (seg[j, 1, 0] - seg[j, 0, 0]), near[j]]
        return tri, out

    def closest(self, points: np.ndarray, parts: list[str] | None = None):
        """Closest surface point (of the given parts) to each point: (K,) triangles, (K, 3) points."""
        import trimesh

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if parts is None:
            p, _, tri = trimesh.proximity.closest_point(self.mesh, points)
            return np.asarray(tri, dtype=np.int64), p
        keep = np.flatnonzero(np.isin(self.part_of, [self.names.index(n) for n in parts]))
        sub = trimesh.Trimesh(self.vertices, self.triangles[keep], process=False, validate=False)
        p, _, tri = trimesh.proximity.closest_point(sub, points)
        return keep[np.asarray(tri, dtype=np.int64)], p

    def piece_of(self, h: Hit) -> np.ndarray:
        """Vertex ids (into all parts) of the connected piece a hit lies on."""
        if not hasattr(self, "_labels"):
            self._labels = _pieces(type("P", (), {"n_vertices": len(self.vertices), "triangles": self.triangles})())
        return np.flatnonzero(self._labels == self._labels[self.triangles[self.index(h)][0]])

    def index(self, h: Hit) -> int:
        """The hit's triangle among all parts'."""
        k = self.names.index(h.part)
        return int(np.flatnonzero((self.part_of == k) & (self.local == h.triangle))[0])

    def hit(self, tri: int, point: np.ndarray, confidence: float, how: str) -> Hit:
        import trimesh

        corners = self.vertices[self.triangles[tri]]
        w = trimesh.triangles.points_to_barycentric(corners[None], np.asarray(point)[None])[0]
        w = np.clip(w, 0.0, None)
        w /= w.sum()
        return Hit(w @ corners, self.names[self.part_of[tri]], int(self.local[tri]), w, float(confidence), how)


def _rays(camera, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origins (on the camera's plane) and directions of an orthographic camera's pixel rays."""
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    cx, cy = camera.principal
    local = np.c_[(pixels[:, 0] - cx) / camera.scale_px, -(pixels[:, 1] - cy) / camera.scale_px,
                  np.zeros(len(pixels))]
    origins = camera.centre + local @ camera.rotation
    return origins, np.tile(-camera.rotation[2], (len(pixels), 1))


def lift(head: Head, views: Views, found: FdpFile, surface: _Surface | None = None) -> dict[str, Hit]:
    """3D feature points on the surface from points found in the two renders.

    The rule per point (the catalogue's visibility): a profile point on the midline (side
    view ``P``) is where the side ray meets the mirror plane x = 0, moved to the nearest
    point of the profile curve (the mesh cut by that plane); a point clear in the front
    view is the front ray's first hit, its confidence lowered where the side view puts it
    elsewhere; a point only the side view shows clearly is the side ray's first hit (a ray
    grazing a rim takes the rim); its right partner (the side view shows the left) is the
    mirror image, snapped; a pupil on a separate eyeball is the eyeball's front (on a head
    whose eyes are named parts, wherever the detector put it).

    Parameters
    ----------
    head : Head
        The rendered head (neutral frame).
    views : Views
    found : FdpFile
        ``front`` and ``side`` views: FP id → pixel, with confidences (1 where absent).

    Returns
    -------
    dict of str to Hit
    """
    surface = surface or _Surface(head)
    front = found.views.get("front")
    side = found.views.get("side")
    fpx = {} if front is None else front.points
    spx = {} if side is None else side.points

    def conf(view, i):
        v = found.views.get(view)
        return 1.0 if v is None else float(v.confidence.get(i, 1.0))

    def cast(view, ids):
        px = np.array([(fpx if view == "front" else spx)[i] for i in ids]).reshape(-1, 2)
        o, d = _rays(views.cameras[view], px)
        # The side view sees the ears edge-on: a ray that grazes a rim takes the rim.
        tri, loc = surface.cast(o, d, radius=0.0015 if view == "side" else 0.0)
        return {i: (t, p, o[k], d[k]) for k, (i, t, p) in enumerate(zip(ids, tri, loc))}

    out: dict[str, Hit] = {}
    profile = [i for i in spx if FEATURE_POINTS[i].side == "C" and FEATURE_POINTS[i].side_view == "P"]
    if profile:
        o, d = _rays(views.cameras["side"], np.array([spx[i] for i in profile]))
        # The side rays run along -x: they meet x = 0 at o + o_x * d / (-d_x)...
        t = -o[:, 0] / d[:, 0]
        on_plane = o + t[:, None] * d
        tri, snapped = surface.on_midline(on_plane)
        for k, i in enumerate(profile):
            gap = float(np.linalg.norm(snapped[k] - on_plane[k]))
            out[i] = surface.hit(tri[k], snapped[k], conf("side", i) * np.exp(-(gap / 0.003) ** 2), "profile")
    front_ids = [i for i in fpx if i not in out and FEATURE_POINTS[i].front != "N"
                 and not (FEATURE_POINTS[i].front == "~" and FEATURE_POINTS[i].side_view == "Y")]
    for i, (tri, p, o, d) in cast("front", front_ids).items():
        if tri < 0:
            continue
        c = conf("front", i)
        if i in spx and FEATURE_POINTS[i].side_view == "Y":
            # The side view sees the same point at (depth, height): how far off is it?
            cam = views.cameras["side"]
            seen = cam.project(p[None])[0]
            gap_px = float(np.linalg.norm(seen - spx[i]))
            c *= float(np.exp(-(gap_px / cam.scale_px / 0.005) ** 2))
        out[i] = surface.hit(tri, p, c, "front ray")
    side_ids = [i for i in spx if i not in out and FEATURE_POINTS[i].side in ("C", "L")]
    for i, (tri, p, o, d) in cast("side", side_ids).items():
        if tri >= 0:
            out[i] = surface.hit(tri, p, conf("side", i), "side ray")
    # A pupil on a separate eyeball: the front of the cornea (an untextured eye shows no
    # pupil to a detector; a neutral eye looks straight ahead).
    for i in ("3.5", "3.6"):
        h = out.get(i)
        if h is None:
            continue
        eye = surface.piece_of(h)
        front = surface.vertices[eye]
        apex = front[np.argmax(front[:, 2])]
        if len(eye) < 0.5 * len(surface.vertices) and np.linalg.norm(apex - h.point) < 0.008:
            tri, snapped = surface.closest(apex[None], [h.part])
            out[i] = surface.hit(tri[0], snapped[0], h.confidence, "eye front")
    # Once the eyes are named parts (the last pass), a pupil is the front of its eyeball
    # wherever the detector put it; a detector far from it is trusted less.
    for i, role in (("3.5", "eye_l"), ("3.6", "eye_r")):
        h = out.get(i)
        if h is None or h.how == "eye front" or role not in head.parts:
            continue
        eye = head.parts[role].vertices
        tri, snapped = surface.closest(eye[np.argmax(eye[:, 2])][None], [role])
        near = np.linalg.norm(snapped[0] - h.point) < 0.008
        out[i] = surface.hit(tri[0], snapped[0], h.confidence * (1.0 if near else 0.5), "eye front")
    # Right partners of points only the (left) side view shows.
    partners = [(FEATURE_POINTS[i].mirror, i) for i in list(out) if FEATURE_POINTS[i].side == "L"
                and FEATURE_POINTS[i].mirror not in out and out[i].how == "side ray"]
    if partners:
        pts = np.array([out[i].point * [-1.0, 1.0, 1.0] for _, i in partners])
        tri, snapped = surface.closest(pts)
        for k, (j, i) in enumerate(partners):
            gap = float(np.linalg.norm(snapped[k] - pts[k]))
            out[j] = surface.hit(tri[k], snapped[k], 0.8 * out[i].confidence * np.exp(-(gap / 0.004) ** 2),
                                 "mirrored")
    return {i: out[i] for i in FP_IDS if i in out}


# --- separate meshes -----------------------------------------------------------------------

def _pieces(part) -> np.ndarray:
    """(N,) connected-piece label of each vertex of a part."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n, t = part.n_vertices, part.triangles
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]]]) if len(t) else np.zeros((0, 2), dtype=np.int64)
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    return connected_components(g, directed=False)[1]


def _sphere_centre(points: np.ndarray) -> np.ndarray:
    """Centre of the least-squares sphere through (K, 3) points."""
    a = np.c_[2 * points, np.ones(len(points))]
    b = np.sum(points ** 2, axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    return sol[:3]


def find_parts(head: Head, hits: Mapping[str, Hit]) -> tuple[dict[str, PartSource], list[str]]:
    """The head's parts in a mesh: skin, eyes, teeth and tongue, by the points and connectivity.

    - the skin: the piece most face points lie on (with everything in its part that no
      other role takes);
    - ``eye_l``/``eye_r``: the piece each pupil's ray hits, when it is not the skin, and the
      pieces inside it; centred on the sphere fitted to the largest;
    - ``teeth_upper``/``teeth_lower``/``tongue``: the pieces inside the mouth (between the
      mouth corners, from the nose base to the chin, behind the lips), above and below the
      mouth line; the tongue is the piece below that is longest front to back for its width.

    Parameters
    ----------
    head : Head
        In the neutral frame, with the file's parts.
    hits : mapping of str to Hit
        Points on it (:func:`lift`).

    Returns
    -------
    parts : dict of str to PartSource
        Role → where it comes from (skin first).
    notes : list of str
    """
    pieces = {n: _pieces(p) for n, p in head.parts.items()}
    roles: dict[str, list[tuple[str, int]]] = {}
    notes = []
    face = [h for i, h in hits.items() if FEATURE_POINTS[i].group in (2, 4, 5, 8, 9, 11) and h.how != "generic"]
    if not face:
        raise InputError("no feature point landed on the surface", fix="check the mesh is a head facing the viewer")
    votes: dict[tuple[str, int], int] = {}
    for h in face:
        key = (h.part, int(pieces[h.part][head.parts[h.part].triangles[h.triangle][0]]))
        votes[key] = votes.get(key, 0) + 1
    skin = max(votes, key=votes.get)
    taken = {skin}

    def bbox(key):
        n, k = key
        v = head.parts[n].vertices[pieces[n] == k]
        return v.min(axis=0), v.max(axis=0)

    all_keys = [(n, int(k)) for n, lab in pieces.items() for k in np.unique(lab)]
    for role, fp in (("eye_l", "3.5"), ("eye_r", "3.6")):
        h = hits.get(fp)
        if h is None:
            continue
        key = (h.part, int(pieces[h.part][head.parts[h.part].triangles[h.triangle][0]]))
        if key in taken:
            continue
        lo, hi = bbox(key)
        inside = [k for k in all_keys if k not in taken and k != key
                  and (bbox(k)[0] >= lo - 1e-3).all() and (bbox(k)[1] <= hi + 1e-3).all()]
        roles[role] = [key] + inside
        taken.update(roles[role])
    need = ("8.3", "8.4", "9.15", "2.1")
    if all(i in hits for i in need):
        ml, mr = hits["8.3"].point, hits["8.4"].point
        half = 0.75 * abs(ml[0] - mr[0])
        top, bottom = hits["9.15"].point[1], hits["2.1"].point[1]
        lips = max(ml[2], mr[2]) + 0.01
        line = np.mean([hits[i].point[1] for i in ("2.2", "2.3", "8.3", "8.4") if i in hits])
        upper, lower = [], []
        for k in all_keys:
            if k in taken:
                continue
            lo, hi = bbox(k)
            c = 0.5 * (lo + hi)
            ext = hi - lo
            if (abs(c[0]) < half and bottom < c[1] < top and c[2] < lips and ext[0] < 2.5 * half
                    and ext[1] < (top - bottom)):
                (upper if c[1] > line else lower).append(k)
        tongue = None
        if len(lower) >= 2:
            def shape(k):
                lo, hi = bbox(k)
                e = hi - lo
                return abs(0.5 * (lo + hi)[0]), e[2] / max(e[0], 1e-9), float(np.prod(e))
            # On the midline, longer front to back than wide, the biggest such piece.
            midline = [k for k in lower if shape(k)[0] < 0.003 and shape(k)[1] > 1.1]
            if midline:
                tongue = max(midline, key=lambda k: shape(k)[2])
                lower.remove(tongue)
        for role, keys in (("teeth_upper", upper), ("teeth_lower", lower), ("tongue", [tongue] if tongue else [])):
            if keys:
                roles[role] = keys
                taken.update(keys)
    # Whole file parts where a role has all of a part's pieces; vertex lists otherwise.
    out: dict[str, PartSource] = {}
    for role in ("skin", "eye_l", "eye_r", "teeth_upper", "teeth_lower", "tongue"):
        keys = [skin] if role == "skin" else roles.get(role)
        if not keys:
            continue
        names = {n for n, _ in keys}
        if len(names) > 1:  # pieces from several file parts: keep the part with most of them
            n = max(names, key=lambda n: sum(1 for m, _ in keys if m == n))
            keys = [k for k in keys if k[0] == n]
        n = keys[0][0]
        if role == "skin":
            others = [k for r, ks in roles.items() for k in ks if k[0] == n]
            mask = ~np.isin(pieces[n], [k for _, k in others])
        else:
            mask = np.isin(pieces[n], [k for _, k in keys])
        ids = np.flatnonzero(mask)
        centre = None
        if role.startswith("eye_"):
            biggest = max(keys, key=lambda k: int((pieces[k[0]] == k[1]).sum()))
            centre = _sphere_centre(head.parts[n].vertices[pieces[n] == biggest[1]])
        out[role] = PartSource(n, None if len(ids) == head.parts[n].n_vertices else ids, centre)
        notes.append(f"{role}: " + (f"part '{n}'" if len(ids) == head.parts[n].n_vertices
                                    else f"{len(keys) if role != 'skin' else 1} piece(s) of part '{n}' "
                                         f"({len(ids)} vertices)"))
    # A role that would take a whole part another role takes pieces of cannot be: drop it.
    for role in list(out):
        s = out[role]
        if s.vertices is None and any(o.source == s.source for r, o in out.items() if r != role):
            del out[role]
    return out, notes


# --- points from the shape ----------------------------------------------------------------

def fitted_points(head: Head, hits: dict[str, Hit], guessed=(), give: float = 0.0,
                  surface: _Surface | None = None, generic: Head | None = None) -> dict[str, Hit]:
    """Points from the generic head fitted to the surface (:func:`recon.shape.template_fit.fit_generic`).

    The found skin points (all but ``guessed``) are the fit's anchors. Then:

    - a guessed point, one the detector missed, or an anchor the fit leaves out as an
      outlier: the fitted generic head's point, snapped to the skin (``how`` ``"shape"``;
      confidence 0.5 on the face, 0.3 for the ears, skull and hairline);
    - an anchor, when ``give`` > 0: the fitted point snapped to the skin, which smooths the
      detector's noise by the generic head's shape (``"fitted"``; the detector's
      confidence, lowered by how far the fit moved it);
    - 7.1 (inside the neck): the generic head's, carried by the fit, bound inside (0.3).

    Points not on the skin (pupils, teeth, tongue) are left as they are.

    Parameters
    ----------
    head : Head
        In the neutral frame, parts named (a ``skin`` part; else ``hits`` are returned).
    hits : dict of str to Hit
        From :func:`lift`.
    guessed : collection of str
        Points the detector could only guess (:func:`untextured_guesses`).
    give : float
        How far the shape may overrule the anchors (see ``fit_generic``); 0 keeps them.

    Returns
    -------
    dict of str to Hit
        In catalogue order.
    """
    from recon.shape.template_fit import fit_generic

    if "skin" not in head.parts:
        return hits
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    surface = surface or _Surface(head)
    gb = generic.feature_points
    anchors = {i: h for i, h in hits.items() if i not in guessed and h.confidence > 0 and i in gb
               and gb[i].part == "skin" and h.part == "skin"}
    skin = head.parts["skin"]
    try:
        fit = fit_generic(skin.vertices, skin.triangles, {i: h.point for i, h in anchors.items()},
                          {i: h.confidence for i, h in anchors.items()}, generic, give=give)
    except InputError:
        return hits
    out = dict(hits)
    ids = [i for i in fit.points if i in FEATURE_POINTS and i != "7.1"
           and (i not in anchors or give > 0 or i not in fit.anchors)]
    if ids:
        tri, snapped = surface.closest(np.array([fit.points[i] for i in ids]), ["skin"])
        for i, t, p in zip(ids, tri, snapped):
            if i in anchors and i in fit.anchors:
                moved = float(np.linalg.norm(p - anchors[i].point))
                out[i] = surface.hit(t, p, anchors[i].confidence * np.exp(-(moved / 0.006) ** 2), "fitted")
            else:
                far = FEATURE_POINTS[i].group in (7, 10, 11)
                out[i] = surface.hit(t, p, 0.3 if far else 0.5, "shape")
    if "7.1" in gb:
        out["7.1"] = Hit(fit.move(generic.fp_position("7.1"))[0], "skin", -1, np.zeros(3), 0.3, "shape")
    return {i: out[i] for i in FP_IDS if i in out}


# --- points no view shows ------------------------------------------------------------------

def _generic_map(hits: Mapping[str, Hit], generic: Head):
    """Similarity taking the generic head's points onto the found ones (those with confidence)."""
    g = generic.fp_positions()
    ids = [i for i, h in hits.items() if i in g and h.confidence > 0 and h.how not in ("generic", "teeth", "tongue")]
    if len(ids) < 4:
        raise InputError(f"only {len(ids)} feature points were found on the surface", fix="check the mesh is a head")
    return fit_similarity(np.array([g[i] for i in ids]), np.array([hits[i].point for i in ids]),
                          np.array([hits[i].confidence for i in ids]))


def hidden_points(head: Head, hits: dict[str, Hit], generic: Head | None = None,
                  surface: _Surface | None = None) -> dict[str, Hit]:
    """Add the feature points no view shows, and any the detector missed.

    - teeth (9.8–9.11) and tongue (6.x) points: the generic head's, moved by the
      similarity between the generic head's mouth and nose points and the found ones,
      snapped to the head's own teeth or tongue (confidence 0.5);
    - 7.1 (inside the neck): the generic head's, moved by the similarity between the
      generic head's points and the found ones, bound inside (confidence 0.3);
    - any other point: the same, snapped to the skin (confidence 0: a guess).

    Returns
    -------
    dict of str to Hit
        ``hits`` with the new points added (catalogue order).
    """
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    surface = surface or _Surface(head)
    g = generic.fp_positions()
    out = dict(hits)
    to_head = _generic_map(hits, generic)
    mouth = {i: h for i, h in hits.items() if FEATURE_POINTS[i].group in (2, 8) or i in ("9.15", "9.1", "9.2", "9.3")}
    to_mouth = _generic_map(mouth, generic) if len(mouth) >= 6 else to_head
    groups = {"teeth_upper": ("teeth_upper", "gums_upper"), "teeth_lower": ("teeth_lower", "gums_lower"),
              "tongue": ("tongue",)}
    for i in FP_IDS:
        if i in out or i not in g:
            continue
        b = generic.feature_points[i]
        role = b.part if b.part in groups and b.part in head.parts else None
        if role is not None:
            p = to_mouth(g[i])
            tri, snapped = surface.closest(p[None], [role])
            out[i] = surface.hit(tri[0], snapped[0], 0.5, "teeth" if role != "tongue" else "tongue")
        elif i == "7.1":
            out[i] = Hit(to_head(g[i]), "skin", -1, np.zeros(3), 0.3, "generic")
        elif b.part == "skin" and "skin" in head.parts:
            tri, snapped = surface.closest(to_head(g[i])[None], ["skin"])
            out[i] = surface.hit(tri[0], snapped[0], 0.0, "generic")
    return {i: out[i] for i in FP_IDS if i in out}


def _inside_binding(part, point: np.ndarray) -> FeaturePointBinding:
    """An affine combination of four of the part's vertices that is exactly ``point``."""
    from scipy.spatial import cKDTree

    v = part.vertices
    _, near = cKDTree(v).query(point, k=min(64, len(v)))
    near = np.atleast_1d(near)
    # Four vertices spread around the point: the nearest, then the farthest from the span so far.
    chosen = [near[0]]
    for _ in range(3):
        base = v[chosen]
        if len(chosen) == 1:
            score = np.linalg.norm(v[near] - base[0], axis=1)
        else:
            q, _ = np.linalg.qr((base[1:] - base[0]).T)
            d = v[near] - base[0]
            score = np.linalg.norm(d - (d @ q) @ q.T, axis=1)
        chosen.append(near[int(np.argmax(score))])
    a = np.c_[v[chosen], np.ones(4)].T
    w = np.linalg.lstsq(a, np.r_[point, 1.0], rcond=None)[0]
    return FeaturePointBinding(part.name, tuple(int(k) for k in chosen), tuple(float(x) for x in w / w.sum()))


# --- the whole job -------------------------------------------------------------------------

@dataclass
class Marking:
    """A marked mesh.

    Attributes
    ----------
    head : Head
        In the neutral frame, parts named (skin, eye_l ...), feature points bound.
    fdp : FdpFile
        What ``fmc mark`` writes: bindings to the file's vertices, 3D points, FAPU, frame,
        parts, and in ``metadata["mark3d"]`` the confidences and how each point was placed.
    frame : Frame
    hits : dict of str to Hit
    notes : list of str
        What was detected or assumed.
    warnings : list of str
    """

    head: Head
    fdp: FdpFile
    frame: Frame
    hits: dict[str, Hit]
    notes: list[str]
    warnings: list[str]

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
         where: str | None = None) -> Marking:
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
        See :func:`estimate_frame`.
    size : int
        Render height, pixels.
    passes : int
        1: points from the first renders; 2: the frame turned by those points, rendered and
        lifted again (true front and profile views for a tilted head).
    progress : callable, optional
        Called with a short message before each step.
    where : str, optional
        The file's name for messages.

    Returns
    -------
    Marking

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
        say("finding the eyes, teeth and tongue")
        parts, part_notes = find_parts(head, hits)
        head = place_mesh(raw, frame.matrix, parts, where)
        views = render_views(head, tmp, size, frame.matrix, frame.nose)
        found = _detect(detect, views, name, where)
    surface = _Surface(head)
    hits = lift(head, views, found, surface)
    say("fitting the generic head to the surface")
    guessed = getattr(detect, "guessed", None)
    hits = fitted_points(head, hits, set() if guessed is None else guessed(found), getattr(detect, "give", 0.0),
                         surface)
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
              progress: Callable[[str], None] | None = None) -> tuple[Path, Marking]:
    """``fmc mark`` / ``recon mark3d``: mark a head mesh and write its ``fdp.json``.

    A file already at ``out`` is kept as ``out.bak`` before it is replaced (atomically).

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
    result = mark(mesh, detect=detect, unit=unit, up=up, forward=forward, passes=passes, progress=progress)
    if out.exists():
        backup = out.with_name(out.name + ".bak")
        with atomic_write(backup, "wb") as f:
            f.write(out.read_bytes())
    write_fdp_json(out, result.fdp)
    return out, result
