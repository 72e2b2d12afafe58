"""GLB files read into heads (this project's own layout, or any glTF head mesh) and their animations."""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field

import numpy as np

from ...catalogue import FP_IDS
from ...errors import InputError, require_file
from ...fat import FAT, FaceDefTable, FaceDefTransform, MorphSpec, fat_from_morph_targets
from ...head import FeaturePointBinding, Head, Part, SparseDisplacement

__all__ = ["FORMAT_VERSION", "MAX_ACCESSOR_VALUES", "GlbAnimation", "read_glb_animation", "read_glb"]

#: Version of the ``extras["mpeg4"]`` layout.
FORMAT_VERSION = 1
#: Most numbers one accessor may hold (a mesh of 22 million vertices; a head has well under one).
MAX_ACCESSOR_VALUES = 1 << 26
# What a damaged file's dangling references and wrong types raise inside the reader.
_DAMAGE = (IndexError, KeyError, TypeError, AttributeError, ValueError, OverflowError, struct.error)
_DTYPES = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8, 5122: np.int16, 5120: np.int8}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


@dataclass
class GlbAnimation:
    """Keyframes to store with a head: morph-target weights and node rotations.

    Attributes
    ----------
    times : (F,) float
        Seconds, increasing.
    weights : dict of str to (F,) float
        Morph target name → weight per frame (targets not listed stay at 0).
    rotations : dict of str to (F, 4) float
        Node name → unit quaternion (x, y, z, w) per frame. ``"pivot"`` turns the head
        about ``pivot`` (the point 7.1), faded over the neck (:func:`write_glb` skins the
        head mesh and adds the ``"neck_j"`` joints' shares); ``"eye_l"``/``"eye_r"`` turn
        the eyes about their centres.
    pivot : (3,) float
        Centre of the whole-head rotation, metres.
    name : str
    """

    times: np.ndarray
    weights: dict = field(default_factory=dict)
    rotations: dict = field(default_factory=dict)
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(3))
    name: str = "animation"


def read_glb_animation(path: str | os.PathLike) -> GlbAnimation | None:
    """The first animation of a GLB written by :func:`write_glb` (None if it has none)."""
    path = require_file(path, "head file")
    r = _Reader(path)
    try:
        return _read_animation(r)
    except InputError:
        raise
    except _DAMAGE as e:
        raise _damaged(path, e) from None


def _read_animation(r: _Reader) -> GlbAnimation | None:
    gltf = r.gltf
    if not gltf.animations:
        return None
    a = gltf.animations[0]
    out = None
    for ch in a.channels:
        sm = a.samplers[ch.sampler]
        times = r.accessor(sm.input).astype(np.float64)
        if out is None:
            pivot = next((k for k, n in enumerate(gltf.nodes) if n.name == "pivot"), None)
            out = GlbAnimation(times, name=a.name or "animation",
                               pivot=np.zeros(3) if pivot is None else _rest_position(gltf, pivot))
        node = gltf.nodes[ch.target.node]
        values = r.accessor(sm.output).astype(np.float64)
        if ch.target.path == "weights":
            names = (gltf.meshes[node.mesh].extras or {}).get("targetNames", [])
            values = values.reshape(len(times), len(names))
            for j, n in enumerate(names):
                out.weights[n] = values[:, j]
        elif ch.target.path == "rotation":
            out.rotations[node.name] = values.reshape(len(times), 4)
    return out


def _rest_position(gltf, index: int) -> np.ndarray:
    """(3,) where node ``index``'s origin sits at rest, its parents' transforms applied
    (the ``pivot`` hangs under the ``shoulders`` joint in a skinned head)."""
    parent = {c: k for k, n in enumerate(gltf.nodes) for c in (n.children or [])}
    m = _node_matrix(gltf.nodes[index])
    seen = {index}
    while index in parent and parent[index] not in seen:
        index = parent[index]
        seen.add(index)
        m = _node_matrix(gltf.nodes[index]) @ m
    return m[:3, 3].copy()


