"""Key-models: a neutral model and named expressions of it, and their compositing.

:class:`KeyModels` holds a base (neutral) model and its key-models as displacements of
all of a head's parts stacked (the head's part order), so that blending them is one
matrix product. Key-models come from a head's morph targets (:meth:`KeyModels.from_head`),
from vertex arrays (:meth:`KeyModels.from_positions`), or from the generic head's
ARKit-named shapes by the viseme and expression mixes of ``fmc/data/high_level_shapes.toml``
(:func:`key_models_from_shapes`).

Compositing (Pyun et al., section 3 and the appendix) makes a key-model for every pair of
an emotional and a verbal key-model: each vertex gets an importance for speech,
:func:`vertex_importance`, and :func:`composite` keeps the verbal displacement where the
importance is high and the emotional one where it is low, adding of the other only its
component perpendicular to the kept one. Unlike the paper's hard switch at 0.5, the
importance is spread over the mesh (:func:`smooth_importance`), the two are blended across
a band of it, and the projection is softened for barely moving vertices, so that the skin
does not tear where the rule changes (:func:`composite` says why).

References
----------
.. [1] H. Pyun, Y. Kim, W. Chae, H. W. Kang, S. Y. Shin, "An example-based approach for
   facial expression cloning", Proc. ACM SIGGRAPH/Eurographics Symposium on Computer
   Animation (2003) 167-176.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mpeg4.catalogue import EXPRESSIONS, VISEMES
from mpeg4.errors import InputError
from mpeg4.head import Head, SparseDisplacement

__all__ = ["KeyModels", "key_models_from_shapes", "vertex_importance", "smooth_importance", "composite",
           "composite_key_models", "VERBAL", "EMOTIONAL", "combined_name"]

#: Names of the verbal key-models :func:`key_models_from_shapes` builds: the 14 MPEG-4 visemes.
VERBAL = tuple(f"viseme_{VISEMES[k].name}" for k in range(1, 15))
#: Names of the emotional key-models: the 6 MPEG-4 expressions.
EMOTIONAL = tuple(f"expression_{EXPRESSIONS[k].name}" for k in range(1, 7))


def combined_name(emotional: str, verbal: str) -> str:
    """Name of the key-model compositing ``emotional`` with ``verbal``."""
    return f"{emotional}+{verbal}"


@dataclass
class KeyModels:
    """A neutral model and named key-models of it, every part of a head stacked.

    Attributes
    ----------
    neutral : (V, 3) float64
        The base model's vertices, metres; with a ``head``, its parts stacked in the
        head's part order.
    names : list of str
        The key-models' names, N of them (the neutral is not among them).
    displacements : (N, V, 3) float64
        Key-model minus neutral, metres.
    head : Head or None
        The base model the vertices belong to: its parts give the stacking and its
        feature points the parameterisation. Without a head, feature points are given
        as vertex indices.

    Examples
    --------
    >>> import numpy as np
    >>> keys = KeyModels.from_positions({"neutral": np.zeros((4, 3)), "smile": np.eye(4, 3)})
    >>> keys.names, keys.displacements.shape
    (['smile'], (1, 4, 3))
    """

    neutral: np.ndarray
    names: list
    displacements: np.ndarray
    head: Head | None = None

    def __post_init__(self):
        self.neutral = np.ascontiguousarray(self.neutral, dtype=np.float64)
        self.names = [str(n) for n in self.names]
        self.displacements = np.ascontiguousarray(self.displacements, dtype=np.float64)
        v = self.neutral.shape[0] if self.neutral.ndim == 2 else -1
        if self.neutral.ndim != 2 or self.neutral.shape[1] != 3:
            raise InputError(f"the neutral model has shape {self.neutral.shape}, expected (V, 3)")
        if self.displacements.shape != (len(self.names), v, 3):
            raise InputError(f"{len(self.names)} key-models of {v} vertices need displacements of shape "
                             f"({len(self.names)}, {v}, 3), got {self.displacements.shape}")
        if len(set(self.names)) != len(self.names):
            dup = sorted({n for n in self.names if self.names.count(n) > 1})
            raise InputError(f"key-model names are repeated: {', '.join(dup[:3])}", fix="give each key-model one name")
        if self.head is not None and sum(p.n_vertices for p in self.head.parts.values()) != v:
            raise InputError(f"the key-models have {v} vertices but the head's parts have "
                             f"{sum(p.n_vertices for p in self.head.parts.values())}")
        if not (np.isfinite(self.neutral).all() and np.isfinite(self.displacements).all()):
            raise InputError("key-model vertices contain NaN or infinity")

    # --- construction ---------------------------------------------------------------
    @classmethod
    def from_head(cls, head: Head, names: Iterable[str] | None = None) -> KeyModels:
        """The head's morph targets (all, or ``names`` in that order) as key-models."""
        names = list(head.morph_targets if names is None else names)
        missing = [n for n in names if n not in head.morph_targets]
        if missing:
            raise InputError(f"the head has no morph targets {', '.join(missing[:4])}"
                             f"{' ...' if len(missing) > 4 else ''}",
                             fix="give a head with these key-models as named morph targets, or draft them with FMC")
        offsets = _offsets(head)
        n = sum(p.n_vertices for p in head.parts.values())
        disp = np.zeros((len(names), n, 3))
        for i, name in enumerate(names):
            for part, d in head.morph_targets[name].items():
                disp[i, offsets[part] + d.indices] = d.vectors
        neutral = np.concatenate([p.vertices for p in head.parts.values()])
        return cls(neutral, names, disp, head)

    @classmethod
    def from_positions(cls, models: Mapping[str, np.ndarray], head: Head | None = None,
                       where: str | None = None) -> KeyModels:
        """Key-models given as vertex positions, one (V, 3) array per name; the base model
        is the one named ``"neutral"``."""
        if "neutral" not in models:
            raise InputError(f"the key-models have no 'neutral' (the base model): found {', '.join(list(models)[:5])}",
                             where=where, fix="add the neutral face under the name 'neutral'")
        neutral = np.asarray(models["neutral"], dtype=np.float64)
        names = [n for n in models if n != "neutral"]
        for n in names:
            shape = np.shape(models[n])
            if shape != neutral.shape:
                raise InputError(f"key-model '{n}' has {shape[0] if len(shape) else 0} vertices, the neutral "
                                 f"{neutral.shape[0]}", where=where,
                                 fix="every key-model of a set must be the same mesh as its neutral")
        disp = np.array([np.asarray(models[n], dtype=np.float64) - neutral for n in names]).reshape(len(names),
                                                                                                    *neutral.shape)
        return cls(neutral, names, disp, head)

    # --- views ----------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.names)

    @property
    def n_vertices(self) -> int:
        return len(self.neutral)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(f"no key-model '{name}'", fix=f"known: {', '.join(self.names[:6])} ...") from None

    def select(self, names: Iterable[str]) -> KeyModels:
        """These key-models only, in this order."""
        names = list(names)
        idx = [self.index(n) for n in names]
        return KeyModels(self.neutral, names, self.displacements[idx], self.head)

    def positions(self, name: str) -> np.ndarray:
        """(V, 3) vertices of one key-model (``"neutral"`` for the base)."""
        return self.neutral.copy() if name == "neutral" else self.neutral + self.displacements[self.index(name)]

    def part_slices(self) -> dict[str, slice]:
        """Part name → rows of the stacked vertices (needs the head)."""
        if self.head is None:
            raise InputError("these key-models have no head to split their vertices into parts")
        return {p: slice(o, o + self.head.parts[p].n_vertices) for p, o in _offsets(self.head).items()}

    def morph_targets(self, tol: float = 1e-7) -> dict[str, dict[str, SparseDisplacement]]:
        """Key-model name → part → displacement (rows moving less than ``tol`` metres dropped)."""
        out = {}
        slices = self.part_slices()
        for i, name in enumerate(self.names):
            parts = {}
            for p, sl in slices.items():
                d = SparseDisplacement.from_dense(self.displacements[i, sl], tol=tol)
                if len(d.indices):
                    parts[p] = d
            out[name] = parts
        return out

    def to_head(self, tol: float = 1e-7) -> Head:
        """The base head with these key-models as its only morph targets."""
        if self.head is None:
            raise InputError("these key-models have no head to write")
        out = self.head.copy()
        out.morph_targets = self.morph_targets(tol)
        out.fat = None
        return out


