"""One 3D annotation session: a head mesh, its ``fdp.json``, and what the page asks of them.

The 3D mode of ``recon annotate MESH``: the mesh is shown in the page in the MPEG-4 neutral
frame, the feature points as markers on its surface. It touches two files (and a backup):
the mesh (read) and its annotation file (read and written), with the same rules as the
photo mode (:mod:`recon.annotate.session`): saves are validated and atomic, a file that is
not this session's own work is first copied to ``F.fdp.json.bak``, and a file changed on
disk since the session read or wrote it is not overwritten unless the user says so.

Where the points start, in this order: the annotation file when it exists; the head's own
points (a GLB of this project); :func:`recon.mark.mark` with the 2D detector when it is
installed; else the generic head's points, scaled to the mesh and snapped to its surface
(confidence 0, listed for checking).
"""

from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.head import FeaturePointBinding, Head
from mpeg4.io.fdp_json import FdpFile, place_mesh, read_fdp_json

from .placement import GUESS_CONFIDENCE
from .session import LOW_CONFIDENCE, _colour, _hash, _write_file, file_lock

__all__ = ["MESH_EXTENSIONS", "SNAP_MM", "INSIDE", "MeshSession", "is_mesh"]

#: Files the 3D mode opens.
MESH_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply")
#: A saved point may lie this far from the surface (it is moved onto it); farther is refused.
SNAP_MM = 2.0
#: Points inside the head (not on any surface): kept where they are.
INSIDE = ("7.1",)
VIEW = "mesh"


def is_mesh(path) -> bool:
    """Whether ``recon annotate`` opens this file in the 3D mode."""
    return Path(path).suffix.lower() in MESH_EXTENSIONS