class _Reader:
    def __init__(self, path: str):
        import pygltflib as g

        self.path = path
        try:
            self.gltf = g.GLTF2().load(path)
        except Exception as e:
            raise InputError(f"not a readable glTF/GLB file ({e.__class__.__name__}: {str(e)[:120]})", where=path,
                             fix="export the head as glTF 2.0 binary (.glb)") from None
        if self.gltf is None:
            raise InputError("not a readable glTF/GLB file", where=path, fix="export the head as glTF 2.0 (.glb)")
        self.buffers = []
        for k, buf in enumerate(self.gltf.buffers):
            if buf.uri is None:
                data = self.gltf.binary_blob()
            else:
                try:
                    data = self.gltf.get_data_from_buffer_uri(buf.uri)
                except Exception:
                    base = os.path.dirname(path)
                    p = os.path.join(base, buf.uri)
                    if not os.path.exists(p):
                        raise InputError(f"buffer {k} refers to '{buf.uri}', which is missing", where=path,
                                         fix="keep the .bin file beside the .gltf, or use .glb") from None
                    with open(p, "rb") as f:
                        data = f.read()
            if data is None or len(data) < buf.byteLength:
                raise InputError(f"buffer {k} holds {0 if data is None else len(data)} bytes, "
                                 f"the file says {buf.byteLength}", where=path, fix="the file is truncated; export it again")
            self.buffers.append(bytes(data))

    def view_bytes(self, index: int) -> bytes:
        v = self.gltf.bufferViews[index]
        start = v.byteOffset or 0
        return self.buffers[v.buffer][start:start + v.byteLength]

    def accessor(self, index: int) -> np.ndarray:
        a = self.gltf.accessors[index]
        width = _WIDTH[a.type]
        if not 0 <= a.count * width <= MAX_ACCESSOR_VALUES:
            raise InputError(f"accessor {index} claims {a.count} elements, beyond the {MAX_ACCESSOR_VALUES} values read",
                             where=self.path, fix="the file is damaged, or a mesh far larger than a head; export it again")
        dtype = np.dtype(_DTYPES[a.componentType])
        if a.bufferView is None:
            out = np.zeros((a.count, width), dtype)
        else:
            view = self.gltf.bufferViews[a.bufferView]
            raw = self.view_bytes(a.bufferView)
            stride = view.byteStride or dtype.itemsize * width
            offset = a.byteOffset or 0
            need = offset + stride * (a.count - 1) + dtype.itemsize * width if a.count else 0
            if need > len(raw):
                raise InputError(f"accessor {index} runs past the end of its data", where=self.path,
                                 fix="the file is truncated or damaged; export it again")
            arr = np.lib.stride_tricks.as_strided(np.frombuffer(raw, np.uint8, offset=offset),
                                                  shape=(a.count, width * dtype.itemsize), strides=(stride, 1))
            out = np.ascontiguousarray(arr).view(dtype).reshape(a.count, width).copy()
        if a.sparse is not None and a.sparse.count:
            s = a.sparse
            idx_dtype = _DTYPES[s.indices.componentType]
            idx = np.frombuffer(self.view_bytes(s.indices.bufferView), idx_dtype,
                                count=s.count, offset=s.indices.byteOffset or 0)
            vals = np.frombuffer(self.view_bytes(s.values.bufferView), dtype, count=s.count * width,
                                 offset=s.values.byteOffset or 0).reshape(s.count, width)
            out[idx.astype(np.int64)] = vals
        if a.normalized and dtype.kind in "ui":
            out = out.astype(np.float64) / np.iinfo(dtype).max
        return out if width > 1 else out[:, 0]

    def sparse_target(self, index: int) -> SparseDisplacement:
        a = self.gltf.accessors[index]
        if a.bufferView is None:
            if a.sparse is None or not a.sparse.count:
                return SparseDisplacement(np.zeros(0, np.int64), np.zeros((0, 3)))
            s = a.sparse
            idx = np.frombuffer(self.view_bytes(s.indices.bufferView), _DTYPES[s.indices.componentType],
                                count=s.count, offset=s.indices.byteOffset or 0).astype(np.int64)
            vals = np.frombuffer(self.view_bytes(s.values.bufferView), np.float32, count=s.count * 3,
                                 offset=s.values.byteOffset or 0).reshape(-1, 3)
            return SparseDisplacement(idx, vals.astype(np.float64))
        return SparseDisplacement.from_dense(self.accessor(index).astype(np.float64))

    def texture_of(self, material_index) -> np.ndarray | None:
        import cv2

        if material_index is None:
            return None
        m = self.gltf.materials[material_index]
        pbr = m.pbrMetallicRoughness
        if pbr is None or pbr.baseColorTexture is None:
            return None
        img = self.gltf.images[self.gltf.textures[pbr.baseColorTexture.index].source]
        if img.bufferView is not None:
            data = self.view_bytes(img.bufferView)
        elif img.uri:
            if img.uri.startswith("data:"):
                data = self.gltf.get_data_from_buffer_uri(img.uri)
            else:
                with open(os.path.join(os.path.dirname(self.path), img.uri), "rb") as f:
                    data = f.read()
        else:
            return None
        decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        return None if decoded is None else np.ascontiguousarray(decoded[..., ::-1])

    def colour_of(self, material_index) -> tuple[float, float, float]:
        if material_index is None:
            return (0.8, 0.8, 0.8)
        pbr = self.gltf.materials[material_index].pbrMetallicRoughness
        if pbr is None or pbr.baseColorFactor is None:
            return (1.0, 1.0, 1.0)
        return tuple(float(c) for c in pbr.baseColorFactor[:3])

    def primitive_geometry(self, prim):
        if prim.attributes.POSITION is None:
            raise InputError("a mesh primitive has no POSITION attribute", where=self.path)
        v = self.accessor(prim.attributes.POSITION).astype(np.float64)
        if prim.mode not in (None, 4):
            raise InputError(f"a primitive uses drawing mode {prim.mode}, not triangles", where=self.path,
                             fix="export the mesh triangulated")
        if prim.indices is None:
            t = np.arange(len(v), dtype=np.int64).reshape(-1, 3)
        else:
            t = self.accessor(prim.indices).astype(np.int64).reshape(-1, 3)
        uv = None
        if prim.attributes.TEXCOORD_0 is not None:
            raw = self.accessor(prim.attributes.TEXCOORD_0).astype(np.float64)
            uv = np.c_[raw[:, 0], 1.0 - raw[:, 1]]
        return v, t, uv


