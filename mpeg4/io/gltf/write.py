"""Heads written as GLB files, with their morph targets, tables and an optional animation."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping

import numpy as np

from ...catalogue import FP_IDS
from ...errors import InputError
from ...fat import FaceDefTransform, MorphSpec, fat_to_morph_targets
from ...head import Head, SparseDisplacement
from ...neck import NECK_SEGMENTS, joint_pair, neck_fade, quat_power
from ..atomic import atomic_write
from .read import FORMAT_VERSION, GlbAnimation

__all__ = ["write_glb"]

_FLOAT, _UINT, _USHORT, _UBYTE = 5126, 5125, 5123, 5121
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


class _NotFinite(Exception):
    """A value to be written is NaN or infinite (``what``, row ``row``)."""

    def __init__(self, what: str, row: int):
        super().__init__(what, row)
        self.what, self.row = what, row


def _check_finite(array: np.ndarray, what: str) -> np.ndarray:
    """``array`` as it is, or :class:`_NotFinite` naming its first row with a NaN or an
    infinity (a float64 beyond float32's range has become one by now)."""
    if array.dtype.kind == "f":
        bad = ~np.isfinite(array.reshape(len(array), -1)).all(axis=1)
        if bad.any():
            raise _NotFinite(what, int(np.flatnonzero(bad)[0]))
    return array


def _normals(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    from ...render import vertex_normals

    return vertex_normals(v, t)


class _Writer:
    def __init__(self):
        import pygltflib as g

        self.g = g
        self.gltf = g.GLTF2(asset=g.Asset(version="2.0", generator="mpeg4-heads"))
        self.blob = bytearray()

    def view(self, data: bytes, target: int | None = None) -> int:
        g = self.g
        self.blob += b"\0" * (-len(self.blob) % 4)
        view = g.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data))
        if target is not None:
            view.target = target
        self.blob += data
        self.gltf.bufferViews.append(view)
        return len(self.gltf.bufferViews) - 1

    def accessor(self, array: np.ndarray, kind: str, target: int | None = None, minmax: bool = False,
                 what: str = "a value") -> int:
        g = self.g
        array = _check_finite(np.ascontiguousarray(array), what)
        ctype = {np.float32: _FLOAT, np.uint32: _UINT, np.uint16: _USHORT, np.uint8: _UBYTE}[array.dtype.type]
        acc = g.Accessor(bufferView=self.view(array.tobytes(), target), componentType=ctype,
                         count=len(array), type=kind)
        if minmax:
            acc.min = array.reshape(len(array), -1).min(axis=0).tolist()
            acc.max = array.reshape(len(array), -1).max(axis=0).tolist()
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1

    def sparse_target(self, n: int, d: SparseDisplacement | None, what: str = "a morph target") -> int:
        """A VEC3 accessor of n displacements, zeros except ``d`` (stored sparse)."""
        g = self.g
        acc = g.Accessor(componentType=_FLOAT, count=n, type="VEC3", min=[0.0, 0.0, 0.0], max=[0.0, 0.0, 0.0])
        acc.byteOffset = None  # no bufferView: the format forbids an offset
        if d is not None and len(d.indices):
            vec = _check_finite(d.vectors.astype(np.float32), what)
            lo, hi = vec.min(axis=0), vec.max(axis=0)
            if len(d.indices) < n:  # the vertices not listed are zeros
                lo, hi = np.minimum(lo, 0), np.maximum(hi, 0)
            acc.min, acc.max = lo.tolist(), hi.tolist()
            acc.sparse = g.Sparse(
                count=len(d.indices),
                indices=g.AccessorSparseIndices(bufferView=self.view(d.indices.astype(np.uint32).tobytes()),
                                                componentType=_UINT),
                values=g.AccessorSparseValues(bufferView=self.view(vec.tobytes())))
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1


def _png(image: np.ndarray) -> bytes:
    import cv2

    img = np.ascontiguousarray(image[..., :3][..., ::-1])
    ok, data = cv2.imencode(".png", img)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return data.tobytes()


def _transform_dict(key, t: FaceDefTransform) -> dict:
    return dict(fap=key[0], high_level=key[1], part=t.part, kind=t.kind, centre=t.centre.tolist(),
                axis=t.axis.tolist(), amount=np.asarray(t.amount, dtype=float).tolist())