def _offsets(head: Head) -> dict[str, int]:
    sizes = [p.n_vertices for p in head.parts.values()]
    return dict(zip(head.parts, np.cumsum([0] + sizes[:-1]).tolist()))


def key_models_from_shapes(head: Head, visemes: Iterable[int] = range(1, 15),
                           expressions: Iterable[int] = range(1, 7)) -> KeyModels:
    """Verbal and emotional key-models from a head's ARKit-named sculpted shapes.

    Each viseme and expression is the mix of shapes that ``fmc/data/high_level_shapes.toml``
    gives it at full intensity (the mixes the authored animation tables use).

    Parameters
    ----------
    head : Head
        With the ARKit-named morph targets (the generic head has all 53).
    visemes, expressions : iterable of int
        MPEG-4 viseme numbers (1-14) and expression numbers (1-6).

    Returns
    -------
    KeyModels
        Named ``viseme_<name>`` and ``expression_<name>`` (:data:`VERBAL`,
        :data:`EMOTIONAL`), the visemes first.
    """
    from fmc.high_level import HIGH_LEVEL_SHAPES

    wanted = [((1, k), f"viseme_{VISEMES[k].name}") for k in visemes]
    wanted += [((2, k), f"expression_{EXPRESSIONS[k].name}") for k in expressions]
    shapes = sorted({s for key, _ in wanted for s in HIGH_LEVEL_SHAPES[key]})
    missing = [s for s in shapes if s not in head.morph_targets]
    if missing:
        raise InputError(f"the head lacks the shapes {', '.join(missing[:4])}{' ...' if len(missing) > 4 else ''}",
                         fix="give a head with the ARKit-named shapes (the generic head has them), "
                             "or key-models as morph targets")
    base = KeyModels.from_head(head, shapes)
    weights = np.zeros((len(wanted), len(shapes)))
    for i, (key, _) in enumerate(wanted):
        for s, w in HIGH_LEVEL_SHAPES[key].items():
            weights[i, shapes.index(s)] = w
    disp = np.tensordot(weights, base.displacements, axes=1)
    return KeyModels(base.neutral, [n for _, n in wanted], disp, head)