def _node_matrix(node) -> np.ndarray:
    m = np.eye(4)
    if node.matrix is not None:
        return np.array(node.matrix, dtype=np.float64).reshape(4, 4).T  # column-major in the file
    if node.scale is not None:
        m = np.diag([*node.scale, 1.0]) @ m
    if node.rotation is not None:
        x, y, z, w = node.rotation
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        rm = np.eye(4)
        rm[:3, :3] = r
        m = rm @ m
    if node.translation is not None:
        t = np.eye(4)
        t[:3, 3] = node.translation
        m = t @ m
    return m


def read_glb(path: str | os.PathLike) -> Head:
    """Read a head from a GLB (or glTF) file.

    Files written by :func:`write_glb` come back whole (parts, feature points, morph
    targets, Facial Animation Tables, metadata). Other glTF files load as one part per
    primitive (node transforms applied, names from the mesh or material), without feature
    points.
    """
    path = require_file(path, "head file")
    r = _Reader(path)
    gltf = r.gltf
    ext = None
    for node in gltf.nodes:
        if isinstance(node.extras, dict) and isinstance(node.extras.get("mpeg4"), dict):
            ext = node.extras["mpeg4"]
            break
    try:
        return _read_own(r, ext) if ext is not None else _read_foreign(r)
    except InputError:
        raise
    except _DAMAGE as e:
        raise _damaged(path, e) from None


def _damaged(path, e: Exception) -> InputError:
    """The one-line error for a file whose structure is broken (an index pointing nowhere,
    a field of the wrong type)."""
    return InputError(f"the glTF structure is damaged ({e.__class__.__name__}: {str(e)[:100]})", where=path,
                      fix="export the head again as glTF 2.0 binary (.glb)")