def write_glb(head: Head, path: str | os.PathLike, animation: GlbAnimation | None = None) -> str:
    """Write ``head`` as a GLB file (atomically) and return the path.

    Parameters
    ----------
    head : Head
    path : str or os.PathLike
        Destination, normally ``*.glb``.
    animation : GlbAnimation, optional
        Keyframes. When they turn the head (``rotations["pivot"]``), the head mesh is
        skinned so that the turn fades over the neck as the decoder plays it
        (:mod:`mpeg4.neck`): a root joint ``shoulders`` at the neck's cut that stays, and
        joints ``neck_1`` … ``neck_{K-1}`` and ``pivot`` at 7.1 turning by ``j/K`` of the
        head turn (``pivot`` the whole of it); ``JOINTS_0``/``WEIGHTS_0`` hold each
        vertex's two neighbouring joints. The eyeballs' nodes hang under ``pivot``.
        Otherwise the head node hangs under a ``pivot`` node at the rotation centre.
    """
    try:
        with np.errstate(over="ignore"):  # a value beyond float32 becomes inf, refused below
            data = _glb_bytes(head, animation)
    except _NotFinite as e:
        raise InputError(f"{e.what} {e.row} is not a finite number (NaN, or beyond the float32 range of glTF)",
                         where=os.fspath(path), fix="check the values that made it (a FAP value far out of range?); "
                                                    "nothing was written") from None
    except ValueError as e:
        if "JSON compliant" not in str(e) and "Out of range float" not in str(e):
            raise
        raise InputError("the head's feature points, FAPU, tables or metadata hold a NaN or an infinity",
                         where=os.fspath(path), fix="check the values that made them; nothing was written") from None
    with atomic_write(path, "wb") as f:
        f.write(data)
    return os.fspath(path)