class MeshSession:
    """A head mesh and its annotation file (see the module docstring).

    Parameters
    ----------
    mesh : path
        GLB, glTF, OBJ or PLY.
    fdp_path : path, optional
        ``<mesh>.fdp.json`` beside the mesh when None (where :func:`mpeg4.io.load_head`
        finds it).
    detect : callable or bool
        ``detect(views) -> FdpFile`` for :func:`recon.mark.mark`; True uses
        :func:`recon.mark.landmark_detector` when installed; False skips detection.
    unit, up, forward : str, optional
        For :func:`recon.mark.estimate_frame` when the points do not come from a file.
    """

    mode = "mesh"

    def __init__(self, mesh, fdp_path=None, detect=True, unit=None, up=None, forward=None):
        from mpeg4.io import load_head
        from recon.mark import default_fdp_path, load_mesh

        self.mesh_path = Path(mesh).resolve()
        self.fdp_path = Path(fdp_path) if fdp_path is not None else default_fdp_path(mesh)
        if self.fdp_path.is_dir():
            raise InputError("expected an annotation file, found a folder", where=self.fdp_path,
                             fix="give a file name such as head.fdp.json")
        self._lock = threading.Lock()
        self.raw = load_mesh(mesh)
        where = os.fspath(mesh)
        self.notes: list[str] = []
        if self.fdp_path.exists():
            fdp = read_fdp_json(self.fdp_path)
            self._start_from_file(fdp, where)
            self.source, self.message = "file", f"Points loaded from {self.fdp_path.name} ({len(self.points)} points)."
        else:
            own = load_head(mesh)
            if own.feature_points and own.metadata.get("mark3d") is None and len(own.feature_points) >= 10:
                self._start(own, None, {}, {i: own.fp_position(i) for i in own.feature_points}, {},
                            bindings=own.feature_points)
                self.source, self.message = "head", f"The head's own {len(own.feature_points)} points."
            else:
                self._start_detected(mesh, detect, unit, up, forward, where)
        self._disk = _hash(self.fdp_path)
        self._foreign = self._disk is not None
        self.saved_at: float | None = self.fdp_path.stat().st_mtime if self._disk else None
        self._glb: bytes | None = None
        self._surface = None

    # --- where the points start ---------------------------------------------------
    def _start(self, head: Head, frame, parts, points, confidence, metadata=None, bindings=None):
        self.head = head
        self.bindings = dict(bindings or {})
        self.frame = frame
        self.parts = parts
        self.points = {i: np.asarray(points[i], dtype=np.float64) for i in FP_IDS if i in points}
        self.confidence = {i: float(c) for i, c in confidence.items() if i in self.points}
        self.metadata = dict(metadata or {})

    def _start_from_file(self, fdp: FdpFile, where: str):
        from mpeg4.io.fdp_json import apply_fdp

        head = apply_fdp(self.raw, fdp, where=os.fspath(self.fdp_path))
        info = fdp.metadata.get("mark3d") if isinstance(fdp.metadata.get("mark3d"), dict) else {}
        conf = info.get("confidence") or {}
        self._start(head, fdp.frame, fdp.parts, {i: head.fp_position(i) for i in head.feature_points},
                    {i: c for i, c in conf.items() if i in head.feature_points}, fdp.metadata, head.feature_points)
        head.feature_points = {}

    def _start_detected(self, mesh, detect, unit, up, forward, where: str):
        from recon.mark import estimate_frame, landmark_detector, mark

        why = None
        if detect is True:
            try:
                detect = landmark_detector()
            except InputError as e:
                detect, why = None, e.what
        elif detect is False:
            detect, why = None, "automatic detection was not asked for"
        if detect is not None:
            try:
                result = mark(mesh, detect=detect, unit=unit, up=up, forward=forward)
            except InputError as e:
                detect, why = None, f"automatic detection failed: {e.what}"
            else:
                head = result.head
                pts = head.fp_positions()
                bindings, head.feature_points = head.feature_points, {}
                self._start(head, result.fdp.frame, result.fdp.parts, pts, result.confidence, result.fdp.metadata,
                            bindings)
                self.notes = result.notes
                self.source, self.message = "landmarks", "Points placed by automatic detection (fmc mark); check them."
                return
        frame = estimate_frame(self.raw, unit, up, forward, where)
        head = place_mesh(self.raw, frame.matrix, None, where)
        self._start(head, frame.matrix, {}, self._generic_guess(head), {})
        self.confidence = {i: GUESS_CONFIDENCE for i in self.points}
        self.notes = frame.notes
        self.source = "generic"
        self.message = (f"Points placed from the generic head's proportions ({why}). Drag each to its place on "
                        "the surface; N goes to the next to check.")

    def _generic_guess(self, head: Head) -> dict[str, np.ndarray]:
        """The generic head's points moved onto the mesh's box and snapped to its surface."""
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
        g = generic.fp_positions()
        glo, ghi = generic.skin.vertices.min(axis=0), generic.skin.vertices.max(axis=0)
        v = np.concatenate([p.vertices for p in head.parts.values()])
        lo, hi = v.min(axis=0), v.max(axis=0)
        # Scale by the width (the neck's length varies), aligned at the top and the front.
        s = (hi - lo)[0] / (ghi - glo)[0]
        ids = [i for i in FP_IDS if i in g]
        p = np.array([g[i] for i in ids])
        q = np.c_[(p[:, 0] - 0.5 * (glo + ghi)[0]) * s + 0.5 * (lo + hi)[0], (p[:, 1] - ghi[1]) * s + hi[1],
                  (p[:, 2] - ghi[2]) * s + hi[2]]
        surface = self.surface(head)
        tri, snapped = surface.closest(q)
        return {i: (q[k] if i in INSIDE else snapped[k]) for k, i in enumerate(ids)}

    def surface(self, head: Head | None = None):
        from recon.mark.lift import _Surface

        if head is not None:
            return _Surface(head)
        if self._surface is None:
            self._surface = _Surface(self.head)
        return self._surface

    # --- what the page needs ------------------------------------------------------
    @property
    def backup_path(self) -> Path:
        return self.fdp_path.with_name(self.fdp_path.name + ".bak")

    def views_json(self) -> dict:
        return {VIEW: {"points": {i: [float(c) for c in p] for i, p in self.points.items()},
                       "confidence": dict(self.confidence)}}

    def state(self) -> dict:
        from mpeg4.preview import GROUP_COLOURS

        lo, hi = self.head.bounds
        return {
            "mode": "mesh",
            "mesh": {"name": self.mesh_path.name, "parts": list(self.head.parts), "notes": self.notes,
                     "size_cm": [round(float(d) * 100, 1) for d in hi - lo]},
            "file": {"path": os.fspath(self.fdp_path), "name": self.fdp_path.name,
                     "exists": self._disk is not None, "saved_at": self.saved_at,
                     "backup": os.fspath(self.backup_path)},
            "views": self.views_json(),
            "initialisation": {"source": self.source, "message": self.message},
            "catalogue": [{"id": i, "group": fp.group, "side": fp.side, "front": fp.front,
                           "side_view": fp.side_view, "mirror": fp.mirror, "description": fp.description}
                          for i, fp in ((i, FEATURE_POINTS[i]) for i in FP_IDS)],
            "shown": {VIEW: list(FP_IDS)},
            "inside": list(INSIDE),
            "colours": {str(g): _colour(c) for g, c in GROUP_COLOURS.items()},
            "low_confidence": LOW_CONFIDENCE,
        }

    def glb(self) -> bytes:
        """The mesh in the neutral frame as a GLB (parts only), made once."""
        if self._glb is None:
            from mpeg4.io import save_head

            shown = Head(self.head.parts, metadata={"source": self.mesh_path.name})
            with tempfile.TemporaryDirectory(prefix="recon-annotate-") as tmp:
                path = Path(tmp) / "mesh.glb"
                save_head(shown, path)
                self._glb = path.read_bytes()
        return self._glb

    def parse_views(self, data) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """The page's points, checked (raises InputError): FP id → (3,) metres, confidences."""
        where = "the page's points"
        if not isinstance(data, dict) or set(data) != {VIEW}:
            raise InputError(f"expected an object with '{VIEW}' only, found "
                             f"{sorted(data) if isinstance(data, dict) else type(data).__name__}", where=where,
                             fix='send {"mesh": {"points": {"2.1": [x, y, z], ...}}}')
        v = data[VIEW]
        if not isinstance(v, dict) or set(v) - {"points", "confidence"} or not isinstance(v.get("points"), dict):
            raise InputError("the mesh view must be an object with 'points' and optionally 'confidence'",
                             where=f"{where}, mesh", fix="send only points and confidence")
        points, conf = {}, {}
        for i, p in v["points"].items():
            if i not in FEATURE_POINTS:
                raise InputError(f"unknown feature point {i!r}", where=f"{where}, mesh.points",
                                 fix="use an id such as 3.5 from the MPEG-4 catalogue")
            a = np.asarray(p, dtype=np.float64) if isinstance(p, list) and all(
                isinstance(c, (int, float)) and not isinstance(c, bool) for c in p) else None
            if a is None or a.shape != (3,) or not np.isfinite(a).all():
                raise InputError(f"expected [x, y, z] finite numbers (metres), found {str(p)[:40]}",
                                 where=f'{where}, mesh.points["{i}"]', fix="each point is [x, y, z] in metres")
            points[i] = a
        for i, c in (v.get("confidence") or {}).items():
            if i not in points:
                raise InputError(f"confidence given for {i}, which is not placed", where=f"{where}, mesh.confidence",
                                 fix="drop its confidence")
            if isinstance(c, bool) or not isinstance(c, (int, float)) or not 0 <= c <= 1:
                raise InputError(f"confidence {c!r} is not a number in [0, 1]",
                                 where=f'{where}, mesh.confidence["{i}"]', fix="give a number from 0 to 1")
            conf[i] = float(c)
        return points, conf

    def _bindings(self, points: dict[str, np.ndarray]) -> tuple[dict, dict]:
        """Each point snapped onto the surface and bound to its triangle (inside points to
        four vertices around them)."""
        from recon.mark.parts import _inside_binding

        surface = self.surface()
        # Points the page did not move keep their bindings (a snap could pick a surface
        # beside theirs, such as an eyeball's inner shell).
        bindings = {i: self.bindings[i] for i, p in points.items()
                    if i in self.bindings and i in self.points and np.allclose(p, self.points[i], rtol=0, atol=1e-9)}
        ids = [i for i in points if i not in INSIDE and i not in bindings]
        placed = {}
        if ids:
            tri, snapped = surface.closest(np.array([points[i] for i in ids]))
            for k, i in enumerate(ids):
                gap = float(np.linalg.norm(snapped[k] - points[i])) * 1000
                if gap > SNAP_MM:
                    raise InputError(f"feature point {i} lies {gap:.1f} mm off the mesh's surface",
                                     where=f'the page\'s points, mesh.points["{i}"]',
                                     fix="drag it onto the surface (points snap to it)")
                h = surface.hit(tri[k], snapped[k], 1.0, "annotate")
                keep = h.weights > 1e-9
                corners = self.head.parts[h.part].triangles[h.triangle][keep]
                w = h.weights[keep] / h.weights[keep].sum()
                bindings[i] = FeaturePointBinding(h.part, tuple(int(x) for x in corners), tuple(float(x) for x in w))
        for i in points:
            if i in INSIDE and i not in bindings:
                part = self.head.parts.get("skin") or next(iter(self.head.parts.values()))
                bindings[i] = _inside_binding(part, points[i])
        head = Head(self.head.parts, bindings)
        for i in points:
            placed[i] = head.fp_position(i)
        return bindings, placed

    # --- saving and loading -------------------------------------------------------
    def save(self, data, force: bool = False) -> dict:
        """Write the page's points (snapped to the surface) to the annotation file.

        Raises
        ------
        InputError
            The points are not valid, or one lies off the surface (nothing is written).
        SaveConflict
            The file changed on disk since this session last read or wrote it.
        """
        points, conf = self.parse_views(data)
        bindings, placed = self._bindings(points)
        head = Head(self.head.parts, bindings)
        try:
            fapu = head.fapu
        except InputError:
            fapu = None
        meta = dict(self.metadata)
        info = dict(meta.get("mark3d") or {})
        info.update({"source": self.mesh_path.name, "confidence": {i: round(c, 4) for i, c in conf.items()},
                     "reviewed": not any(c < LOW_CONFIDENCE for c in conf.values())})
        info.setdefault("detector", "recon annotate")
        meta["mark3d"] = info
        fdp = FdpFile(points3d=placed, bindings=bindings, fapu=fapu, frame=self.frame, parts=self.parts,
                      metadata=meta)
        with self._lock:
            backup = _write_file(self, fdp, force)
            self.points, self.confidence, self.metadata, self.bindings = placed, conf, meta, bindings
        return {"path": os.fspath(self.fdp_path), "saved_at": self.saved_at, "backup": backup,
                "points": {VIEW: len(placed)}}

    def load(self) -> dict:
        """The points as the annotation file holds them now.

        Raises
        ------
        FileNotFoundError
            Nothing has been saved yet.
        InputError
            The file is not a valid annotation of this mesh.
        """
        with self._lock, file_lock(self.fdp_path, exclusive=False):
            if not self.fdp_path.exists():
                raise FileNotFoundError(self.fdp_path)
            fdp = read_fdp_json(self.fdp_path)
            from mpeg4.io.fdp_json import apply_fdp

            head = apply_fdp(self.raw, fdp, where=os.fspath(self.fdp_path))
            if fdp.frame is not None and self.frame is not None and not np.allclose(fdp.frame, self.frame, atol=1e-9):
                raise InputError("the file places the mesh in another frame than this page shows",
                                 where=self.fdp_path, fix="restart recon annotate to open the file as it is")
            info = fdp.metadata.get("mark3d") if isinstance(fdp.metadata.get("mark3d"), dict) else {}
            self.points = {i: head.fp_position(i) for i in FP_IDS if i in head.feature_points}
            self.bindings = dict(head.feature_points)
            self.confidence = {i: float(c) for i, c in (info.get("confidence") or {}).items() if i in self.points}
            self.metadata = fdp.metadata
            disk = _hash(self.fdp_path)
            self._foreign = self._foreign or disk != self._disk
            self._disk = disk
            self.saved_at = self.fdp_path.stat().st_mtime
        return {"views": self.views_json(), "saved_at": self.saved_at}

    def close(self) -> None:
        pass
