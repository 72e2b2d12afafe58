"""``*.fdp.json``: feature points of one head, on its photos and in 3D.

One file holds what the annotation tool saves (FP id → pixel per photo, with confidences)
and what a built head ships (3D points, where each sits on the mesh, texture coordinates,
FAPU, provenance). Its layout is the JSON Schema ``mpeg4/data/fdp.schema.json``; this module
validates against it and then checks what a schema cannot: feature point ids, pixels inside
the image, left/right labels on the right sides. Every problem is one line naming the file,
the JSON place and the fix.

Example (abridged)::

    {"format": "mpeg4-fdp", "version": 1, "units": "m",
     "views": {"front": {"image": "front.jpg", "width": 1024, "height": 1365,
                         "points": {"3.5": [602.5, 610.0], "3.6": [420.0, 612.5]},
                         "confidence": {"3.5": 0.98}}},
     "points3d": {"3.5": [0.0321, 0.0362, 0.0964]},
     "fapu": {"IRISD0": 0.0083, "ES0": 0.0672, "ENS0": 0.0483, "MNS0": 0.0212, "MW0": 0.0507},
     "metadata": {"source": "recon fit"}}
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from importlib import resources

import numpy as np

from ..catalogue import FEATURE_POINTS, FP_IDS, check_fp_id
from ..errors import InputError, require_file
from ..fapu import FAPU
from ..head import FeaturePointBinding, Head
from .atomic import atomic_write

__all__ = ["FORMAT", "VERSIONS", "ViewAnnotation", "FdpFile", "read_fdp_json", "write_fdp_json", "parse_fdp",
           "fdp_to_dict", "validate_fdp", "fdp_from_head", "apply_fdp", "schema", "PartSource", "place_mesh"]

FORMAT = "mpeg4-fdp"
#: Versions this reader understands.
VERSIONS = (1,)


@dataclass
class ViewAnnotation:
    """Feature points marked on one photo.

    Attributes
    ----------
    image : str or None
        The photo's path as the user gave it.
    width, height : int or None
        Photo size in pixels.
    points : dict of str to (2,) float64
        FP id → pixel (x right, y down; the top-left pixel's centre is (0, 0)).
    confidence : dict of str to float
        FP id → confidence in [0, 1] (automatic placement); absent for hand-placed points.
    """

    image: str | None = None
    width: int | None = None
    height: int | None = None
    points: dict[str, np.ndarray] = field(default_factory=dict)
    confidence: dict[str, float] = field(default_factory=dict)


@dataclass
class PartSource:
    """Where one part of a head comes from in a mesh file whose parts are not the head's.

    Attributes
    ----------
    source : str
        The file's part (as :func:`mpeg4.io.load_head` names it).
    vertices : (k,) int64 or None
        The part's vertices among the source part's, ascending; None for all of them.
        Whole connected pieces only: no triangle may join them to the rest.
    centre : (3,) float64 or None
        Rotation centre (eyes), metres, neutral frame.
    """

    source: str
    vertices: np.ndarray | None = None
    centre: np.ndarray | None = None


@dataclass
class FdpFile:
    """The contents of a ``*.fdp.json`` file (see the module docstring).

    ``frame`` and ``parts`` describe a mesh from elsewhere (see :func:`place_mesh`): the
    (4, 4) similarity from the file's coordinates to the neutral frame in metres, and head
    part name → :class:`PartSource`.
    """

    views: dict[str, ViewAnnotation] = field(default_factory=dict)
    points3d: dict[str, np.ndarray] = field(default_factory=dict)
    bindings: dict[str, FeaturePointBinding] = field(default_factory=dict)
    texcoords: dict[str, np.ndarray] = field(default_factory=dict)
    fapu: FAPU | None = None
    metadata: dict = field(default_factory=dict)
    version: int = 1
    frame: np.ndarray | None = None
    parts: dict[str, PartSource] = field(default_factory=dict)


def schema() -> dict:
    """The shipped JSON Schema of the format."""
    return json.loads(resources.files("mpeg4").joinpath("data/fdp.schema.json").read_text())


def _json_place(path) -> str:
    parts = list(path)
    text = ""
    for p in parts:
        if isinstance(p, int):
            text += f"[{p}]"
        elif "." in str(p) or not str(p).isprintable():
            # A key with a dot, or a line break or other control character (an error is one
            # line), is written as a JSON string.
            text += f"[{json.dumps(str(p))}]"
        else:
            text += f".{p}" if text else str(p)
    return text or "top level"


def validate_fdp(data, where: str = "fdp.json") -> None:
    """Raise :class:`InputError` if ``data`` (parsed JSON) is not a valid fdp.json.

    Parameters
    ----------
    data : object
        The parsed JSON.
    where : str
        The file name, for messages.
    """
    import jsonschema

    if not isinstance(data, dict):
        raise InputError(f"expected a JSON object, found {type(data).__name__}", where=where,
                         fix="an fdp.json file is one object with 'format' and 'version'")
    if data.get("format") != FORMAT:
        raise InputError(f"'format' is {data.get('format')!r}, expected '{FORMAT}'", where=f"{where}, format",
                         fix="is this an fdp.json file? It starts with {\"format\": \"mpeg4-fdp\", \"version\": 1}")
    known = ", ".join(map(str, VERSIONS))
    if "version" not in data:
        raise InputError(f"no 'version' (this reader knows version {known})", where=f"{where}, top level",
                         fix='add "version": 1 after "format"')
    if data["version"] not in VERSIONS or isinstance(data["version"], bool):
        raise InputError(f"version {data['version']!r} is not one this reader knows ({known})",
                         where=f"{where}, version", fix="update this tool, or write the file with a matching version")
    # Ids first: an unknown id is the likeliest mistake and deserves its own message.
    for key in ("points3d", "bindings", "texcoords"):
        if isinstance(data.get(key), dict):
            for fp_id in data[key]:
                _check_id(fp_id, f"{where}, {key}")
    for name, view in (data.get("views") or {}).items() if isinstance(data.get("views"), dict) else ():
        if isinstance(view, dict):
            for key in ("points", "confidence"):
                if isinstance(view.get(key), dict):
                    for fp_id in view[key]:
                        _check_id(fp_id, f"{where}, views.{name}.{key}")
    validator = jsonschema.Draft202012Validator(schema())
    error = jsonschema.exceptions.best_match(validator.iter_errors(data))
    if error is not None:
        path = list(error.absolute_path)
        # A bad coordinate is reported for its whole point: "expected [x, y] numbers, found ...".
        depth = 4 if path[:1] == ["views"] and path[2:3] == ["points"] else 2
        if len(path) >= depth and (depth == 4 or path[0] in ("points3d", "texcoords")):
            point = data
            for k in path[:depth]:
                point = point[k]
            names = {"points3d": "x, y, z", "texcoords": "u, v"}.get(path[0], "x, y")
            found = json.dumps(point)
            raise InputError(f"expected [{names}] numbers, found {found if len(found) < 60 else found[:57] + '...'}",
                             where=f"{where}, {_json_place(path[:depth])}", fix=_fix_for(error))
        found = json.dumps(error.instance)
        found = found if len(found) < 60 else found[:57] + "..."
        raise InputError(f"{error.message if len(error.message) < 120 else error.message[:117] + '...'} "
                         f"(found {found})", where=f"{where}, {_json_place(error.absolute_path)}",
                         fix=_fix_for(error))
    # Strict JSON has no NaN or infinity; Python's reader accepts them, so check here.
    bad = _non_finite(data, [])
    if bad is not None:
        raise InputError("not a finite number (NaN or infinity)", where=f"{where}, {_json_place(bad)}",
                         fix="give a finite number, or leave the point out if it is unknown")
    for name, view in (data.get("views") or {}).items():
        w, h = view.get("width"), view.get("height")
        for fp_id, (x, y) in view.get("points", {}).items():
            if w and h and not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
                raise InputError(f"pixel ({x:g}, {y:g}) lies outside the {w}x{h} image",
                                 where=f'{where}, views.{name}.points["{fp_id}"]',
                                 fix="move the point onto the photo or remove it")
    for fp_id, b in (data.get("bindings") or {}).items():
        if len(b["vertices"]) != len(b["weights"]) or abs(sum(b["weights"]) - 1) > 1e-6:
            raise InputError(f"{len(b['vertices'])} vertices with weights summing to {sum(b['weights']):.6g}",
                             where=f'{where}, bindings["{fp_id}"]', fix="give one weight per vertex, summing to 1")
    if data.get("frame") is not None:
        _check_frame(np.asarray(data["frame"], dtype=np.float64), f"{where}, frame")
    _check_sides(data, where)


def _check_frame(m: np.ndarray, where: str) -> None:
    """A similarity with positive scale and no mirroring, as a (4, 4) matrix."""
    if not np.allclose(m[3], [0, 0, 0, 1]):
        raise InputError(f"the last row is {m[3].tolist()}, expected [0, 0, 0, 1]", where=where,
                         fix="give the 4x4 matrix row by row, the translation in the last column")
    a = m[:3, :3]
    s = np.cbrt(np.linalg.det(a))
    if not s > 0 or not np.allclose(a @ a.T, s * s * np.eye(3), atol=1e-6 * max(s * s, 1e-30)):
        raise InputError("the matrix is not a rotation times a positive scale (a similarity without mirroring)",
                         where=where, fix="keep axes at right angles and right-handed, the same scale on each")


def _check_id(fp_id: str, where: str) -> None:
    try:
        check_fp_id(fp_id, where=where)
    except InputError as e:
        raise InputError(f"{e.what}: not one of the {len(FP_IDS)} MPEG-4 feature points", where=where,
                         fix=e.fix) from None


def _non_finite(value, path: list) -> list | None:
    """JSON path of the first NaN or infinity in ``value`` (Python's json reads both)."""
    if isinstance(value, float) and not np.isfinite(value):
        return path
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return None
    for k, v in items:
        found = _non_finite(v, path + [k])
        if found is not None:
            return found
    return None


def _fix_for(error) -> str:
    path = list(error.absolute_path)
    if path and path[0] == "views" and "points" in path:
        return "each point is [x, y] in pixels"
    if path and path[0] in ("points3d",):
        return "each 3D point is [x, y, z] in metres"
    if path and path[0] in ("texcoords",):
        return "each texture coordinate is [u, v] with v = 0 at the bottom of the image"
    if error.validator == "additionalProperties":
        return "remove the unknown key or check its spelling against mpeg4/data/fdp.schema.json"
    return "see mpeg4/data/fdp.schema.json for the layout"


def _check_sides(data: dict, where: str) -> None:
    """Left points must be on the face's left: larger x than their partner, in 3D and in a
    front photo (where the face's left appears on the image's right).

    Some files in the wild name sides by the viewer's left and right, for every pair or just
    for the ears (10.x); say which convention the file seems to use rather than build a head
    whose sides are swapped.
    """
    checks = [("points3d", data.get("points3d") or {}, "3D x"),
              ("views.front.points", ((data.get("views") or {}).get("front") or {}).get("points") or {},
               "front-photo x")]
    for place, pts, axis in checks:
        pairs = [i for i in FP_IDS if FEATURE_POINTS[i].side == "L" and i in pts and FEATURE_POINTS[i].mirror in pts]
        # Equal x is not evidence either way (a point on the midline marked twice).
        reversed_ = [i for i in pairs if pts[i][0] < pts[FEATURE_POINTS[i].mirror][0]]
        if not reversed_:
            continue
        named = ", ".join(f"{i}/{FEATURE_POINTS[i].mirror}" for i in reversed_)
        others_fine = [i for i in pairs if not i.startswith("10.")]
        if others_fine and all(i.startswith("10.") for i in reversed_):
            raise InputError(f"ear pairs {named} are on the opposite sides while all {len(others_fine)} non-ear "
                             "pairs are on the correct sides: the file seems to label the ears by the viewer's "
                             "left/right (mirrored convention)",
                             where=f"{where}, {place}",
                             fix="swap the ids of each listed ear pair; odd ids (10.1, 10.3, ...) are on the "
                                 "face's own left ear, which has the larger x")
        if 2 * len(reversed_) > len(pairs):
            photo = " (or the photo is mirrored, as selfie cameras do)" if place.startswith("views") else ""
            raise InputError(f"{len(reversed_)} of {len(pairs)} left/right pairs have the left point at the "
                             f"smaller {axis}: the file seems to use the mirrored (viewer's left/right) "
                             f"convention{photo}",
                             where=f"{where}, {place}",
                             fix="MPEG-4 names sides by the face's own left (3.5 is the face's left pupil, on the "
                                 "viewer's right in a front photo); swap the ids of every left/right pair")
        raise InputError(f"left/right pairs {named} have the left point at the smaller {axis}",
                         where=f"{where}, {place}",
                         fix="swap the ids of each listed pair (the first id of each is the face's own left point, "
                             "which has the larger x)")


def parse_fdp(data: dict, where: str = "fdp.json") -> FdpFile:
    """An :class:`FdpFile` from parsed JSON (validated first)."""
    validate_fdp(data, where)
    views = {}
    for name, v in (data.get("views") or {}).items():
        views[name] = ViewAnnotation(image=v.get("image"), width=v.get("width"), height=v.get("height"),
                                     points={i: np.asarray(p, dtype=np.float64) for i, p in v["points"].items()},
                                     confidence={i: float(c) for i, c in (v.get("confidence") or {}).items()})
    fapu = data.get("fapu")
    parts = {name: PartSource(s["from"], None if "vertices" not in s else np.asarray(s["vertices"], dtype=np.int64),
                              None if "centre" not in s else np.asarray(s["centre"], dtype=np.float64))
             for name, s in (data.get("parts") or {}).items()}
    return FdpFile(
        frame=None if data.get("frame") is None else np.asarray(data["frame"], dtype=np.float64),
        parts=parts,
        views=views,
        points3d={i: np.asarray(p, dtype=np.float64) for i, p in (data.get("points3d") or {}).items()},
        bindings={i: FeaturePointBinding(b["part"], tuple(b["vertices"]), tuple(float(w) for w in b["weights"]))
                  for i, b in (data.get("bindings") or {}).items()},
        texcoords={i: np.asarray(p, dtype=np.float64) for i, p in (data.get("texcoords") or {}).items()},
        fapu=None if fapu is None else FAPU(**fapu),
        metadata=data.get("metadata") or {}, version=int(data["version"]))


def read_fdp_json(path: str | os.PathLike) -> FdpFile:
    """Read and validate a ``*.fdp.json`` file."""
    from .strict_json import read_json

    path = require_file(path, "feature point file")
    return parse_fdp(read_json(path, "feature point file"), where=path)


def _ordered(d: dict) -> list[str]:
    return [i for i in FP_IDS if i in d]


def _num(x: float) -> float:
    return float(round(float(x), 9))


def fdp_to_dict(fdp: FdpFile) -> dict:
    """The JSON object of ``fdp`` (catalogue order, so diffs stay small)."""
    out: dict = {"format": FORMAT, "version": fdp.version, "units": "m"}
    if fdp.views:
        out["views"] = {}
        for name, v in fdp.views.items():
            view = {"image": v.image, "width": v.width, "height": v.height,
                    "points": {i: [_num(c) for c in v.points[i]] for i in _ordered(v.points)}}
            if v.confidence:
                view["confidence"] = {i: _num(v.confidence[i]) for i in _ordered(v.confidence)}
            out["views"][name] = view
    if fdp.points3d:
        out["points3d"] = {i: [_num(c) for c in fdp.points3d[i]] for i in _ordered(fdp.points3d)}
    if fdp.bindings:
        out["bindings"] = {i: {"part": b.part, "vertices": [int(k) for k in b.vertices],
                               "weights": [float(w) for w in b.weights]} for i, b in
                           ((i, fdp.bindings[i]) for i in _ordered(fdp.bindings))}
    if fdp.texcoords:
        out["texcoords"] = {i: [_num(c) for c in fdp.texcoords[i]] for i in _ordered(fdp.texcoords)}
    if fdp.fapu is not None:
        out["fapu"] = {k: _num(v) for k, v in fdp.fapu.as_dict().items()}
    if fdp.frame is not None:
        out["frame"] = [[float(c) for c in row] for row in np.asarray(fdp.frame, dtype=np.float64)]
    if fdp.parts:
        out["parts"] = {}
        for name, s in fdp.parts.items():
            entry = {"from": s.source}
            if s.vertices is not None:
                entry["vertices"] = [int(k) for k in s.vertices]
            if s.centre is not None:
                entry["centre"] = [_num(c) for c in s.centre]
            out["parts"][name] = entry
    if fdp.metadata:
        out["metadata"] = _plain(fdp.metadata)
    return out


def write_fdp_json(path: str | os.PathLike, fdp: FdpFile) -> str:
    """Write ``fdp`` (validated) atomically and return the path."""
    data = fdp_to_dict(fdp)
    bad = _non_finite(data, [])
    if bad is not None:
        raise InputError("not a finite number (NaN or infinity)", where=f"{os.fspath(path)}, {_json_place(bad)}",
                         fix="check what computed it; nothing was written")
    validate_fdp(json.loads(json.dumps(data)), where=os.fspath(path))
    with atomic_write(path, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, allow_nan=False)
        f.write("\n")
    return os.fspath(path)


def _plain(value):
    """``value`` with numpy arrays and scalars (and tuples) turned into JSON types."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def fdp_from_head(head: Head) -> FdpFile:
    """3D points, bindings, FAPU and provenance of a head (no photo views)."""
    try:
        fapu = head.fapu
    except InputError:
        fapu = None
    texcoords = {}
    for i, b in head.feature_points.items():
        uv = head.parts[b.part].uv
        if uv is not None:
            texcoords[i] = np.asarray(b.weights) @ uv[list(b.vertices)]
    return FdpFile(points3d=head.fp_positions(), bindings=dict(head.feature_points), texcoords=texcoords,
                   fapu=fapu, metadata=_plain(head.metadata))


def place_mesh(head: Head, frame: np.ndarray | None = None, parts: dict[str, PartSource] | None = None,
               where: str = "fdp.json") -> Head:
    """A mesh from elsewhere as a head: parts regrouped and named, moved into the neutral frame.

    Parameters
    ----------
    head : Head
        As read from the file (its own units, axes and part names; no feature points).
    frame : (4, 4) float, optional
        Similarity from the file's coordinates to the neutral frame, metres.
    parts : dict of str to PartSource, optional
        Head part name → where it comes from. A part taken whole is renamed; a part taken
        in pieces gives its listed vertices (in that order) and the triangles among them;
        what no listed part takes stays under the file's name (a suffix added if a listed
        part already has it). Listed parts come first, in the given order.

    Returns
    -------
    Head
        A new head without feature points or animation tables; its morph targets are the
        mesh's, turned and scaled with it and regrouped with its parts (a source head keeps
        the motion its file carries).
    """

    parts = parts or {}
    m = np.eye(4) if frame is None else np.asarray(frame, dtype=np.float64)
    _check_frame(m, f"{where}, frame")

    def moved(v):
        return v @ m[:3, :3].T + m[:3, 3]

    taken: dict[str, np.ndarray] = {}
    out: dict = {}
    pieces: dict[str, list] = {}  # file part → (head part, its vertex ids in the file part)
    for name, s in parts.items():
        place = f"{where}, parts.{name}"
        if s.source not in head.parts:
            raise InputError(f"comes from part '{s.source}', which the mesh does not have", where=place,
                             fix=f"the mesh's parts are {', '.join(sorted(head.parts))}; mark the mesh again")
        src = head.parts[s.source]
        mask = taken.setdefault(s.source, np.zeros(src.n_vertices, dtype=bool))
        ids = np.arange(src.n_vertices) if s.vertices is None else np.asarray(s.vertices, dtype=np.int64)
        if len(ids) and (ids.min() < 0 or ids.max() >= src.n_vertices or (np.diff(ids) <= 0).any()):
            raise InputError(f"vertex ids must be ascending and below {src.n_vertices}", where=place,
                             fix="the file belongs to another mesh; mark the mesh again")
        if mask[ids].any():
            raise InputError(f"shares vertices of '{s.source}' with another part", where=place,
                             fix="give each vertex to one part")
        mask[ids] = True
        out[name] = _sub_part(src, name, ids, moved, s.centre, place)
        pieces.setdefault(s.source, []).append((name, ids))
    for name, src in head.parts.items():
        mask = taken.get(name)
        if mask is not None and mask.all():
            continue
        ids = np.arange(src.n_vertices) if mask is None else np.flatnonzero(~mask)
        new, k = name, 2
        while new in out:
            new, k = f"{name}_{k}", k + 1
        centre = None if src.centre is None or mask is not None else moved(src.centre[None])[0]
        out[new] = _sub_part(src, new, ids, moved, centre, f"{where}, part '{name}'")
        pieces.setdefault(name, []).append((new, ids))
    return Head(out, morph_targets=_regrouped_targets(head, pieces, m[:3, :3]), metadata=dict(head.metadata))


def _regrouped_targets(head: Head, pieces: dict, linear: np.ndarray) -> dict:
    """The head's morph targets on the regrouped parts, their vectors turned and scaled."""
    from ..head import SparseDisplacement

    targets = {}
    for tname, target in head.morph_targets.items():
        moved = {}
        for source, d in target.items():
            n = head.parts[source].n_vertices
            for part, ids in pieces.get(source, ()):
                slot = np.full(n, -1, dtype=np.int64)
                slot[ids] = np.arange(len(ids))
                keep = slot[d.indices] >= 0
                if keep.any():
                    moved[part] = SparseDisplacement(slot[d.indices[keep]], d.vectors[keep] @ linear.T)
        targets[tname] = moved
    return targets


