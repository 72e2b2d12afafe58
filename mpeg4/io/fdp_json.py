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
           "fdp_to_dict", "validate_fdp", "fdp_from_head", "apply_fdp", "schema"]

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
class FdpFile:
    """The contents of a ``*.fdp.json`` file (see the module docstring)."""

    views: dict[str, ViewAnnotation] = field(default_factory=dict)
    points3d: dict[str, np.ndarray] = field(default_factory=dict)
    bindings: dict[str, FeaturePointBinding] = field(default_factory=dict)
    texcoords: dict[str, np.ndarray] = field(default_factory=dict)
    fapu: FAPU | None = None
    metadata: dict = field(default_factory=dict)
    version: int = 1


def schema() -> dict:
    """The shipped JSON Schema of the format."""
    return json.loads(resources.files("mpeg4").joinpath("data/fdp.schema.json").read_text())


def _json_place(path) -> str:
    parts = list(path)
    text = ""
    for p in parts:
        if isinstance(p, int):
            text += f"[{p}]"
        elif "." in str(p):
            text += f'["{p}"]'
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
        raise InputError(f"'format' is {data.get('format')!r}, expected '{FORMAT}'", where=where,
                         fix="is this an fdp.json file? It starts with {\"format\": \"mpeg4-fdp\", \"version\": 1}")
    if data.get("version") not in VERSIONS:
        raise InputError(f"version {data.get('version')!r} is not one this reader knows ({', '.join(map(str, VERSIONS))})",
                         where=f"{where}, version", fix="update this tool, or write the file with a matching version")
    # Ids first: an unknown id is the likeliest mistake and deserves its own message.
    for key in ("points3d", "bindings", "texcoords"):
        for fp_id in (data.get(key) or {}):
            check_fp_id(fp_id, where=f"{where}, {key}")
    for name, view in (data.get("views") or {}).items():
        if isinstance(view, dict):
            for key in ("points", "confidence"):
                for fp_id in (view.get(key) or {}):
                    check_fp_id(fp_id, where=f"{where}, views.{name}.{key}")
    validator = jsonschema.Draft202012Validator(schema())
    error = jsonschema.exceptions.best_match(validator.iter_errors(data))
    if error is not None:
        found = json.dumps(error.instance)
        found = found if len(found) < 60 else found[:57] + "..."
        raise InputError(f"{error.message if len(error.message) < 120 else error.message[:117] + '...'} "
                         f"(found {found})", where=f"{where}, {_json_place(error.absolute_path)}",
                         fix=_fix_for(error))
    for name, view in (data.get("views") or {}).items():
        w, h = view.get("width"), view.get("height")
        for fp_id, (x, y) in view.get("points", {}).items():
            if not (np.isfinite(x) and np.isfinite(y)):
                raise InputError("pixel is not a finite number", where=f'{where}, views.{name}.points["{fp_id}"]')
            if w and h and not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
                raise InputError(f"pixel ({x:g}, {y:g}) lies outside the {w}x{h} image",
                                 where=f'{where}, views.{name}.points["{fp_id}"]',
                                 fix="move the point onto the photo or remove it")
    for fp_id, b in (data.get("bindings") or {}).items():
        if len(b["vertices"]) != len(b["weights"]) or abs(sum(b["weights"]) - 1) > 1e-6:
            raise InputError(f"{len(b['vertices'])} vertices with weights summing to {sum(b['weights']):.6g}",
                             where=f'{where}, bindings["{fp_id}"]', fix="give one weight per vertex, summing to 1")
    _check_sides(data, where)


def _fix_for(error) -> str:
    path = list(error.absolute_path)
    if path and path[0] == "views" and "points" in path:
        return "each point is [x, y] in pixels"
    if path and path[0] in ("points3d",):
        return "each 3D point is [x, y, z] in metres"
    if error.validator == "additionalProperties":
        return "remove the unknown key or check its spelling against mpeg4/data/fdp.schema.json"
    return "see mpeg4/data/fdp.schema.json for the layout"