def _max_norm_importance(displacements: np.ndarray) -> np.ndarray:
    """(V,) largest displacement of each vertex over the key-models, over the largest of all."""
    m = np.linalg.norm(displacements, axis=2).max(axis=0) if len(displacements) else np.zeros(displacements.shape[1])
    top = m.max() if m.size else 0.0
    return m / top if top > 0 else m


def _propagate(points: np.ndarray, importance: np.ndarray, radius: float, s1: float) -> np.ndarray:
    """Every vertex within ``radius`` of a vertex whose importance exceeds ``s1`` takes at
    least that vertex's importance."""
    out = importance.copy()
    strong = np.flatnonzero(importance > s1)
    if radius <= 0 or not len(strong):
        return out
    tree = cKDTree(points)
    for j, near in zip(strong, tree.query_ball_point(points[strong], radius)):
        near = np.asarray(near, dtype=np.int64)
        out[near] = np.maximum(out[near], importance[j])
    return out


def vertex_importance(neutral: np.ndarray, verbal: np.ndarray, emotional: np.ndarray, radius_verbal: float,
                      radius_emotional: float, s1: float = 0.5, s2: float = 0.3) -> np.ndarray:
    """Per-vertex importance for speech (verbal importance) in [0, 1].

    Three steps:

    1. a vertex's verbal importance is the largest norm of its displacement over the
       verbal key-models, divided by the largest over all vertices; its emotional
       importance likewise over the emotional key-models;
    2. each importance is propagated: every vertex within ``radius_verbal`` (verbal) or
       ``radius_emotional`` (emotional) of a vertex whose importance exceeds ``s1``
       takes at least that vertex's importance, so that a region that speaks (the lips
       and what moves with them) is important as a whole, not only where it moves most;
    3. the two are combined: a vertex whose propagated verbal importance is at least
       ``s2`` is verbal (importance 1: speech must stay legible where it moves the face
       noticeably); elsewhere its importance is its share ``a_v / (a_v + a_e)`` of the
       two (0 where neither moves).

    :func:`composite` treats vertices of importance at least 0.75 as verbal, at most 0.25
    as emotional, and blends between (after :func:`smooth_importance`). The paper
    gives the roles of S_1, S_2, L_p and L_e; the combination in step 3 and the default
    values (S_1 = 0.5, S_2 = 0.3, and in :func:`composite_key_models` L_p = MW0 / 4,
    L_e = ES0 / 4) are this project's.

    Parameters
    ----------
    neutral : (V, 3) float
        Base model vertices, metres (for the propagation distances).
    verbal : (Nv, V, 3) float
        Displacements of the verbal key-models, metres.
    emotional : (Ne, V, 3) float
        Displacements of the emotional key-models, metres.
    radius_verbal, radius_emotional : float
        Propagation radii L_p and L_e, metres.
    s1 : float
        Importance above which a vertex propagates its importance (S_1).
    s2 : float
        Propagated verbal importance at or above which a vertex is verbal (S_2).

    Returns
    -------
    (V,) float
        Verbal importance; 1 − it is the vertex's emotional importance.

    References
    ----------
    .. [1] H. Pyun et al., "An example-based approach for facial expression cloning",
       SCA 2003, section 3 and appendix.
    """
    neutral = np.asarray(neutral, dtype=np.float64)
    verbal = np.asarray(verbal, dtype=np.float64).reshape(-1, *neutral.shape)
    emotional = np.asarray(emotional, dtype=np.float64).reshape(-1, *neutral.shape)
    if not 0 <= s1 <= 1 or not 0 <= s2 <= 1:
        raise InputError(f"importance thresholds must lie in [0, 1], got S1 = {s1}, S2 = {s2}")
    a_v = _propagate(neutral, _max_norm_importance(verbal), radius_verbal, s1)
    a_e = _propagate(neutral, _max_norm_importance(emotional), radius_emotional, s1)
    total = a_v + a_e
    share = np.divide(a_v, total, out=np.zeros_like(total), where=total > 0)
    return np.where(a_v >= s2, 1.0, share)