def _sub_part(src, name: str, ids: np.ndarray, moved, centre, where: str):
    from ..head import Part

    slot = np.full(src.n_vertices, -1, dtype=np.int64)
    slot[ids] = np.arange(len(ids))
    corner = slot[src.triangles]
    inside = (corner >= 0).all(axis=1)
    straddle = (corner >= 0).any(axis=1) & ~inside
    if straddle.any():
        raise InputError(f"{int(straddle.sum())} triangles join the listed vertices to the rest of '{src.name}'",
                         where=where, fix="list whole connected pieces of the part")
    return Part(name, moved(src.vertices[ids]), corner[inside], uv=None if src.uv is None else src.uv[ids],
                texture=src.texture, colour=src.colour, centre=centre)


def apply_fdp(head: Head, fdp: FdpFile, tol: float = 1e-4, where: str = "fdp.json") -> Head:
    """A copy of ``head`` whose feature points are the file's bindings.

    A file with a ``frame`` or ``parts`` (a mesh from elsewhere, see :func:`place_mesh`)
    first brings the mesh into the neutral frame and names its parts. Where the file also
    has 3D points, each bound point must land within ``tol`` metres of it (the file
    belongs to this mesh).
    """
    out = head.copy()
    if fdp.frame is not None or fdp.parts:
        out = place_mesh(out, fdp.frame, fdp.parts, where)
    for i, b in fdp.bindings.items():
        try:
            out._check_binding(i, b)
        except InputError as e:
            raise InputError(e.what, where=f'{where}, bindings["{i}"]', fix=e.fix) from None
        out.feature_points[i] = b
        if i in fdp.points3d:
            d = float(np.linalg.norm(out.fp_position(i) - fdp.points3d[i]))
            if d > tol:
                raise InputError(f"feature point {i} is bound {d * 1000:.2f} mm away from its 3D position",
                                 where=f'{where}, bindings["{i}"]',
                                 fix="the feature point file belongs to another mesh; use the head's own")
    return out
