"""A GLB's animation evaluated as the glTF 2.0 specification defines it, in numpy.

What a viewer (three.js, Blender) shows at a keyframe: the channels' values at that
keyframe set the nodes' translation, rotation, scale and the meshes' morph weights; each
mesh's positions are its morphed positions (``POSITION + Σ weight · target``), then either
its node's world transform, or for a skinned mesh linear blend skinning (glTF 2.0 §3.7.3):
``Σ_k WEIGHTS_0[k] · jointMatrix[JOINTS_0[k]]`` with ``jointMatrix = world(joint) ·
inverseBindMatrix`` (the mesh node's own transform is ignored). It checks files written by
:func:`mpeg4.io.write_glb` against the decoder, independently of how they were written.
"""

from __future__ import annotations

import os
from types import SimpleNamespace

import numpy as np

from ...errors import require_file
from .read import _node_matrix, _Reader

__all__ = ["posed_parts"]


def _local(node, overrides: dict) -> np.ndarray:
    """(4, 4) local matrix of a node with animated TRS values in ``overrides``."""
    fields = {k: overrides.get(k, getattr(node, k)) for k in ("translation", "rotation", "scale")}
    return _node_matrix(SimpleNamespace(matrix=node.matrix, **fields))


def posed_parts(path: str | os.PathLike, frame: int) -> dict[str, np.ndarray]:
    """The parts of a GLB written by :func:`mpeg4.io.write_glb` as a glTF viewer poses
    them at keyframe ``frame`` of the file's first animation.

    Parameters
    ----------
    path : str or os.PathLike
    frame : int
        Keyframe index (the channels' values at their ``frame``-th input time; the
        writer gives every channel the same times).

    Returns
    -------
    dict of str to (N, 3) float64
        Part name → world positions of its vertices, metres.
    """
    path = require_file(path, "head file")
    r = _Reader(path)
    gltf = r.gltf
    trs: dict[int, dict] = {}
    morph: dict[int, np.ndarray] = {}
    if gltf.animations:
        anim = gltf.animations[0]
        for ch in anim.channels:
            out = r.accessor(anim.samplers[ch.sampler].output).astype(np.float64)
            n_times = r.gltf.accessors[anim.samplers[ch.sampler].input].count
            values = out.reshape(n_times, -1)[frame]
            if ch.target.path == "weights":
                morph[ch.target.node] = values
            else:
                trs.setdefault(ch.target.node, {})[ch.target.path] = values.tolist()
    world: dict[int, np.ndarray] = {}
    scene = gltf.scenes[gltf.scene or 0]
    stack = [(k, np.eye(4)) for k in scene.nodes]
    while stack:
        k, parent = stack.pop()
        world[k] = parent @ _local(gltf.nodes[k], trs.get(k, {}))
        stack += [(c, world[k]) for c in gltf.nodes[k].children or []]
    ext = next(n.extras["mpeg4"] for n in gltf.nodes if isinstance(n.extras, dict) and "mpeg4" in n.extras)
    node_of_mesh = {n.mesh: k for k, n in enumerate(gltf.nodes) if n.mesh is not None}
    mesh_index = {m.name: k for k, m in enumerate(gltf.meshes)}
    cursor: dict[str, int] = {}
    parts = {}
    for info in ext["parts"]:
        mi = mesh_index[info["mesh"]]
        j = cursor.get(info["mesh"], 0)
        cursor[info["mesh"]] = j + 1
        mesh, node_index = gltf.meshes[mi], node_of_mesh[mi]
        prim = mesh.primitives[j]
        v = r.accessor(prim.attributes.POSITION).astype(np.float64)
        weights = morph.get(node_index, mesh.weights or [])
        for wt, target in zip(weights, prim.targets or []):
            if wt:
                d = r.sparse_target(target["POSITION"])
                v[d.indices] += wt * d.vectors
        node = gltf.nodes[node_index]
        if node.skin is None:
            m = world[node_index]
            parts[info["name"]] = v @ m[:3, :3].T + m[:3, 3]
            continue
        skin = gltf.skins[node.skin]
        ibm = r.accessor(skin.inverseBindMatrices).astype(np.float64).reshape(-1, 4, 4).transpose(0, 2, 1)
        jm = np.stack([world[jn] @ ibm[i] for i, jn in enumerate(skin.joints)])  # (J, 4, 4)
        joints = r.accessor(prim.attributes.JOINTS_0).astype(np.int64)
        w = r.accessor(prim.attributes.WEIGHTS_0).astype(np.float64)
        m = np.einsum("vk,vkab->vab", w, jm[joints])  # per-vertex skin matrix
        parts[info["name"]] = np.einsum("vab,vb->va", m[:, :3, :3], v) + m[:, :3, 3]
    return parts