def _check_sides(data: dict, where: str) -> None:
    """Left points must be on the face's left: x > partner's x in 3D and in a front photo.

    Some files in the wild label by the viewer's left/right (mirrored), for the whole file or
    just for the ears (10.x); say which, rather than let a head come out inside out.
    """
    checks = [("points3d", data.get("points3d") or {}, "has larger x in 3D")]
    front = ((data.get("views") or {}).get("front") or {}).get("points") or {}
    checks.append(("views.front.points", front, "appears right of its partner in the front photo"))
    for place, pts, meaning in checks:
        reversed_, total = [], []
        for fp_id in FP_IDS:
            fp = FEATURE_POINTS[fp_id]
            if fp.side == "L" and fp_id in pts and fp.mirror in pts:
                total.append(fp_id)
                if pts[fp_id][0] < pts[fp.mirror][0]:
                    reversed_.append(fp_id)
        if not reversed_:
            continue
        ears = [i for i in total if i.startswith("10.")]
        ears_rev = [i for i in reversed_ if i.startswith("10.")]
        if ears and set(ears_rev) == set(ears) and len(ears_rev) >= 2 and set(reversed_) == set(ears_rev) \
                and len(total) > len(ears):
            raise InputError("the ear points 10.x are on the opposite sides (the file seems to label the ears by "
                             f"the viewer's left/right): {', '.join(ears_rev)}", where=f"{where}, {place}",
                             fix="swap each ear pair (10.1<->10.2, 10.3<->10.4, 10.5<->10.6, 10.7<->10.8, "
                                 "10.9<->10.10); the odd ids are the face's left ear")
        if len(reversed_) > 0.5 * len(total) and len(total) >= 3:
            raise InputError(f"{len(reversed_)} of {len(total)} left/right pairs are on the wrong sides: the file "
                             "seems to name sides by the viewer's left and right", where=f"{where}, {place}",
                             fix="MPEG-4 names sides by the face's own left (3.5 is the face's left pupil, on the "
                                 "viewer's right); swap every left/right pair")
        worst = reversed_[0]
        raise InputError(f"left point {worst} {meaning.replace('has larger', 'should have larger')} than "
                         f"{FEATURE_POINTS[worst].mirror}, but it does not" if "3D" in meaning else
                         f"left point {worst} should appear right of {FEATURE_POINTS[worst].mirror} in the front "
                         "photo, but it does not", where=f"{where}, {place}",
                         fix=f"swap {worst} and {FEATURE_POINTS[worst].mirror}")


def parse_fdp(data: dict, where: str = "fdp.json") -> FdpFile:
    """An :class:`FdpFile` from parsed JSON (validated first)."""
    validate_fdp(data, where)
    views = {}
    for name, v in (data.get("views") or {}).items():
        views[name] = ViewAnnotation(image=v.get("image"), width=v.get("width"), height=v.get("height"),
                                     points={i: np.asarray(p, dtype=np.float64) for i, p in v["points"].items()},
                                     confidence={i: float(c) for i, c in (v.get("confidence") or {}).items()})
    fapu = data.get("fapu")
    return FdpFile(
        views=views,
        points3d={i: np.asarray(p, dtype=np.float64) for i, p in (data.get("points3d") or {}).items()},
        bindings={i: FeaturePointBinding(b["part"], tuple(b["vertices"]), tuple(float(w) for w in b["weights"]))
                  for i, b in (data.get("bindings") or {}).items()},
        texcoords={i: np.asarray(p, dtype=np.float64) for i, p in (data.get("texcoords") or {}).items()},
        fapu=None if fapu is None else FAPU(**fapu),
        metadata=data.get("metadata") or {}, version=int(data["version"]))


def read_fdp_json(path: str | os.PathLike) -> FdpFile:
    """Read and validate a ``*.fdp.json`` file."""
    path = require_file(path, "feature point file")
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON: {e.msg} at line {e.lineno}, column {e.colno}", where=path,
                         fix="fix the JSON syntax (a missing comma or quote?)") from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file", where=path, fix="give the .fdp.json file, not an image") from None
    return parse_fdp(data, where=path)


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
    if fdp.metadata:
        out["metadata"] = fdp.metadata
    return out


def write_fdp_json(path: str | os.PathLike, fdp: FdpFile) -> str:
    """Write ``fdp`` (validated) atomically and return the path."""
    data = fdp_to_dict(fdp)
    validate_fdp(json.loads(json.dumps(data)), where=os.fspath(path))
    with atomic_write(path, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    return os.fspath(path)


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
    meta = {k: v for k, v in head.metadata.items() if k not in ("ict_vertex_ids",)}
    return FdpFile(points3d=head.fp_positions(), bindings=dict(head.feature_points), texcoords=texcoords,
                   fapu=fapu, metadata=meta)


def apply_fdp(head: Head, fdp: FdpFile, tol: float = 1e-4, where: str = "fdp.json") -> Head:
    """A copy of ``head`` whose feature points are the file's bindings.

    Where the file also has 3D points, each bound point must land within ``tol`` metres of
    it (the file belongs to this mesh).
    """
    out = head.copy()
    for i, b in fdp.bindings.items():
        out._check_binding(i, b)
        out.feature_points[i] = b
        if i in fdp.points3d:
            d = float(np.linalg.norm(out.fp_position(i) - fdp.points3d[i]))
            if d > tol:
                raise InputError(f"feature point {i} is bound {d * 1000:.2f} mm away from its 3D position",
                                 where=f'{where}, bindings["{i}"]',
                                 fix="the feature point file belongs to another mesh; use the head's own")
    return out