def _glb_bytes(head: Head, animation: GlbAnimation | None) -> bytes:
    """The GLB file's bytes (see :func:`write_glb`)."""
    w = _Writer()
    g, gltf = w.g, w.gltf
    targets: dict[str, Mapping[str, SparseDisplacement]] = dict(head.morph_targets)
    specs: list[MorphSpec] = []
    if head.fat is not None and len(head.fat):
        fat_targets, specs = fat_to_morph_targets(head.fat, head.fapu)
        clash = sorted(set(fat_targets) & set(targets))
        if clash:
            raise InputError(f"morph target names {clash[:3]} are used both by the head and by its animation tables",
                             fix="rename the head's own morph targets")
        targets.update(fat_targets)
    names = list(targets)
    gltf.samplers.append(g.Sampler(magFilter=9729, minFilter=9987, wrapS=33071, wrapT=33071))

    groups: list[tuple[str, list[str], np.ndarray | None]] = [("head", [], None)]
    for name, part in head.parts.items():
        if part.centre is None:
            groups[0][1].append(name)
        else:
            groups.append((name, [name], part.centre))
    # A turn that fades over the neck: the head mesh is skinned (see write_glb).
    fade = neck_fade(head) if animation is not None and "pivot" in animation.rotations else None
    eye_nodes = []
    part_info = []
    mesh_target_names: dict[str, list[str]] = {}
    gltf.nodes.append(g.Node(name="head", children=[]))
    for gi, (mesh_name, part_names, centre) in enumerate(groups):
        if not part_names:
            continue
        if gi == 0:
            mesh_targets = names
        else:
            mesh_targets = [t for t in names if any(p in targets[t] for p in part_names)]
        mesh = g.Mesh(name=mesh_name, primitives=[])
        for pname in part_names:
            part = head.parts[pname]
            v = part.vertices - (0 if centre is None else centre)
            attrs = g.Attributes(POSITION=w.accessor(v.astype(np.float32), "VEC3", _ARRAY_BUFFER, minmax=True,
                                                     what=f"part '{pname}': vertex"),
                                 NORMAL=w.accessor(_normals(v, part.triangles).astype(np.float32), "VEC3", _ARRAY_BUFFER,
                                                   what=f"part '{pname}': the normal of vertex"))
            if part.uv is not None:
                uv = np.c_[part.uv[:, 0], 1.0 - part.uv[:, 1]].astype(np.float32)
                attrs.TEXCOORD_0 = w.accessor(uv, "VEC2", _ARRAY_BUFFER,
                                              what=f"part '{pname}': the texture coordinates of vertex")
            idx = part.triangles.reshape(-1)
            idx = idx.astype(np.uint16 if part.n_vertices < 65535 else np.uint32)
            material = g.Material(name=pname, doubleSided=True, pbrMetallicRoughness=g.PbrMetallicRoughness(
                baseColorFactor=[*part.colour, 1.0], metallicFactor=0.0, roughnessFactor=0.6))
            if part.texture is not None:
                gltf.images.append(g.Image(bufferView=w.view(_png(part.texture)), mimeType="image/png", name=pname))
                gltf.textures.append(g.Texture(sampler=0, source=len(gltf.images) - 1))
                material.pbrMetallicRoughness.baseColorTexture = g.TextureInfo(index=len(gltf.textures) - 1)
            gltf.materials.append(material)
            prim = g.Primitive(attributes=attrs, indices=w.accessor(idx, "SCALAR", _ELEMENT_ARRAY_BUFFER),
                               material=len(gltf.materials) - 1, mode=4)
            if fade is not None and gi == 0:
                first, upper = joint_pair(fade.fade[pname])
                # The two joints that weigh in; a slot of weight 0 names joint 0, as glTF asks.
                joints = np.c_[first, first + 1, np.zeros((len(first), 2), np.int64)]
                weights = np.c_[1.0 - upper, upper, np.zeros((len(first), 2))].astype(np.float32)
                joints[weights == 0] = 0
                attrs.JOINTS_0 = w.accessor(joints.astype(np.uint8), "VEC4", _ARRAY_BUFFER)
                attrs.WEIGHTS_0 = w.accessor(weights, "VEC4", _ARRAY_BUFFER,
                                             what=f"part '{pname}': the skin weights of vertex")
            if mesh_targets:
                prim.targets = [{"POSITION": w.sparse_target(part.n_vertices, targets[t].get(pname),
                                                             f"morph target '{t}' of part '{pname}': displacement")}
                                for t in mesh_targets]
            mesh.primitives.append(prim)
            part_info.append(dict(name=pname, mesh=mesh_name, colour=list(part.colour),
                                  centre=None if centre is None else centre.tolist()))
        if mesh_targets:
            mesh.extras = {"targetNames": mesh_targets}
            mesh.weights = [0.0] * len(mesh_targets)
        mesh_target_names[mesh_name] = mesh_targets
        gltf.meshes.append(mesh)
        if gi == 0:
            gltf.nodes[0].mesh = len(gltf.meshes) - 1
        else:
            gltf.nodes.append(g.Node(name=mesh_name, mesh=len(gltf.meshes) - 1, translation=centre.tolist()))
            eye_nodes.append(len(gltf.nodes) - 1)
    gltf.nodes[0].children = eye_nodes if eye_nodes and fade is None else None

    order = list(head.parts)
    part_info.sort(key=lambda info: order.index(info["name"]))  # the head's part order
    pos = {}
    fps = {}
    for i in FP_IDS:
        if i in head.feature_points:
            b = head.feature_points[i]
            fps[i] = dict(part=b.part, vertices=list(b.vertices), weights=list(b.weights),
                          position=np.round(head.fp_position(i), 9).tolist())
            pos[i] = head.fp_position(i)
    try:
        fapu = head.fapu.as_dict()
    except InputError:
        fapu = None
    extras = dict(format="mpeg4-heads", version=FORMAT_VERSION, units="m", parts=part_info, feature_points=fps,
                  fapu=fapu, morph_targets=list(head.morph_targets),
                  fat=None if head.fat is None else dict(
                      targets=[s.as_dict() for s in specs],
                      transforms=[_transform_dict(k, t) for k, tab in sorted(head.fat.items()) for t in tab.transforms],
                      tables=[list(k) for k in sorted(head.fat)]),
                  metadata=head.metadata)
    gltf.nodes[0].extras = {"mpeg4": extras}
    roots = [0]
    if fade is not None:
        roots.append(_add_skeleton(w, fade.base, np.asarray(animation.pivot, dtype=np.float64), eye_nodes))
    if animation is not None:
        roots = [_add_animation(w, animation, mesh_target_names, skinned=fade is not None)] + roots[1:]
    gltf.scenes.append(g.Scene(nodes=roots))
    gltf.scene = 0
    gltf.buffers.append(g.Buffer(byteLength=len(w.blob)))
    gltf.set_binary_blob(bytes(w.blob))
    # glTF's JSON has no NaN or Infinity: refused here rather than written as invalid JSON.
    json.dumps(extras, allow_nan=False, default=str)
    return b"".join(gltf.save_to_bytes())