def smooth_importance(importance: np.ndarray, triangles: np.ndarray, steps: int = 20) -> np.ndarray:
    """The importance diffused along a mesh's edges, so that it changes over a band.

    Each step moves every vertex halfway to the mean of its edge neighbours (a uniform
    Laplacian step); after ``steps`` of them a jump from one vertex to the next is spread
    over about ``2 * sqrt(steps)`` edges on either side. Vertices deep inside a verbal or an
    emotional region keep their importance; vertices on no triangle keep theirs.

    Parameters
    ----------
    importance : (V,) float
        Verbal importance (:func:`vertex_importance`).
    triangles : (M, 3) int
        The mesh's triangles, indices into the V vertices (several parts' stacked, with
        their vertex offsets added, diffuse each within its own part).
    steps : int
        Number of diffusion steps; 0 returns the importance unchanged.

    Returns
    -------
    (V,) float
        In [0, 1] when the importance is.
    """
    from scipy.sparse import coo_matrix

    out = np.asarray(importance, dtype=np.float64).copy()
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if steps < 0:
        raise InputError(f"the number of smoothing steps must be at least 0, got {steps}")
    if steps == 0 or not len(tri):
        return out
    i = np.r_[tri[:, 0], tri[:, 1], tri[:, 2], tri[:, 1], tri[:, 2], tri[:, 0]]
    j = np.r_[tri[:, 1], tri[:, 2], tri[:, 0], tri[:, 0], tri[:, 1], tri[:, 2]]
    adj = coo_matrix((np.ones(len(i)), (i, j)), shape=(len(out), len(out))).tocsr()
    adj.data[:] = 1.0  # an edge shared by two triangles counts once
    deg = np.asarray(adj.sum(axis=1)).ravel()
    on_mesh = deg > 0
    for _ in range(steps):
        mean = np.divide(adj @ out, deg, out=out.copy(), where=on_mesh)
        out = 0.5 * (out + mean)
    return out


