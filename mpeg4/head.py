"""The head: named mesh parts, feature points bound to them, FAPU, texture, morph targets, FATs.

:class:`Head` is the one rich type both halves of the project share. Geometry lives in
:class:`Part` objects (plain numpy arrays, metres, MPEG-4 neutral frame: +x the face's own
left, +y up, +z towards the viewer). Feature points are *bound* to a part as an affine
combination of its vertices (one vertex, a barycentric point on a triangle, or a weighted
mean of a few vertices for points inside the head such as 7.1), so they follow any change
of the vertices. Derived values (FP positions, FAPU) are computed on demand.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from .catalogue import FP_IDS, check_fp_id
from .errors import InputError
from .fapu import FAPU, fapu_from_points

__all__ = ["Part", "FeaturePointBinding", "SparseDisplacement", "Head", "PART_NAMES"]

#: Conventional part names. Heads may carry other parts too.
PART_NAMES = ("skin", "eye_l", "eye_r", "teeth_upper", "teeth_lower", "gums_upper", "gums_lower",
              "tongue", "eyelashes_l", "eyelashes_r")


@dataclass
class Part:
    """One mesh of the head.

    Attributes
    ----------
    name : str
    vertices : (N, 3) float64
        Metres, neutral frame.
    triangles : (M, 3) int64
        Counter-clockwise seen from outside.
    uv : (N, 2) float64 or None
        Texture coordinates, t = 0 at the bottom row of the texture image.
    texture : (H, W, 3) uint8 or None
        RGB, row 0 at the top.
    colour : (3,) float
        Base colour in [0, 1], used when there is no texture (and multiplied with it).
    centre : (3,) float64 or None
        Rotation centre for rigid parts (the eyeballs), metres.
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    colour: tuple[float, float, float] = (0.8, 0.8, 0.8)
    centre: np.ndarray | None = None

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        self.triangles = np.ascontiguousarray(self.triangles, dtype=np.int64)
        where = f"part '{self.name}'"
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise InputError(f"vertices have shape {self.vertices.shape}, expected (N, 3)", where=where)
        if self.triangles.ndim != 2 or self.triangles.shape[1] != 3:
            raise InputError(f"triangles have shape {self.triangles.shape}, expected (M, 3)", where=where)
        if self.triangles.size and (self.triangles.min() < 0 or self.triangles.max() >= len(self.vertices)):
            raise InputError(f"a triangle index is outside 0..{len(self.vertices) - 1}", where=where)
        bad = np.flatnonzero(~np.isfinite(self.vertices).all(axis=1))
        if len(bad):
            raise InputError(f"vertex {int(bad[0])} (of {len(bad)} such) has a NaN or infinite coordinate", where=where,
                             fix="export the mesh again from the tool that made it, or delete those vertices")
        if self.uv is not None:
            self.uv = np.ascontiguousarray(self.uv, dtype=np.float64)
            if self.uv.shape != (len(self.vertices), 2):
                raise InputError(f"uv has shape {self.uv.shape}, expected ({len(self.vertices)}, 2)", where=where)
        if self.texture is not None:
            self.texture = np.ascontiguousarray(self.texture, dtype=np.uint8)
            if self.texture.ndim != 3 or self.texture.shape[2] not in (3, 4):
                raise InputError(f"texture has shape {self.texture.shape}, expected (H, W, 3)", where=where)
        if self.centre is not None:
            self.centre = np.asarray(self.centre, dtype=np.float64).reshape(3)
        self.colour = tuple(float(c) for c in self.colour)

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)


@dataclass(frozen=True)
class FeaturePointBinding:
    """Where a feature point sits: an affine combination of vertices of one part.

    Attributes
    ----------
    part : str
    vertices : (k,) int64
        Vertex indices in the part; k = 1 for a vertex, 3 for a barycentric point.
    weights : (k,) float64
        Summing to 1.
    """

    part: str
    vertices: tuple[int, ...]
    weights: tuple[float, ...]

    @classmethod
    def at_vertex(cls, part: str, vertex: int) -> FeaturePointBinding:
        return cls(part, (int(vertex),), (1.0,))

    def __post_init__(self):
        if len(self.vertices) != len(self.weights) or not self.vertices:
            raise InputError("a feature point binding needs as many weights as vertices (at least one)")
        if abs(sum(self.weights) - 1.0) > 1e-6:
            raise InputError(f"feature point weights sum to {sum(self.weights):.6g}, expected 1")

    def position(self, vertices: np.ndarray) -> np.ndarray:
        """(3,) position of the point on ``vertices`` (the part's (N, 3) array); of any
        per-vertex array (N, ...), the point's value, shape (...)."""
        return np.tensordot(np.asarray(self.weights, dtype=np.float64), np.asarray(vertices)[list(self.vertices)], 1)