def _add_skeleton(w: _Writer, base: np.ndarray, pivot: np.ndarray, eye_nodes: list[int]) -> int:
    """The joints that fade the head turn over the neck, and the skin of the head mesh
    (node 0); return the root joint's index. See :func:`write_glb`."""
    g, gltf = w.g, w.gltf
    pivot = pivot.reshape(3)
    gltf.nodes.append(g.Node(name="shoulders", translation=base.tolist(), children=[]))
    root = len(gltf.nodes) - 1
    joints = [root]
    for j in range(1, NECK_SEGMENTS + 1):
        name = "pivot" if j == NECK_SEGMENTS else f"neck_{j}"
        gltf.nodes.append(g.Node(name=name, translation=(pivot - base).tolist()))
        joints.append(len(gltf.nodes) - 1)
        gltf.nodes[root].children.append(joints[-1])
    if eye_nodes:  # the eyeballs turn with the head fully, about their own centres
        gltf.nodes.append(g.Node(name="head_frame", translation=(-pivot).tolist(), children=eye_nodes))
        gltf.nodes[joints[-1]].children = [len(gltf.nodes) - 1]
    # Inverse bind matrices (column-major): the joints' rest frames are translations.
    ibm = np.tile(np.eye(4), (len(joints), 1, 1))
    ibm[0, :3, 3] = -base
    ibm[1:, :3, 3] = -pivot
    acc = w.accessor(np.ascontiguousarray(ibm.transpose(0, 2, 1)).reshape(-1, 16).astype(np.float32), "MAT4")
    gltf.skins.append(g.Skin(name="neck", joints=joints, skeleton=root, inverseBindMatrices=acc))
    gltf.nodes[0].skin = len(gltf.skins) - 1
    return root


def _add_animation(w: _Writer, anim: GlbAnimation, mesh_targets: dict[str, list[str]], skinned: bool = False) -> int:
    """Add the pivot node (unless the head is ``skinned``: :func:`_add_skeleton` made the
    joints) and the animation; return the index of the root node holding the head mesh."""
    g, gltf = w.g, w.gltf
    times = _check_finite(np.asarray(anim.times, dtype=np.float32).reshape(-1), "the animation's time of frame")
    if len(times) < 1 or (np.diff(times) <= 0).any():
        raise InputError("animation times must be increasing", fix="give one time per frame, in seconds")
    pivot = np.asarray(anim.pivot, dtype=np.float64).reshape(3)
    root = 0
    if not skinned:
        gltf.nodes[0].translation = (-pivot).tolist()
        gltf.nodes.append(g.Node(name="pivot", translation=pivot.tolist(), children=[0]))
        root = len(gltf.nodes) - 1
    t_acc = w.accessor(times, "SCALAR", minmax=True)
    samplers, channels = [], []
    nodes = {n.name: k for k, n in enumerate(gltf.nodes)}
    for mesh_name, names in mesh_targets.items():
        if not names or not any(n in anim.weights for n in names):
            continue
        out = np.zeros((len(times), len(names)), np.float32)
        for j, n in enumerate(names):
            if n in anim.weights:
                out[:, j] = _check_finite(np.asarray(anim.weights[n], dtype=np.float32),
                                          f"the animation's weight of morph target '{n}' at frame")
        samplers.append(g.AnimationSampler(input=t_acc, output=w.accessor(out.reshape(-1), "SCALAR"),
                                           interpolation="LINEAR"))
        channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                           target=g.AnimationChannelTarget(node=nodes[mesh_name], path="weights")))
    for node_name, quats in anim.rotations.items():
        if node_name not in nodes:
            raise InputError(f"the animation turns node '{node_name}', which the file does not have",
                             fix=f"use one of {sorted(nodes)}")
        q = _check_finite(np.asarray(quats, dtype=np.float32).reshape(len(times), 4),
                          f"the animation's rotation of node '{node_name}' at frame")
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        turned = [(node_name, q)]
        if skinned and node_name == "pivot":  # the neck joints take their shares of the turn
            turned += [(f"neck_{j}", np.array([quat_power(x, j / NECK_SEGMENTS) for x in q], np.float32))
                       for j in range(1, NECK_SEGMENTS)]
        for name, quats in turned:
            samplers.append(g.AnimationSampler(input=t_acc, output=w.accessor(quats, "VEC4"), interpolation="LINEAR"))
            channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                               target=g.AnimationChannelTarget(node=nodes[name], path="rotation")))
    if channels:
        gltf.animations.append(g.Animation(name=anim.name, samplers=samplers, channels=channels))
    return root