def composite(verbal: np.ndarray, emotional: np.ndarray, importance: np.ndarray,
              band: tuple[float, float] = (0.25, 0.75), softness: float = 0.0) -> np.ndarray:
    """The displacement of an emotional and a verbal key-model composited.

    Two candidates per vertex, as in Pyun et al.: the verbal displacement kept whole plus
    the emotional one's component perpendicular to it, and the emotional one kept whole
    plus the verbal one's perpendicular component. Where the importance is at least
    ``band[1]`` the composite is the first (clearly verbal), at most ``band[0]`` the second
    (clearly emotional), and between them a blend of the two by a smooth step of the
    importance (3t² − 2t³, t rising from 0 to 1 across the band). A vertex one of them
    leaves still takes the other's displacement.

    Two departures from the paper, which switches at importance 0.5 and removes the whole
    component along the kept displacement:

    - where the displacements point against each other (a rounded vowel holding the lips
      while an expression drops the jaw) each candidate is about its kept displacement
      alone, so a switch from one vertex to the next opens a step in the skin: the lips
      stay put while the skin next to them drops. The blend over a band of importance
      (with the importance itself spread over the mesh, :func:`smooth_importance`) makes
      that step a slope;
    - the component of the other along the kept displacement k is removed by the factor
      |k|² / (|k|² + ``softness``²) rather than wholly: a vertex the kept key-model barely
      moves would otherwise cancel up to all of the other's motion along a direction set
      by that tiny motion, which changes from vertex to vertex and tears the skin inside a
      region too. Where |k| is well above ``softness`` the rule is the paper's.

    Parameters
    ----------
    verbal, emotional : (V, 3) float
        Displacements, metres.
    importance : (V,) float
        Verbal importance (:func:`vertex_importance`, :func:`smooth_importance`).
    band : (float, float)
        Importance below which the composite is the emotional candidate and above which
        it is the verbal one; ``(0.5, 0.5)`` is the paper's hard switch.
    softness : float
        Length in the displacements' unit (metres) below which a kept displacement stops
        cancelling the other's along it; 0 is the paper's projection.

    Returns
    -------
    (V, 3) float

    References
    ----------
    .. [1] H. Pyun et al., "An example-based approach for facial expression cloning",
       SCA 2003, section 3 and appendix.

    Examples
    --------
    >>> import numpy as np
    >>> composite(np.array([[0.0, -1, 0]]), np.array([[1.0, 1, 0]]), np.array([1.0]))
    array([[ 1., -1.,  0.]])
    """
    verbal = np.asarray(verbal, dtype=np.float64)
    emotional = np.asarray(emotional, dtype=np.float64)
    lo, hi = (float(b) for b in band)
    if softness < 0:
        raise InputError(f"the compositing softness must be at least 0, got {softness}")
    if not 0 <= lo <= hi <= 1:
        raise InputError(f"the compositing band must satisfy 0 <= low <= high <= 1, got {band}")
    imp = np.asarray(importance, dtype=np.float64)
    if hi > lo:
        t = np.clip((imp - lo) / (hi - lo), 0.0, 1.0)
        w = (t * t * (3.0 - 2.0 * t))[:, None]
    else:
        w = (imp >= hi).astype(np.float64)[:, None]
    return w * _keep(verbal, emotional, softness) + (1.0 - w) * _keep(emotional, verbal, softness)


