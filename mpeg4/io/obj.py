"""Wavefront OBJ heads: ``head.obj`` + ``head.mtl`` + one PNG per textured part, with the
feature points, FAPU and metadata in ``head.fdp.json`` beside them.

Each part is one ``o`` group with its own material; vertices keep their order inside each
part, so feature point bindings (vertex indices per part) survive the round trip. OBJ has
no morph targets: a head's morph targets and animation tables are not written (the
function returns a warning saying so; use GLB to keep them).

Reading also takes plain OBJ files from elsewhere: one part per ``o``/``g`` group (or one
part, ``skin``), polygons fan-triangulated, and a vertex that carries several texture
coordinates (a UV seam) duplicated once per extra coordinate.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError, require_file
from ..head import Head, Part
from .atomic import atomic_write

__all__ = ["write_obj", "read_obj"]


def _png_bytes(image: np.ndarray) -> bytes:
    import cv2

    ok, data = cv2.imencode(".png", np.ascontiguousarray(image[..., :3][..., ::-1]))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return data.tobytes()


def write_obj(head: Head, path: str | os.PathLike, texture_names: dict[str, str] | None = None) -> list[str]:
    """Write ``head`` as OBJ + MTL + PNGs + ``.fdp.json`` (all atomically).

    Writes ``<stem>.obj`` (one ``o <part>`` / ``usemtl <part>`` group per part, vertices in
    metres with 10 significant digits, ``vt`` with t = 0 at the bottom of the image as
    stored), ``<stem>.mtl`` (``Kd`` colour, ``map_Kd`` texture), ``<stem>_<part>.png`` per
    textured part and ``<stem>.fdp.json`` (feature point bindings, 3D points, FAPU,
    metadata). No normals are written. Morph targets and animation tables (FAT) cannot be
    stored in OBJ and are left out; the returned warnings say so.

    Parameters
    ----------
    head : Head
        The head to write.
    path : str or os.PathLike
        The ``.obj`` path; the other files take its stem.
    texture_names : dict of str to str, optional
        Part name → file name (in the OBJ's folder) for its texture, instead of
        ``<stem>_<part>.png``.

    Returns
    -------
    list of str
        Warnings: what OBJ cannot carry (morph targets, animation tables); empty if nothing
        was left out.
    """
    from .fdp_json import fdp_from_head, write_fdp_json

    path = Path(path)
    stem = path.with_suffix("")
    mtl = stem.with_suffix(".mtl")
    any_uv = any(p.uv is not None for p in head.parts.values())
    lines = [f"# {len(head.parts)} parts, metres, +y up, +z towards the viewer", f"mtllib {mtl.name}"]
    mtl_lines = []
    offset = 0
    for name, part in head.parts.items():
        for what, arr in (("vertex", part.vertices), ("texture coordinate of vertex", part.uv)):
            bad = None if arr is None else np.flatnonzero(~np.isfinite(arr).all(axis=1))
            if bad is not None and len(bad):
                raise InputError(f"part '{name}': {what} {int(bad[0])} is not a finite number (NaN or infinite)",
                                 where=os.fspath(path), fix="check what computed it; nothing was written")
        lines += [f"o {name}", f"usemtl {name}"]
        lines.extend(f"v {x:.10g} {y:.10g} {z:.10g}" for x, y, z in part.vertices)
        # vt k belongs to v k (written for every part when any part has uv), so faces
        # can use the same index for both.
        if any_uv:
            uv = part.uv if part.uv is not None else np.zeros((part.n_vertices, 2))
            lines.extend(f"vt {u:.10g} {v:.10g}" for u, v in uv)
        t = part.triangles + offset + 1
        if part.uv is not None:
            lines.extend(f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in t)
        else:
            lines.extend(f"f {a} {b} {c}" for a, b, c in t)
        mtl_lines += [f"newmtl {name}", "Kd " + " ".join(f"{c:.6g}" for c in part.colour), "Ka 0 0 0", "Ks 0 0 0"]
        if part.texture is not None:
            png = path.parent / texture_names[name] if texture_names and name in texture_names \
                else Path(f"{stem}_{name}.png")
            with atomic_write(png, "wb") as f:
                f.write(_png_bytes(part.texture))
            mtl_lines.append(f"map_Kd {png.name}")
        offset += part.n_vertices
    with atomic_write(mtl, "w", encoding="utf-8") as f:
        f.write("\n".join(mtl_lines) + "\n")
    with atomic_write(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    fdp = fdp_from_head(head)
    fdp.metadata = dict(fdp.metadata, obj_parts={n: {"centre": None if p.centre is None else p.centre.tolist()}
                                                 for n, p in head.parts.items()})
    write_fdp_json(stem.with_suffix(".fdp.json"), fdp)
    warnings = []
    if head.morph_targets:
        warnings.append(f"{len(head.morph_targets)} morph targets are not written: OBJ has none (use .glb)")
    if head.fat:
        warnings.append(f"{len(head.fat)} animation tables are not written: OBJ has none (use .glb)")
    return warnings


def _read_mtl(path: Path) -> dict[str, dict]:
    out: dict[str, dict] = {}
    if not path.exists():
        return out
    cur = None
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        toks = line.split()
        if not toks or toks[0].startswith("#"):
            continue
        if toks[0] == "newmtl":
            cur = out.setdefault(" ".join(toks[1:]), {})
        elif cur is not None and toks[0] == "Kd" and len(toks) >= 4:
            cur["Kd"] = tuple(float(x) for x in toks[1:4])
        elif cur is not None and toks[0] == "map_Kd":
            cur["map_Kd"] = toks[-1]
    return out


def read_obj(path: str | os.PathLike, feature_points: bool = True) -> Head:
    """Read an OBJ head (with its ``.mtl``, textures and ``.fdp.json`` when present).

    Files written by :func:`write_obj` come back exactly: parts in order, vertex order,
    uv, textures, ``Kd`` colours, eye centres, feature point bindings and metadata from the
    sidecar (checked against its 3D points). Other OBJ files: one part per ``o``/``g``
    group (faces before any group form the part ``skin``); polygons are fan-triangulated;
    ``vn`` and other statements are ignored. A part's vertices are the ``v`` lines of its
    group when its faces use only those, else the vertices its faces use, in file order.
    OBJ gives each face corner its own ``vt``; when one vertex is used with several ``vt``
    (a UV seam) it is duplicated, the copies appended at the end of its part, so every
    vertex has one uv. A part whose corners are not all textured gets no uv.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.obj`` file.
    feature_points : bool
        Read the sidecar ``.fdp.json`` when there is one (False: the mesh alone).

    Returns
    -------
    Head
        Vertices in the file's units (ours are metres), no morph targets, no FAT.

    Raises
    ------
    InputError
        Missing file, a malformed line (with its number), no faces, an unreadable texture,
        or a sidecar ``.fdp.json`` that does not fit the mesh.
    """
    import cv2

    path = Path(require_file(path, "head file"))
    verts, uvs = [], []
    groups: dict[str, dict] = {}
    order: list[str] = []
    current = None
    materials: dict[str, dict] = {}
    with open(path, encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            toks = line.split()
            if not toks or toks[0].startswith("#"):
                continue
            key = toks[0]
            try:
                if key == "v":
                    verts.append([float(x) for x in toks[1:4]])
                    if len(verts[-1]) != 3:
                        raise ValueError
                elif key == "vt":
                    if len(toks) < 2:
                        raise ValueError
                    # 'vt u' alone is allowed by the format (v defaults to 0).
                    uvs.append([float(x) for x in toks[1:3]] + [0.0] * (2 - len(toks[1:3])))
                elif key in ("o", "g"):
                    name = "_".join(toks[1:]) or f"part{len(order)}"
                    if key == "g" and current is not None and not groups[current]["faces"] and current in order:
                        # 'o x' followed by 'g x': one group
                        groups[name] = groups.pop(current)
                        order[order.index(current)] = name
                    elif name not in groups:
                        groups[name] = {"faces": [], "material": None, "v_start": len(verts)}
                        order.append(name)
                    current = name
                elif key == "usemtl":
                    if current is None:
                        current = "skin"
                        groups[current] = {"faces": [], "material": None, "v_start": 0}
                        order.append(current)
                    groups[current]["material"] = " ".join(toks[1:])
                elif key == "mtllib":
                    materials.update(_read_mtl(path.parent / " ".join(toks[1:])))
                elif key == "f":
                    if current is None:
                        current = "skin"
                        groups[current] = {"faces": [], "material": None, "v_start": 0}
                        order.append(current)
                    corners = []
                    for c in toks[1:]:
                        parts = c.split("/")
                        vi = int(parts[0])
                        ti = int(parts[1]) if len(parts) > 1 and parts[1] else None
                        vi = vi - 1 if vi > 0 else len(verts) + vi
                        if ti is not None:
                            ti = ti - 1 if ti > 0 else len(uvs) + ti
                        if not 0 <= vi < len(verts) or (ti is not None and not 0 <= ti < len(uvs)):
                            raise IndexError
                        corners.append((vi, ti))
                    if len(corners) < 3:
                        raise ValueError
                    for k in range(1, len(corners) - 1):
                        groups[current]["faces"].append((corners[0], corners[k], corners[k + 1]))
            except (ValueError, IndexError):
                raise InputError(f"malformed '{key}' line: {line.strip()[:60]!r}", where=f"{path}, line {n}",
                                 fix="v takes 3 numbers, vt 2, f at least 3 vertex indices that exist") from None
    if not any(g["faces"] for g in groups.values()):
        raise InputError("the file has no faces", where=str(path), fix="export the head as a polygon mesh")
    V = np.asarray(verts, dtype=np.float64)
    T = np.asarray(uvs, dtype=np.float64).reshape(-1, 2)
    parts = {}
    sidecar = path.with_suffix(".fdp.json")
    fdp = None
    if feature_points and sidecar.exists():
        from .fdp_json import read_fdp_json

        fdp = read_fdp_json(sidecar)
    centres = (fdp.metadata.get("obj_parts", {}) if fdp is not None else {})
    for name in order:
        faces = groups[name]["faces"]
        if not faces:
            continue
        corners = np.array(faces, dtype=object).reshape(-1, 2)
        vi = corners[:, 0].astype(np.int64)
        ti = np.array([-1 if t is None else t for t in corners[:, 1]], dtype=np.int64)
        has_uv = bool(len(T)) and (ti >= 0).all()
        # The part's own vertices: the v lines of its group when its faces use only those
        # (files written here keep unused vertices too), else the vertices its faces use.
        k = order.index(name)
        start = groups[name]["v_start"]
        stop = groups[order[k + 1]]["v_start"] if k + 1 < len(order) else len(V)
        own = start < stop and vi.min() >= start and vi.max() < stop
        base = np.arange(start, stop) if own else np.unique(vi)
        slot = np.full(len(V), -1, np.int64)
        slot[base] = np.arange(len(base))
        # One output vertex per distinct (vertex, uv) pair: a vertex's first pair takes its
        # place in ``base``, further pairs (UV seams) are appended.
        pairs = np.c_[vi, ti if has_uv else np.zeros_like(ti)]
        uniq, inv = np.unique(pairs, axis=0, return_inverse=True)
        first = np.r_[True, uniq[1:, 0] != uniq[:-1, 0]]
        index = np.empty(len(uniq), np.int64)
        index[first] = slot[uniq[first, 0]]
        index[~first] = len(base) + np.arange(int((~first).sum()))
        tris = index[inv.reshape(-1)].reshape(-1, 3)
        vert_ids = np.r_[base, uniq[~first, 0]]
        uv = None
        if has_uv:
            # Vertices no face uses keep the vt of the same index when the file pairs them.
            base_uv = T[base] if len(T) == len(V) else np.zeros((len(base), 2))
            base_uv[slot[uniq[first, 0]]] = T[uniq[first, 1]]
            uv = np.r_[base_uv, T[uniq[~first, 1]]]
        mat = materials.get(groups[name]["material"] or "", {})
        texture = None
        if "map_Kd" in mat:
            img = cv2.imread(str(path.parent / mat["map_Kd"]), cv2.IMREAD_COLOR)
            if img is None:
                raise InputError(f"texture '{mat['map_Kd']}' of part '{name}' cannot be read",
                                 where=str(path.with_suffix(".mtl")), fix="keep the PNG beside the .mtl")
            texture = img[..., ::-1]
        centre = (centres.get(name) or {}).get("centre")
        parts[name] = Part(name, V[vert_ids], tris, uv=uv, texture=texture,
                           colour=mat.get("Kd", (0.8, 0.8, 0.8)), centre=centre)
    metadata = {}
    head = Head(parts, metadata=metadata)
    if fdp is not None:
        from .fdp_json import apply_fdp

        head = apply_fdp(head, fdp, where=str(sidecar))
        head.metadata = {k: v for k, v in fdp.metadata.items() if k != "obj_parts"}
    return head