def read_glb_feature_points(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """The feature point positions a GLB written by :func:`write_glb` stores, read from
    its JSON chunk alone (milliseconds, where :func:`read_glb` decodes every buffer).

    Returns
    -------
    dict of str to (3,) float64
        FP id → position in metres, in catalogue order; empty for a file without them.
    """
    import struct

    from ..strict_json import loads

    path = require_file(path, "head file")
    with open(path, "rb") as f:
        head = f.read(20)
        glb = len(head) == 20 and head[:4] == b"glTF" and head[16:20] == b"JSON"
        if not glb:
            f.seek(0)
        text = f.read(struct.unpack("<I", head[12:16])[0]) if glb else f.read()
    try:
        doc = loads(text, where=os.fspath(path))
    except InputError as e:
        raise InputError(f"not a glTF file ({e.what})", where=os.fspath(path),
                         fix="give a .glb or .gltf file") from None
    if not isinstance(doc, dict):
        raise InputError("not a glTF file (its JSON is not an object)", where=os.fspath(path))
    try:
        for node in doc.get("nodes", []):
            ext = (node.get("extras") or {}).get("mpeg4")
            if isinstance(ext, dict):
                fps = ext.get("feature_points") or {}
                return {i: np.array(fps[i]["position"], float).reshape(3) for i in FP_IDS
                        if i in fps and "position" in fps[i]}
    except _DAMAGE as e:
        raise _damaged(os.fspath(path), e) from None
    return {}


def _read_own(r: _Reader, ext: dict) -> Head:
    gltf = r.gltf
    if ext.get("version", 0) > FORMAT_VERSION:
        raise InputError(f"the file's head data has version {ext.get('version')}; this reader knows up to "
                         f"{FORMAT_VERSION}", where=r.path, fix="update this tool")
    meshes = {m.name: (k, m) for k, m in enumerate(gltf.meshes)}
    nodes = {n.name: n for n in gltf.nodes}
    parts, targets = {}, {}
    cursor = {}
    for info in ext["parts"]:
        k, mesh = meshes[info["mesh"]]
        j = cursor.get(info["mesh"], 0)
        cursor[info["mesh"]] = j + 1
        prim = mesh.primitives[j]
        v, t, uv = r.primitive_geometry(prim)
        centre = None if info.get("centre") is None else np.asarray(info["centre"], dtype=np.float64)
        if centre is not None:
            node = nodes.get(info["mesh"])
            if node is not None and node.translation is not None:
                centre = np.asarray(node.translation, dtype=np.float64)
            v = v + centre
        texture = r.texture_of(prim.material)
        parts[info["name"]] = Part(info["name"], v, t, uv=uv, texture=texture, colour=tuple(info["colour"]),
                                   centre=centre)
        names = (mesh.extras or {}).get("targetNames", [])
        for name, tgt in zip(names, prim.targets or []):
            d = r.sparse_target(tgt["POSITION"])
            if len(d.indices):
                targets.setdefault(name, {})[info["name"]] = d
            else:
                targets.setdefault(name, {})
    fps = {i: FeaturePointBinding(b["part"], tuple(b["vertices"]), tuple(b["weights"]))
           for i, b in ext.get("feature_points", {}).items()}
    own = {n: targets.get(n, {}) for n in ext.get("morph_targets", [])}
    head = Head(parts, fps, own, metadata=ext.get("metadata") or {})
    fat_ext = ext.get("fat")
    if fat_ext is not None:
        # pygltflib also drops empty lists from extras: every key may be missing.
        specs = [MorphSpec(**s) for s in fat_ext.get("targets", [])]
        transforms = FAT()
        for k in fat_ext.get("tables", []):
            transforms.add(FaceDefTable(int(k[0]), int(k[1])))
        for t in fat_ext.get("transforms", []):
            key = (t["fap"], t["high_level"])
            if key not in transforms:
                transforms.add(FaceDefTable(*key))
            # pygltflib drops null values from extras: a missing part is the whole head.
            transforms[key].transforms.append(FaceDefTransform(t.get("part"), t["kind"], t["centre"], t["axis"],
                                                               t["amount"]))
        fat_targets = {s.target: targets.get(s.target, {}) for s in specs}
        fat = fat_from_morph_targets(fat_targets, specs, head.fapu, transforms) if specs else FAT()
        for key, table in transforms.items():
            if key not in fat:
                fat.add(FaceDefTable(table.fap, table.high_level, [], list(table.transforms)))
        head.fat = fat
    return head


def _read_foreign(r: _Reader) -> Head:
    gltf = r.gltf
    scene = gltf.scenes[gltf.scene or 0] if gltf.scenes else None
    roots = scene.nodes if scene is not None else list(range(len(gltf.nodes)))
    parts: dict[str, Part] = {}

    seen: set[int] = set()
    # Depth first, in the file's order, with a stack of its own: a hierarchy thousands of
    # nodes deep is read like any other.
    stack = [(index, np.eye(4)) for index in reversed(list(roots))]
    while stack:
        index, parent = stack.pop()
        if index in seen:  # a node reached twice: the hierarchy is not a tree
            raise InputError(f"node {index} is reached twice in the scene's hierarchy", where=r.path,
                             fix="export the head again (a glTF node has one parent and no cycles)")
        seen.add(index)
        node = gltf.nodes[index]
        m = parent @ _node_matrix(node)
        if node.mesh is not None:
            mesh = gltf.meshes[node.mesh]
            for j, prim in enumerate(mesh.primitives):
                v, t, uv = r.primitive_geometry(prim)
                v = v @ m[:3, :3].T + m[:3, 3]
                mat_name = gltf.materials[prim.material].name if prim.material is not None else None
                base = (mesh.name or mat_name or node.name or "part").replace(" ", "_")
                if len(mesh.primitives) > 1 and mat_name:
                    base = mat_name.replace(" ", "_")
                name = "skin" if not parts and base in ("head", "part") else base
                k = 2
                while name in parts:
                    name, k = f"{base}_{k}", k + 1
                parts[name] = Part(name, v, t, uv=uv, texture=r.texture_of(prim.material),
                                   colour=r.colour_of(prim.material))
        stack += [(c, m) for c in reversed(node.children or [])]
    if not parts or not any(len(p.triangles) for p in parts.values()):
        raise InputError("the file has no triangle meshes", where=r.path, fix="export the head as a triangle mesh")
    return Head(parts, metadata={"source": os.path.basename(r.path)})