def _keep(kept: np.ndarray, other: np.ndarray, softness: float = 0.0) -> np.ndarray:
    """``kept`` plus the component of ``other`` perpendicular to it, per row; with a
    ``softness`` (metres) the component along it is removed only by |kept|² / (|kept|² +
    softness²), so that a barely moving kept vertex does not cancel the other's motion."""
    nn = (kept * kept).sum(axis=1, keepdims=True) + softness ** 2
    along = np.divide((other * kept).sum(axis=1, keepdims=True), nn, out=np.zeros_like(nn), where=nn > 0)
    return kept + other - along * kept


def composite_key_models(keys: KeyModels, verbal: Iterable[str] = VERBAL, emotional: Iterable[str] = EMOTIONAL,
                         radius_verbal: float | None = None, radius_emotional: float | None = None,
                         s1: float = 0.5, s2: float = 0.3, smoothing_steps: int = 20,
                         band: tuple[float, float] = (0.25, 0.75),
                         softness: float | None = None) -> tuple[KeyModels, np.ndarray]:
    """The pure key-models and one composite per emotional × verbal pair.

    The importance (:func:`vertex_importance`) is diffused along each of the head's parts'
    edges (:func:`smooth_importance`, when the key-models have a head) and the composites
    blend their verbal and emotional candidates across ``band`` with a soft projection
    (:func:`composite`).

    Parameters
    ----------
    keys : KeyModels
        Holding the verbal and emotional key-models.
    verbal, emotional : iterable of str
        Their names.
    radius_verbal, radius_emotional : float, optional
        L_p and L_e in metres; by default a quarter of the head's mouth width MW0 and
        of its eye separation ES0.
    s1, s2 : float
        Thresholds of :func:`vertex_importance`.
    smoothing_steps : int
        Diffusion steps of :func:`smooth_importance` (0: the importance as computed).
    band : (float, float)
        Importance band of :func:`composite`.
    softness : float, optional
        Softness of :func:`composite` in metres; by default 5 % of the head's mouth width
        MW0 (about 2.5 mm on the generic head). ``smoothing_steps=0, band=(0.5, 0.5),
        softness=0`` is the paper's rule.

    Returns
    -------
    keys : KeyModels
        The verbal, then the emotional key-models, then the composites named
        ``emotional+verbal`` (:func:`combined_name`), emotion by emotion.
    importance : (V,) float
        The verbal importance used (smoothed).
    """
    verbal, emotional = list(verbal), list(emotional)
    if not verbal or not emotional:
        raise InputError("compositing needs at least one verbal and one emotional key-model")
    if radius_verbal is None or radius_emotional is None:
        if keys.head is None:
            raise InputError("give the propagation radii (metres): the key-models have no head to measure")
        fapu = keys.head.fapu
        radius_verbal = 0.25 * fapu.MW0 if radius_verbal is None else radius_verbal
        radius_emotional = 0.25 * fapu.ES0 if radius_emotional is None else radius_emotional
    if softness is None:
        if keys.head is None:
            raise InputError("give the compositing softness (metres): the key-models have no head to measure")
        softness = 0.05 * keys.head.fapu.MW0
    dv = keys.select(verbal).displacements
    de = keys.select(emotional).displacements
    importance = vertex_importance(keys.neutral, dv, de, radius_verbal, radius_emotional, s1, s2)
    if keys.head is not None and smoothing_steps:
        offsets = _offsets(keys.head)
        triangles = np.concatenate([p.triangles + offsets[name] for name, p in keys.head.parts.items()])
        importance = smooth_importance(importance, triangles, smoothing_steps)
    names = verbal + emotional + [combined_name(e, v) for e in emotional for v in verbal]
    combined = [composite(dv[j], de[i], importance, band, softness)
                for i in range(len(emotional)) for j in range(len(verbal))]
    disp = np.concatenate([dv, de, np.array(combined).reshape(-1, *keys.neutral.shape)])
    return KeyModels(keys.neutral, names, disp, keys.head), importance