@dataclass
class SparseDisplacement:
    """Displacements of a few vertices of one part.

    Attributes
    ----------
    indices : (k,) int64
        Sorted, unique vertex indices.
    vectors : (k, 3) float64
        Metres.
    """

    indices: np.ndarray
    vectors: np.ndarray

    def __post_init__(self):
        self.indices = np.asarray(self.indices, dtype=np.int64).reshape(-1)
        self.vectors = np.asarray(self.vectors, dtype=np.float64).reshape(-1, 3)
        if len(self.indices) != len(self.vectors):
            raise InputError(f"{len(self.indices)} indices but {len(self.vectors)} displacement vectors")
        order = np.argsort(self.indices, kind="stable")
        self.indices, self.vectors = self.indices[order], self.vectors[order]
        if len(self.indices) > 1 and (np.diff(self.indices) == 0).any():
            raise InputError("a vertex is listed twice in a sparse displacement")

    @classmethod
    def from_dense(cls, dense: np.ndarray, tol: float = 0.0) -> SparseDisplacement:
        """Keep the rows of a (N, 3) array whose largest component exceeds ``tol`` (metres)."""
        dense = np.asarray(dense, dtype=np.float64)
        keep = np.flatnonzero(np.abs(dense).max(axis=1) > tol)
        return cls(keep, dense[keep])

    def dense(self, n_vertices: int) -> np.ndarray:
        """(n_vertices, 3) array with zeros where no displacement is stored."""
        out = np.zeros((n_vertices, 3))
        out[self.indices] = self.vectors
        return out

    def __add__(self, other: SparseDisplacement) -> SparseDisplacement:
        """The sum of two displacements of one part (rows that cancel to zero are dropped)."""
        idx = np.union1d(self.indices, other.indices)
        vec = np.zeros((len(idx), 3))
        vec[np.searchsorted(idx, self.indices)] += self.vectors
        vec[np.searchsorted(idx, other.indices)] += other.vectors
        keep = np.abs(vec).max(axis=1) > 0
        return SparseDisplacement(idx[keep], vec[keep])

    def scaled(self, factor: float) -> SparseDisplacement:
        return SparseDisplacement(self.indices.copy(), self.vectors * factor)


@dataclass
class Head:
    """A head model: parts, feature points, morph targets and Facial Animation Tables.

    Attributes
    ----------
    parts : dict of str to Part
        In drawing order; ``skin`` first by convention.
    feature_points : dict of str to FeaturePointBinding
        MPEG-4 FP id → binding. A head may carry a subset of the 84.
    morph_targets : dict of str to dict of str to SparseDisplacement
        Target name → part name → displacement at weight 1 (metres).
    fat : mpeg4.fat.FAT or None
        Facial Animation Tables.
    metadata : dict
        Provenance and anything else that should travel with the head (JSON-serialisable).

    Examples
    --------
    >>> import numpy as np
    >>> skin = Part("skin", np.eye(3), [[0, 1, 2]])
    >>> head = Head({"skin": skin}, {"2.1": FeaturePointBinding.at_vertex("skin", 0)})
    >>> head.fp_position("2.1")
    array([1., 0., 0.])
    """

    parts: dict[str, Part]
    feature_points: dict[str, FeaturePointBinding] = field(default_factory=dict)
    morph_targets: dict[str, dict[str, SparseDisplacement]] = field(default_factory=dict)
    fat: object | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        if isinstance(self.parts, Iterable) and not isinstance(self.parts, Mapping):
            self.parts = {p.name: p for p in self.parts}
        for fp_id, b in self.feature_points.items():
            check_fp_id(fp_id, where="head feature points")
            self._check_binding(fp_id, b)
        for name, target in self.morph_targets.items():
            for part, d in target.items():
                if part not in self.parts:
                    raise InputError(f"morph target '{name}' moves part '{part}', which the head does not have")
                if len(d.indices) and d.indices.max() >= self.parts[part].n_vertices:
                    raise InputError(f"morph target '{name}' moves vertex {d.indices.max()} of part '{part}', "
                                     f"which has {self.parts[part].n_vertices} vertices")

    def _check_binding(self, fp_id: str, b: FeaturePointBinding) -> None:
        if b.part not in self.parts:
            raise InputError(f"feature point {fp_id} is bound to part '{b.part}', which the head does not have",
                             fix=f"use one of {sorted(self.parts)}")
        n = self.parts[b.part].n_vertices
        if max(b.vertices) >= n or min(b.vertices) < 0:
            raise InputError(f"feature point {fp_id} is bound to vertex {max(b.vertices)} of part '{b.part}', "
                             f"which has {n} vertices")

    # --- derived values -------------------------------------------------------------
    @property
    def skin(self) -> Part:
        """The face and scalp surface."""
        if "skin" not in self.parts:
            raise InputError("the head has no 'skin' part", fix=f"name the face mesh 'skin' (parts: {sorted(self.parts)})")
        return self.parts["skin"]

    def fp_position(self, fp_id: str, vertices: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """(3,) position of one feature point in metres.

        Parameters
        ----------
        fp_id : str
        vertices : mapping of part name to (N, 3) array, optional
            Deformed vertices to evaluate on instead of the neutral ones.
        """
        check_fp_id(fp_id)
        if fp_id not in self.feature_points:
            raise InputError(f"the head has no feature point {fp_id}",
                             fix="place it (recon annotate / fmc mark) or give its position in the fdp.json")
        b = self.feature_points[fp_id]
        v = self.parts[b.part].vertices if vertices is None or b.part not in vertices else vertices[b.part]
        return b.position(v)

    def fp_positions(self, vertices: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """FP id → (3,) position for every bound point, in catalogue order."""
        return {i: self.fp_position(i, vertices) for i in FP_IDS if i in self.feature_points}

    def fp_array(self, ids: Iterable[str] | None = None) -> tuple[list[str], np.ndarray]:
        """The ids and a (K, 3) array of their positions (all bound points by default)."""
        ids = [i for i in FP_IDS if i in self.feature_points] if ids is None else list(ids)
        return ids, np.array([self.fp_position(i) for i in ids]).reshape(-1, 3)

    @property
    def fapu(self) -> FAPU:
        """FAPU measured on the neutral feature points (reference section 2)."""
        return fapu_from_points(self.fp_positions(), where="head feature points")

    @property
    def texture(self) -> np.ndarray | None:
        """The skin's texture image, if any."""
        return self.parts["skin"].texture if "skin" in self.parts else None

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corner over all parts, metres."""
        v = np.concatenate([p.vertices for p in self.parts.values()])
        return np.array([v.min(axis=0), v.max(axis=0)])

    def summary(self) -> str:
        """A few lines a person can read: parts, feature points, FAPU, morph targets, FATs."""
        lines = ["parts:"]
        for p in self.parts.values():
            extra = " textured" if p.texture is not None else ""
            lines.append(f"  {p.name:<14} {p.n_vertices:>6} vertices {len(p.triangles):>6} triangles{extra}")
        lo, hi = self.bounds
        lines.append("size (cm): " + " x ".join(f"{d * 100:.1f}" for d in hi - lo))
        missing = [i for i in FP_IDS if i not in self.feature_points]
        lines.append(f"feature points: {len(self.feature_points)} of {len(FP_IDS)}"
                     + (f" (missing: {', '.join(missing[:12])}{' ...' if len(missing) > 12 else ''})" if missing else ""))
        try:
            lines.append("FAPU (mm): " + "  ".join(f"{k} {v * 1000:.2f}" for k, v in self.fapu.as_dict().items()))
        except InputError as e:
            lines.append(f"FAPU: not measurable ({e.what})")
        names = sorted(self.morph_targets)
        lines.append(f"morph targets: {len(names)}" + (f" ({', '.join(names[:6])}{' ...' if len(names) > 6 else ''})"
                                                        if names else ""))
        lines.append(f"animation tables: {0 if self.fat is None else len(self.fat)}")
        return "\n".join(lines)

    # --- changes --------------------------------------------------------------------
    def copy(self) -> Head:
        """A deep copy."""
        return copy.deepcopy(self)

    def with_vertices(self, vertices: Mapping[str, np.ndarray]) -> Head:
        """A copy with some parts' vertices replaced (feature points follow their bindings)."""
        out = self.copy()
        for name, v in vertices.items():
            if name not in out.parts:
                raise InputError(f"no part '{name}' in the head", fix=f"use one of {sorted(out.parts)}")
            v = np.asarray(v, dtype=np.float64)
            if v.shape != out.parts[name].vertices.shape:
                raise InputError(f"part '{name}' has {out.parts[name].vertices.shape} vertices, got {v.shape}")
            out.parts[name].vertices = v.copy()
        return out

    def morphed(self, weights: Mapping[str, float]) -> dict[str, np.ndarray]:
        """Part name → (N, 3) vertices with the named morph targets applied linearly."""
        out = {name: p.vertices.copy() for name, p in self.parts.items()}
        for name, w in weights.items():
            if name not in self.morph_targets:
                raise InputError(f"the head has no morph target '{name}'",
                                 fix=f"known targets: {', '.join(sorted(self.morph_targets)[:8])}...")
            for part, d in self.morph_targets[name].items():
                out[part][d.indices] += w * d.vectors
        return out

    def mirror_error(self) -> dict[str, float]:
        """For each left/right FP pair, the distance (m) between one and the other's mirror image.

        The mirror is taken across the plane x = 0, the midline of the neutral frame.
        """
        from .catalogue import FEATURE_POINTS

        out = {}
        pos = self.fp_positions()
        for i, fp in FEATURE_POINTS.items():
            if fp.side == "L" and i in pos and fp.mirror in pos:
                m = pos[fp.mirror] * np.array([-1.0, 1.0, 1.0])
                out[i] = float(np.linalg.norm(pos[i] - m))
        return out
