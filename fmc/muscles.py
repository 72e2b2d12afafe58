"""Facial Animation Tables for any head with feature points: FaceEngine's hybrid muscle model.

Where a head has feature points but no sculpted shapes, its motion comes from a model of
the face placed from those points (Fratarcangeli and Schaerf's FaceEngine [1]_):

- a **parametric layer**: the jaw turns about the axis through the two jaw pivots, with
  full weight over the lower face and a cosine fade across the angular sector
  Vchin–Vpivot–Vneck; each eyelid turns about its lid axis; each eyeball about its centre,
  found as the midpoint of its two farthest vertices; the head about 7.1, faded linearly
  between the upper and lower neck lines;
- **Waters muscles** [2]_: linear muscles (a cone of influence about the line from the bone
  attachment to the skin insertion, angular and radial cosine fall-offs, Waters's skin
  elasticity k) and a sphincter for the mouth, placed from the feature points by
  ``fmc/data/muscles.toml``;
- the **combination rule** of [1]_: in the four groups forehead left/right and mouth
  up/down the displacement of a vertex takes the direction of the summed displacements
  of the group's muscles and the largest single magnitude; other muscles add up;
- the **upper/lower split**: the skin is labelled upper or lower by a flood fill that
  grows from the upper-lip and the lower-lip feature points at once (each vertex goes to
  the front that reaches it first along the mesh's edges), so the lips, which touch,
  stay apart; the jaw and the lower-face muscles act only on lower vertices.

:func:`author_from_muscles` turns the model into FATs: each low-level FAP is mapped to
the model by fitting non-negative muscle contractions (or the parametric angle) so that
its feature point moves along the FAP's axis by ``value × FAPU`` while unrelated points
stay still; FAPs no muscle serves (tongue, ears, the nose tip, puffed cheeks, lips pushed
forward) fall back to the local displacement field of :mod:`fmc.author`.
:func:`author_high_level_from_muscles` evaluates the model on the FAP combinations of
``fmc/data/high_level_faps.toml`` for the visemes and expressions.

References
----------
.. [1] M. Fratarcangeli, M. Schaerf, "Realistic modeling of animatable faces in MPEG-4",
   Computer Animation and Social Agents (CASA), 2004.
.. [2] K. Waters, "A muscle model for animating three-dimensional facial expression",
   SIGGRAPH 1987, Computer Graphics 21(4), 17–24.
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass, field
from importlib import resources

import numpy as np
import scipy.sparse as sp
from scipy.optimize import brentq, nnls
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull

from mpeg4.catalogue import FAPS, FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.fat import FAT, HIGH_LEVEL_UNIT, FaceDefMesh, FaceDefTable, FaceDefTransform, fap_unit
from mpeg4.head import Head

from .author import FapFit, _falloff, _special, unrelated

__all__ = ["GROUPS", "Muscle", "MuscleRig", "FapAction", "load_placement", "place_muscles", "split_lips",
           "eyeball_centre", "author_from_muscles", "author_high_level_from_muscles", "HIGH_LEVEL_FAPS"]

#: The combination groups of [1]: direction of the sum, largest single magnitude.
GROUPS = ("forehead_l", "forehead_r", "mouth_up", "mouth_down")

# Seeds of the two fronts of the lip split. The inner and outer contours of each lip are
# required; the rest (chin, jaw angles, cheeks, nose) steer the fronts over the face.
_UPPER_REQUIRED = ("2.2", "8.1")
_LOWER_REQUIRED = ("2.3", "8.2", "2.1")
_UPPER_SEEDS = ("2.2", "2.6", "2.7", "8.1", "8.5", "8.6", "8.9", "8.10", "9.15", "9.4", "9.5", "5.1", "5.2",
                "5.3", "5.4", "3.7", "3.12", "4.5", "4.6", "10.1", "10.2", "10.5", "10.6", "10.7", "10.8", "10.9",
                "10.10", "11.6")
_LOWER_SEEDS = ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8", "2.1", "2.10", "2.11", "2.12", "2.13", "2.14")

# The eyelid points of each eye: margin, fold (upper lid; lower lid), the two corners.
_LIDS = {"L": dict(part="eye_l", upper=("3.1", "3.13"), lower=("3.3", "3.9"), corners=("3.11", "3.7")),
         "R": dict(part="eye_r", upper=("3.2", "3.14"), lower=("3.4", "3.10"), corners=("3.8", "3.12"))}

# FAPs the model has no muscle for: the local displacement field of fmc.author moves them.
_FALLOFF_FAPS = frozenset({16, 17, 39, 40, 43, 44, 45, 46, 63, 64, 65, 66, 67, 68})
_JAW_PARTS = ("teeth_lower", "gums_lower", "tongue")
# Head rotation tables: sampled at these values (AU) to follow the neck's faded turn.
_HEAD_BORDERS = (-40000.0, -20000.0, -10000.0, 0.0, 10000.0, 20000.0, 40000.0)


# --- placement ------------------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def _placement_text() -> str:
    return resources.files("fmc").joinpath("data/muscles.toml").read_text()


def load_placement() -> dict:
    """The model's placement (``fmc/data/muscles.toml``) as a fresh dict."""
    return tomllib.loads(_placement_text())


def _point(head: Head, spec, es0: float, mirrored: bool, where: str) -> np.ndarray:
    """(3,) position of a placement point: Σ w·FP + offset·ES0 (mirrored for the right side)."""
    if not isinstance(spec, dict) or "at" not in spec:
        raise InputError("a placement point needs 'at' (feature point weights)", where=where,
                         fix='write it as { at = { "4.1" = 1.0 }, off = [0, 0, 0] }')
    at = spec["at"]
    off = np.asarray(spec.get("off", [0.0, 0.0, 0.0]), dtype=np.float64)
    total = sum(float(w) for w in at.values())
    if not at or abs(total - 1.0) > 1e-6:
        raise InputError(f"feature point weights sum to {total:g}, expected 1", where=where)
    if off.shape != (3,) or not np.isfinite(off).all():
        raise InputError(f"offset {spec.get('off')} is not three finite numbers", where=where)
    p = np.zeros(3)
    for fp_id, w in at.items():
        if fp_id not in FEATURE_POINTS:
            raise InputError(f"unknown feature point {fp_id!r}", where=where)
        i = FEATURE_POINTS[fp_id].mirror if mirrored and FEATURE_POINTS[fp_id].mirror else fp_id
        if i not in head.feature_points:
            raise InputError(f"{where.split(',')[0]} needs feature point {i}, which the head lacks",
                             fix="place the point (recon annotate / the fdp.json) before authoring")
        p += float(w) * head.fp_position(i)
    if mirrored:
        off = off * np.array([-1.0, 1.0, 1.0])
    return p + off * es0


@dataclass(frozen=True)
class Muscle:
    """One Waters muscle placed on a head.

    Attributes
    ----------
    name : str
    kind : {"linear", "sphincter"}
    head : (3,) float64
        Linear: the bone attachment the skin is pulled towards. Sphincter: the pull centre.
    tail : (3,) float64 or None
        Linear: the skin insertion.
    zone : float
        Half-angle of the cone of influence, radians (linear).
    fall_start, fall_end : float
        Radii (metres from the head) where the radial fall-off peaks and ends (linear).
    semi_axes : (3,) float64 or None
        Sphincter: semi-axes of its ellipsoid of influence, metres (the third, depth, is
        the first).
    midline : float
        Sphincter quadrant: half-width of the fade across the midline, metres (0: none).
    elasticity : float
        Waters's skin constant k.
    side : {"L", "R", "C"}
    group : str or None
        One of :data:`GROUPS`, or None (displacements add up).
    acts_on : {"all", "upper", "lower"}
    """

    name: str
    kind: str
    head: np.ndarray
    tail: np.ndarray | None
    zone: float
    fall_start: float
    fall_end: float
    semi_axes: np.ndarray | None
    midline: float
    elasticity: float
    side: str
    group: str | None
    acts_on: str
    midline_x: float = 0.0

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.tail - self.head)) if self.kind == "linear" else 0.0

    def displacement(self, vertices: np.ndarray) -> np.ndarray:
        """(N, 3) displacement of ``vertices`` (metres) at contraction 1.

        Linear: ``k · L · A(μ) · R(D) · (head − p)/|head − p|`` with ``A = cos(μ/zone · π/2)``
        inside the cone (μ the angle between head→p and head→tail) and the radial fall-off
        ``R = cos((1 − D/Rs) π/2)`` for ``D < Rs``, ``cos((D − Rs)/(Rf − Rs) π/2)`` up to Rf [2]_.
        Sphincter: ``k · (1 − ρ) · P(centre − p)``, ρ the ellipsoidal radius and P the
        projection on the frontal plane.
        """
        v = np.asarray(vertices, dtype=np.float64)
        if self.kind == "sphincter":
            q = v - self.head
            rho = np.sqrt(((q / self.semi_axes) ** 2).sum(axis=1))
            f = np.clip(1.0 - rho, 0.0, None)
            if self.midline > 0:
                s = 1.0 if self.side == "L" else -1.0
                f = f * np.clip(0.5 + s * (v[:, 0] - self.midline_x) / (2 * self.midline), 0.0, 1.0)
            out = -self.elasticity * f[:, None] * q
            out[:, 2] = 0.0  # the ring contracts in its own (frontal) plane
            return out
        d = v - self.head
        dist = np.linalg.norm(d, axis=1)
        axis = (self.tail - self.head) / self.length
        with np.errstate(invalid="ignore", divide="ignore"):
            mu = np.arccos(np.clip(d @ axis / dist, -1.0, 1.0))
            a = np.where(mu < self.zone, np.cos(mu / self.zone * np.pi / 2), 0.0)
            rs, rf = self.fall_start, self.fall_end
            r = np.where(dist < rs, np.cos((1.0 - dist / rs) * np.pi / 2),
                         np.where(dist < rf, np.cos((dist - rs) / (rf - rs) * np.pi / 2), 0.0))
            w = np.where(dist > 0, self.elasticity * self.length * a * r / dist, 0.0)
        return -w[:, None] * d


def _muscle(head: Head, name: str, spec: dict, es0: float, mirrored: bool, midline_x: float) -> Muscle:
    where = f"muscle {name}, fmc/data/muscles.toml"
    kind = spec.get("kind", "linear")
    side = "C" if not (name.endswith("_l") or name.endswith("_r")) else name[-1].upper()
    group = spec.get("group")
    if group is not None and mirrored:
        group = group[:-2] + "_r" if group.endswith("_l") else group
    if group is not None and group not in GROUPS:
        raise InputError(f"unknown combination group {group!r}", where=where, fix=f"use one of {', '.join(GROUPS)}")
    acts_on = spec.get("acts_on", "all")
    if acts_on not in ("all", "upper", "lower"):
        raise InputError(f"acts_on is {acts_on!r}", where=where, fix="use all, upper or lower")
    k = float(spec.get("elasticity", 0.0))
    if not np.isfinite(k) or k <= 0:
        raise InputError(f"elasticity is {k:g}; the skin must give (k > 0)", where=where)
    if kind == "sphincter":
        centre = _point(head, spec.get("centre"), es0, mirrored, where + ", centre")
        axes = np.asarray(spec.get("semi_axes", [0.0, 0.0]), dtype=np.float64) * es0
        if axes.shape != (2,) or not (axes > 1e-6).all():
            raise InputError(f"sphincter semi-axes {spec.get('semi_axes')} must be two positive lengths (ES0)",
                             where=where)
        return Muscle(name, kind, centre, None, 0.0, 0.0, 0.0, np.array([axes[0], axes[1], axes[0]]),
                      float(spec.get("midline", 0.0)) * es0, k, side, group, acts_on, midline_x)
    if kind != "linear":
        raise InputError(f"unknown muscle kind {kind!r}", where=where, fix="use linear or sphincter")
    h = _point(head, spec.get("head"), es0, mirrored, where + ", head")
    t = _point(head, spec.get("tail"), es0, mirrored, where + ", tail")
    length = float(np.linalg.norm(t - h))
    if length < 1e-3 * es0:
        raise InputError(f"head and tail coincide ({length * 1000:.3f} mm apart): the muscle has no direction",
                         where=where, fix="move the head (bone attachment) away from the tail (skin insertion)")
    zone = np.radians(float(spec.get("zone", 0.0)))
    if not 0 < zone < np.pi:
        raise InputError(f"zone half-angle {spec.get('zone')} degrees is outside (0, 180)", where=where)
    fs, fe = float(spec.get("fall_start", 1.0)), float(spec.get("fall_end", 0.0))
    if not 0 < fs < fe:
        raise InputError(f"fall-off radii start {fs:g} and end {fe:g} (muscle lengths) must satisfy 0 < start < end",
                         where=where)
    return Muscle(name, kind, h, t, float(zone), fs * length, fe * length, None, 0.0, k, side, group, acts_on,
                  midline_x)


def place_muscles(head: Head, placement: dict | None = None) -> list[Muscle]:
    """The muscles of ``placement`` (default ``fmc/data/muscles.toml``) placed on ``head``.

    Muscles named ``*_l`` are mirrored to ``*_r``. Raises :class:`InputError` naming the
    muscle and the feature point when a point is missing, and for degenerate placements
    (head and tail together, an empty cone, fall-off radii out of order, a muscle whose
    zone holds no skin vertex).
    """
    placement = load_placement() if placement is None else placement
    es0 = head.fapu.ES0
    midline_x = float(np.mean([head.fp_position(i)[0] for i in ("2.2", "8.1") if i in head.feature_points]
                              or [0.0]))
    out = []
    for name, spec in placement.get("muscles", {}).items():
        out.append(_muscle(head, name, spec, es0, False, midline_x))
        if name.endswith("_l"):
            out.append(_muscle(head, name[:-2] + "_r", spec, es0, True, midline_x))
    skin = head.skin.vertices
    for m in out:
        if not np.abs(m.displacement(skin)).max(initial=0.0) > 0:
            raise InputError(f"muscle {m.name} moves no skin vertex: its zone of influence misses the face",
                             where="fmc/data/muscles.toml",
                             fix="place its tail (insertion) on the skin and its head within reach of it")
    return out


# --- geometry of the parametric layer ---------------------------------------------------

def _edge_graph(part) -> sp.csr_matrix:
    """The mesh's edges weighted by length, with copies of one vertex (a texture seam stores
    a vertex once per side) joined, so that distances run across seams."""
    t = part.triangles
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    _, first, inverse = np.unique(np.round(part.vertices, 9), axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    copies = np.flatnonzero(first[inverse] != np.arange(part.n_vertices))
    e = np.concatenate([e, np.c_[copies, first[inverse[copies]]]])
    w = np.linalg.norm(part.vertices[e[:, 0]] - part.vertices[e[:, 1]], axis=1) + 1e-12
    n = part.n_vertices
    g = sp.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    return g.maximum(g.T).tocsr()


def split_lips(head: Head, corner: float = 0.1) -> np.ndarray:
    """(N,) +1 for skin vertices of the upper face, −1 for the lower face (jaw, lower lip),
    0 where the two meet (the lip corners).

    A two-front flood fill over the skin's edges: one front starts from the upper-lip
    points (and the nose, cheeks, ears), the other from the lower-lip points (and the
    chin and jaw angles); each vertex takes the label of the front that reaches it first
    (geodesic distance along edges). Vertices within ``corner`` × MW0 of a lip corner
    (2.4, 2.5, 8.3, 8.4) belong to both. Lips that touch but share no edge are kept apart
    whatever their shape.

    Raises
    ------
    InputError
        When a lip or chin point it needs (2.2, 8.1, 2.3, 8.2, 2.1) is missing.
    """
    for i in _UPPER_REQUIRED + _LOWER_REQUIRED:
        if i not in head.feature_points:
            raise InputError(f"the upper/lower lip split needs feature point {i}, which the head lacks",
                             fix="place the inner and outer lip centres and the chin (2.1)")
        if head.feature_points[i].part != "skin":
            raise InputError(f"feature point {i} is bound to part '{head.feature_points[i].part}', not the skin")

    up, lo = _fronts(head)
    label = np.where(lo <= up, -1, 1).astype(np.int8)
    corners = [head.fp_position(i) for i in ("2.4", "2.5", "8.3", "8.4") if i in head.feature_points]
    if corners:
        v = head.skin.vertices
        near = np.min([np.linalg.norm(v - c, axis=1) for c in corners], axis=0) < corner * head.fapu.MW0
        label[near] = 0
    return label


def _fronts(head: Head) -> tuple[np.ndarray, np.ndarray]:
    """(N,) geodesic distances (metres along the skin's edges) to the upper and the lower seeds."""
    def seeds(ids):
        return sorted({v for i in ids if i in head.feature_points and head.feature_points[i].part == "skin"
                       for v in head.feature_points[i].vertices})

    g = _edge_graph(head.skin)
    return (dijkstra(g, indices=seeds(_UPPER_SEEDS), min_only=True),
            dijkstra(g, indices=seeds(_LOWER_SEEDS), min_only=True))


def eyeball_centre(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and radius of an eyeball: the midpoint of its two farthest vertices [1]_.

    Parameters
    ----------
    vertices : (N, 3) array, N ≥ 4 not coplanar

    Returns
    -------
    centre : (3,) float64
    radius : float
        Half the largest distance.
    """
    v = np.asarray(vertices, dtype=np.float64)
    try:
        hull = v[ConvexHull(v).vertices]
    except Exception as e:  # scipy's QhullError: flat or too few points
        raise InputError(f"an eyeball of {len(v)} vertices has no volume ({type(e).__name__})",
                         fix="give each eye as a closed mesh") from None
    d = ((hull[:, None, :] - hull[None, :, :]) ** 2).sum(axis=2)
    i, j = np.unravel_index(int(d.argmax()), d.shape)
    return 0.5 * (hull[i] + hull[j]), 0.5 * float(np.sqrt(d[i, j]))


def _rotate(v: np.ndarray, centre: np.ndarray, axis: np.ndarray, angle) -> np.ndarray:
    """Rotate (N, 3) points about the line through ``centre`` along unit ``axis`` by
    ``angle`` radians (scalar or (N,)), right-handed (Rodrigues)."""
    p = v - centre
    a = np.broadcast_to(np.asarray(angle, dtype=np.float64), (len(v),))[:, None]
    c, s = np.cos(a), np.sin(a)
    return centre + p * c + np.cross(axis, p) * s + axis * (p @ axis)[:, None] * (1 - c)


@dataclass
class _Lid:
    axis: np.ndarray
    points: dict  # +1 closing, -1 opening: a point on the axis of that stroke
    sense: float  # the turn about `axis` that closes the lid
    weights: np.ndarray  # (N,) over the skin
    margin: str


@dataclass
class FapAction:
    """What one unit of a FAP (on one side of 0) does to the model.

    Attributes
    ----------
    route : str
        ``muscles``, ``jaw``, ``eyelid``, ``eyeball``, ``neck``, ``pupil`` or ``falloff``.
    muscles : dict of str to float
        Muscle name → contraction per FAP unit (of the FAP's absolute value).
    params : dict of str to float
        Parametric amount per FAP unit (radians or metres), signed.
    """

    route: str
    muscles: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)


class MuscleRig:
    """FaceEngine's hybrid model placed on one head (see the module docstring).

    Build with :meth:`from_head`; :meth:`deform` moves the head for a model state
    (muscle contractions and parametric amounts), :meth:`state` turns FAP values into a
    state through the FAP mapping that :func:`author_from_muscles` fits.
    """

    def __init__(self, head: Head, muscles: list[Muscle], placement: dict):
        self.head = head
        self.muscles = muscles
        self.names = [m.name for m in muscles]
        skin = head.skin.vertices
        self.n_skin = len(skin)
        self.lips = split_lips(head)
        fields = []
        for m in muscles:
            d = m.displacement(skin)
            if m.acts_on == "lower":
                d[self.lips > 0] = 0.0
            elif m.acts_on == "upper":
                d[self.lips < 0] = 0.0
            fields.append(d)
        fields = np.array(fields)
        # Only vertices some muscle moves take part in the per-frame sums.
        self.support = np.flatnonzero(np.abs(fields).max(axis=(0, 2)) > 0)
        self.fields = np.ascontiguousarray(fields[:, self.support])  # (M, S, 3), contraction 1
        self.groups = {g: [k for k, m in enumerate(muscles) if m.group == g] for g in GROUPS}
        self.ungrouped = [k for k, m in enumerate(muscles) if m.group is None]
        self.actions: dict[tuple[int, int], FapAction] = {}
        self.fallback = FAT()  # tables of the FAPs outside the model, added linearly
        self._place_parametric(placement)

    @classmethod
    def from_head(cls, head: Head, placement: dict | None = None) -> MuscleRig:
        """Place the model on ``head`` (see :func:`place_muscles` for the errors)."""
        placement = load_placement() if placement is None else placement
        if "skin" not in head.parts:
            raise InputError("the muscle model needs a 'skin' part", fix=f"name the face mesh 'skin' ({sorted(head.parts)})")
        return cls(head, place_muscles(head, placement), placement)

    # --- placement of the parametric layer ---
    def _place_parametric(self, placement: dict) -> None:
        head, es0 = self.head, self.head.fapu.ES0
        skin = head.skin.vertices
        jaw = placement.get("jaw", {})
        pl = _point(head, jaw.get("pivot_l"), es0, False, "the jaw pivot, fmc/data/muscles.toml [jaw]")
        pr = _point(head, jaw.get("pivot_l"), es0, True, "the jaw pivot, fmc/data/muscles.toml [jaw]")
        chin = _point(head, jaw.get("chin"), es0, False, "the jaw's chin, fmc/data/muscles.toml [jaw]")
        neck = _point(head, jaw.get("neck"), es0, False, "the jaw's neck point, fmc/data/muscles.toml [jaw]")
        if np.linalg.norm(pl - pr) < 0.1 * es0:
            raise InputError("the two jaw pivots coincide: the jaw has no axis", where="fmc/data/muscles.toml [jaw]")
        self.jaw_axis = (pl - pr) / np.linalg.norm(pl - pr)
        self.jaw_centre = 0.5 * (pl + pr)
        e1 = self._perp(chin - self.jaw_centre)
        e2 = self._perp(neck - self.jaw_centre)
        e2 = e2 - (e2 @ e1) * e1
        if np.linalg.norm(e1) < 1e-9 or np.linalg.norm(e2) < 1e-9:
            raise InputError("the chin and the neck point lie on one line through the jaw pivot: the jaw sector is empty",
                             where="fmc/data/muscles.toml [jaw]")
        e2 /= np.linalg.norm(e2)
        q = skin - self.jaw_centre
        phi = np.arctan2(q @ e2, q @ e1)
        phi_neck = float(np.arctan2((neck - self.jaw_centre) @ e2, (neck - self.jaw_centre) @ e1))
        w = np.where(phi <= 0, 1.0, np.where(phi < phi_neck, np.cos(phi / phi_neck * np.pi / 2), 0.0))
        w[phi < -np.pi / 2] = 0.0  # behind and above the pivot: the skull
        # Across the lips the split is sharp (they only touch); over the cheeks the jaw's
        # share fades where the two fronts meet, over a band as wide as half the distance
        # the fronts have come, so the skin over the jaw line stretches instead of tearing.
        up, lo = _fronts(head)
        band = np.maximum(0.5 * np.minimum(up, lo), 1e-6)
        lower = np.clip(0.5 + (up - lo) / (2 * band), 0.0, 1.0)
        self.jaw_weights = w * lower
        neck_spec = placement.get("neck", {})
        up = _point(head, neck_spec.get("upper"), es0, False, "the upper neck line, fmc/data/muscles.toml [neck]")[1]
        lo = _point(head, neck_spec.get("lower"), es0, False, "the lower neck line, fmc/data/muscles.toml [neck]")[1]
        if not up > lo:
            raise InputError(f"the upper neck line ({up * 1000:.1f} mm) is not above the lower one ({lo * 1000:.1f} mm)",
                             where="fmc/data/muscles.toml [neck]")
        self.neck_lines = (lo, up)
        for i in ("7.1",):
            if i not in head.feature_points:
                raise InputError(f"head rotation needs feature point {i}, which the head lacks")
        self.head_centre = head.fp_position("7.1")
        # Eyeballs and lids.
        self.eyes: dict[str, tuple[np.ndarray, float]] = {}
        self.lids: dict[tuple[str, str], _Lid] = {}
        reach = placement.get("lids", {}).get("reach", [1.35, 1.75])
        for side, spec in _LIDS.items():
            if spec["part"] in head.parts:
                self.eyes[side] = eyeball_centre(head.parts[spec["part"]].vertices)
            self._place_lids(side, spec, reach)

    def _perp(self, v: np.ndarray) -> np.ndarray:
        v = v - (v @ self.jaw_axis) * self.jaw_axis
        n = np.linalg.norm(v)
        return v / n if n > 0 else v

    def _place_lids(self, side: str, spec: dict, reach) -> None:
        head = self.head
        needed = spec["upper"] + spec["lower"] + spec["corners"]
        missing = [i for i in needed if i not in head.feature_points]
        if missing:
            raise InputError(f"the {'left' if side == 'L' else 'right'} eyelids need feature point"
                             f"{'s' if len(missing) > 1 else ''} {', '.join(missing)}, which the head lacks",
                             fix="place the lid margins, folds and eye corners")
        if side not in self.eyes:
            raise InputError(f"the {'left' if side == 'L' else 'right'} eyelids turn over the eyeball, "
                             f"but the head has no part '{spec['part']}'", fix="give the eyeballs as parts eye_l/eye_r")
        c, r = self.eyes[side]
        p = {i: head.fp_position(i) for i in needed}
        inner, outer = p[spec["corners"][0]], p[spec["corners"][1]]
        a = (outer - inner) * np.array([1.0, 1.0, 0.0])  # the corner line seen from the front
        if np.linalg.norm(a) < 1e-6:
            raise InputError(f"the eye corners {spec['corners'][0]} and {spec['corners'][1]} coincide in the front view")
        a /= np.linalg.norm(a)
        u = np.array([0.0, 1.0, 0.0]) - a[1] * a
        u /= np.linalg.norm(u)
        f = np.array([0.0, 0.0, 1.0]) - a[2] * a - u[2] * u
        f /= np.linalg.norm(f)
        skin = head.skin.vertices
        mid, half = 0.5 * (inner + outer), 0.5 * np.linalg.norm(outer - inner)
        t = (skin - mid) @ a / half
        w_corner = np.clip(1.0 - t ** 2, 0.0, 1.0)
        rho = np.linalg.norm(skin - c, axis=1) / r
        r0, r1 = reach
        w_reach = np.where(rho <= r0, 1.0, np.where(rho < r1, np.cos((rho - r0) / (r1 - r0) * np.pi / 2), 0.0))
        h = {i: (p[i] - c) @ u for i in needed}
        h_open = 0.5 * (h[spec["upper"][0]] + h[spec["lower"][0]])
        for lid, (margin, fold) in (("upper", spec["upper"]), ("lower", spec["lower"])):
            if (h[margin] - h_open) * (1 if lid == "upper" else -1) <= 0 or \
                    (h[fold] - h[margin]) * (1 if lid == "upper" else -1) <= 0:
                raise InputError(f"the {lid} lid's points are out of order: {fold} (fold) must lie "
                                 f"{'above' if lid == 'upper' else 'below'} {margin} (margin), which must lie "
                                 f"{'above' if lid == 'upper' else 'below'} the middle of the eye opening")
            # Closing turns about an axis at the middle of the closing stroke (margin to the
            # opening's centre), opening about one as far on the other side of the margin,
            # so the margin's chord runs vertically over a stroke of half the opening.
            stroke = h_open - h[margin]
            point = c + u * (h[margin] + 0.5 * stroke)
            points = {1: point, -1: c + u * (h[margin] - 0.5 * stroke)}

            def ang(x):
                q = x - point
                return np.arctan2(q @ u, q @ f)

            psi, psi_m, psi_f, psi_o = ang(skin), ang(p[margin]), ang(p[fold]), ang(c + u * h_open + f * r)
            s = 1.0 if lid == "upper" else -1.0
            x, xm, xf, xo = s * psi, s * psi_m, s * psi_f, s * psi_o
            w_ang = np.where((x >= xo) & (x <= xm), 1.0,
                             np.where((x > xm) & (x < xf), np.cos((x - xm) / (xf - xm) * np.pi / 2), 0.0))
            turned = _rotate(p[margin][None], point, a, 1e-3)[0]
            sense = 1.0 if (turned - p[margin]) @ u * np.sign(stroke) > 0 else -1.0
            self.lids[(side, lid)] = _Lid(a, points, sense, w_ang * w_corner * w_reach, margin)

    # --- the model ---
    def muscle_displacement(self, contractions) -> np.ndarray:
        """(N, 3) skin displacement for muscle contractions by the combination rule.

        Parameters
        ----------
        contractions : (M,) array or mapping of muscle name to contraction (≥ 0)
        """
        c = self._vector(contractions)
        out = np.zeros((self.n_skin, 3))
        sub = np.zeros((len(self.support), 3))
        for members in self.groups.values():
            active = [k for k in members if c[k] > 0]
            if not active:
                continue
            parts = self.fields[active] * c[active, None, None]
            total = parts.sum(axis=0)
            norm = np.linalg.norm(total, axis=1)
            biggest = np.linalg.norm(parts, axis=2).max(axis=0)
            sub += np.where(norm[:, None] > 0, total * (biggest / np.where(norm > 0, norm, 1.0))[:, None], 0.0)
        rest = [k for k in self.ungrouped if c[k] > 0]
        if rest:
            sub += np.einsum("m,msc->sc", c[rest], self.fields[rest])
        out[self.support] = sub
        return out

    def _vector(self, contractions) -> np.ndarray:
        if isinstance(contractions, dict):
            c = np.zeros(len(self.names))
            for name, x in contractions.items():
                c[self.names.index(name)] = x
            return c
        return np.asarray(contractions, dtype=np.float64)

    def deform(self, contractions=None, params=None, vertices=None) -> dict[str, np.ndarray]:
        """Part name → (N, 3) vertices of the head in a model state.

        The parametric layer first (lids, jaw), then the muscles (their displacement,
        computed on the neutral skin, added), then the head's turn, faded over the neck.

        Parameters
        ----------
        contractions : mapping of str to float or (M,) array, optional
        params : mapping, optional
            ``jaw`` (rad, opening), ``jaw_thrust`` (m, +z), ``jaw_shift`` (m, −x),
            ``lid_{L,R}_{upper,lower}`` (rad, closing; negative opens), ``eye_{L,R}_{yaw,pitch}`` (rad),
            ``eye_{L,R}_thrust`` (m), ``pupil_{L,R}`` (m of pupil radius),
            ``head_{pitch,yaw,roll}`` (rad).
        vertices : mapping, optional
            Neutral vertices to start from (default the head's).
        """
        head, params = self.head, dict(params or {})
        out = {n: (p.vertices if vertices is None else vertices[n]).copy() for n, p in head.parts.items()}
        skin = out["skin"]
        for (side, lid), rig in self.lids.items():
            angle = params.get(f"lid_{side}_{lid}", 0.0)
            if angle:
                moving = rig.weights > 0
                skin[moving] = _rotate(skin[moving], rig.points[1 if angle > 0 else -1], rig.axis,
                                       rig.sense * angle * rig.weights[moving])
        jaw = params.get("jaw", 0.0)
        thrust = np.array([-params.get("jaw_shift", 0.0), 0.0, params.get("jaw_thrust", 0.0)])
        if jaw or thrust.any():
            moving = self.jaw_weights > 0
            w = self.jaw_weights[moving]
            if jaw:
                skin[moving] = _rotate(skin[moving], self.jaw_centre, self.jaw_axis, jaw * w)
            skin[moving] += w[:, None] * thrust
            for part in _JAW_PARTS:
                if part in out:
                    if jaw:
                        out[part] = _rotate(out[part], self.jaw_centre, self.jaw_axis, jaw)
                    out[part] = out[part] + thrust
        if contractions is not None:
            skin += self.muscle_displacement(contractions)
        for side, (c, _) in self.eyes.items():
            part = _LIDS[side]["part"]
            pupil = params.get(f"pupil_{side}", 0.0)
            if pupil:
                out[part] = out[part] + pupil * self._pupil_field(side)
            for name, axis in (("yaw", np.array([0.0, 1.0, 0.0])), ("pitch", np.array([1.0, 0.0, 0.0]))):
                angle = params.get(f"eye_{side}_{name}", 0.0)
                if angle:
                    out[part] = _rotate(out[part], c, axis, angle)
            thrust_eye = params.get(f"eye_{side}_thrust", 0.0)
            if thrust_eye:
                out[part] = out[part] + np.array([0.0, 0.0, thrust_eye])
        for name, k in (("pitch", 48), ("yaw", 49), ("roll", 50)):
            angle = params.get(f"head_{name}", 0.0)
            if angle:
                axis = FAPS[k].axis_vector
                for part, v in out.items():
                    w = self.neck_weight(head.parts[part].vertices)
                    out[part] = _rotate(v, self.head_centre, axis, angle * w)
        return out

    def neck_weight(self, vertices: np.ndarray) -> np.ndarray:
        """(N,) share of the head's turn: 1 above the upper neck line, 0 below the lower."""
        lo, up = self.neck_lines
        return np.clip((vertices[:, 1] - lo) / (up - lo), 0.0, 1.0)

    def _pupil_field(self, side: str) -> np.ndarray:
        """(N, 3) radial motion of the eye's vertices per metre of pupil radius.

        The rim of the neutral pupil (a third of the iris, reference section 6) moves by
        1; the field falls linearly to the pupil's centre and to the iris's rim.
        """
        part = _LIDS[side]["part"]
        v = self.head.parts[part].vertices
        c, r = self.eyes[side]
        fp = "3.5" if side == "L" else "3.6"
        g = self.head.fp_position(fp) - c if fp in self.head.feature_points else np.array([0.0, 0.0, 1.0])
        g /= np.linalg.norm(g)
        q = v - c
        radial = q - (q @ g)[:, None] * g
        rho = np.linalg.norm(radial, axis=1)
        iris = 0.5 * self.head.fapu.IRISD0
        pupil = iris / 3.0
        prof = np.where(rho <= pupil, rho / pupil, np.clip((iris - rho) / (iris - pupil), 0.0, None))
        prof[(q @ g) < 0.5 * r] = 0.0  # the front of the eye only
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = np.where(rho[:, None] > 0, radial / rho[:, None], 0.0)
        return prof[:, None] * unit

    def state(self, values) -> tuple[np.ndarray, dict]:
        """Muscle contractions (M,) and parametric amounts for low-level FAP values.

        Each FAP contributes ``|value| ×`` its fitted :class:`FapAction` on the side of 0 its
        value lies; contributions add.
        """
        c = np.zeros(len(self.names))
        params: dict[str, float] = {}
        for n, value in values.items():
            if not value or isinstance(n, tuple):
                continue
            action = self.actions.get((int(n), 1 if value > 0 else -1))
            if action is None:
                continue
            for name, x in action.muscles.items():
                c[self.names.index(name)] += abs(value) * x
            for name, x in action.params.items():
                params[name] = params.get(name, 0.0) + abs(value) * x
        return c, params

    def deform_faps(self, values) -> dict[str, np.ndarray]:
        """Part name → vertices for low-level FAP values through the model (the FAPs the
        model does not serve add their fallback tables linearly)."""
        c, params = self.state(values)
        out = self.deform(c if c.any() else None, params)
        fapu = self.head.fapu
        for n, value in values.items():
            table = self.fallback.get((int(n), 0)) if not isinstance(n, tuple) and value else None
            if table is not None:
                unit = fap_unit(table.fap, fapu)
                for m in table.meshes:
                    out[m.part][m.indices] += m.offsets(value, unit)
        return out


# --- authoring --------------------------------------------------------------------------

def _table(head: Head, n: int, samples: dict, unit: float, high_level: int = 0, tol: float = 1e-6,
           transforms=()) -> FaceDefTable:
    """A FaceDefTable from positions sampled at interval borders.

    ``samples`` maps each non-zero border value to part → (N, 3) displacement reached at
    that value; the slope of each interval is the difference over its length (reference
    section 5), so the decoder reproduces every sample exactly.
    """
    borders = sorted(set(samples) | {0.0})
    parts = sorted({p for s in samples.values() for p in s})
    table = FaceDefTable(n, high_level, transforms=list(transforms))
    for part in parts:
        nv = head.parts[part].n_vertices
        at = [samples[b].get(part, np.zeros((nv, 3))) if b else np.zeros((nv, 3)) for b in borders]
        moving = np.flatnonzero(np.max([np.abs(a).max(axis=1) for a in at], axis=0) > tol)
        if not len(moving):
            continue
        d = np.stack([(at[k + 1][moving] - at[k][moving]) / ((borders[k + 1] - borders[k]) * unit)
                      for k in range(len(borders) - 1)], axis=1)
        table.meshes.append(FaceDefMesh(part, np.array(borders), moving, d))
    return table


def _fp_motion(head: Head, moved: dict, neutral: dict, ids: list[str]) -> np.ndarray:
    return np.array([head.fp_position(i, moved) - head.fp_position(i, neutral) for i in ids])


def _diff(moved: dict, neutral: dict) -> dict:
    return {p: moved[p] - neutral[p] for p in moved if np.abs(moved[p] - neutral[p]).max(initial=0) > 0}


def author_from_muscles(head: Head, value: float = 512.0, tol: float = 0.10, leak_tol: float = 0.20,
                        faps=None, rig: MuscleRig | None = None) -> tuple[FAT, list[FapFit]]:
    """FATs for the low-level FAPs of ``head`` from FaceEngine's hybrid model.

    Parameters
    ----------
    head : Head
        With a skin, eyeballs (``eye_l``/``eye_r``) and the feature points the model's
        placement names; sculpted shapes are not used.
    value : float
        FAP value the tables are authored at (interval borders ±value; the jaw also at
        2·value, the head's turn at ±10000, ±20000, ±40000 AU).
    tol, leak_tol : float
        A muscle fit is kept when the FP's motion is within ``tol`` of the target and no
        unrelated FP moves by more than ``leak_tol`` of it; otherwise the FAP falls back
        to the local displacement field (route ``falloff``).
    faps : iterable of int, optional
        FAPs to author (default 3..68).
    rig : MuscleRig, optional
        A placed model (default: placed from ``fmc/data/muscles.toml``); its FAP mapping
        (:attr:`MuscleRig.actions`) is filled in.

    Returns
    -------
    fat : FAT
    report : list of FapFit
        ``weights`` holds the contractions at ``+value`` for muscle FAPs.
    """
    rig = MuscleRig.from_head(head) if rig is None else rig
    fapu = head.fapu
    ids = [i for i in FP_IDS if i in head.feature_points]
    neutral = {n: p.vertices for n, p in head.parts.items()}
    fat, report = FAT(), []
    a_matrix = None
    for n in (range(3, 69) if faps is None else faps):
        fap = FAPS[n]
        fp_id = fap.feature_points[0]
        if fp_id not in head.feature_points:
            raise InputError(f"FAP {n} ({fap.name}) needs feature point {fp_id}, which the head lacks",
                             fix="place the point (recon annotate / the fdp.json) before authoring")
        unit = fap_unit(n, fapu)
        signs = (1,) if fap.direction == "U" else (-1, 1)
        if n in (48, 49, 50):
            report.append(_author_head_turn(rig, fat, n, unit))
            continue
        if n in (23, 24, 25, 26):
            side = "L" if "_l_" in fap.name else "R"
            part = _LIDS[side]["part"]
            if side not in rig.eyes:
                raise InputError(f"FAP {n} ({fap.name}) turns part '{part}', which the head lacks",
                                 fix="give the eyeballs as parts eye_l/eye_r")
            fat.add(FaceDefTable(n, transforms=[FaceDefTransform(part, "rotation", rig.eyes[side][0],
                                                                 fap.axis_vector, 1.0)]))
            name, model_axis = ("yaw", np.array([0.0, 1.0, 0.0])) if n in (23, 24) else ("pitch", np.array([1.0, 0, 0]))
            for s in signs:  # the model turns about +y / +x: the FAP's own axis gives the sense
                rig.actions[(n, s)] = FapAction("eyeball",
                                                params={f"eye_{side}_{name}": s * unit * (fap.axis_vector @ model_axis)})
            report.append(FapFit(n, "eyeball"))
            continue
        if n in (27, 28):
            side = "L" if n == 27 else "R"
            part = _LIDS[side]["part"]
            if part not in head.parts:
                raise InputError(f"FAP {n} ({fap.name}) moves part '{part}', which the head lacks")
            fat.add(FaceDefTable(n, transforms=[FaceDefTransform(part, "translation", amount=fap.axis_vector)]))
            for s in signs:
                rig.actions[(n, s)] = FapAction("eyeball", params={f"eye_{side}_thrust": s * unit})
            report.append(FapFit(n, "eyeball"))
            continue
        if n in (29, 30):
            side = "L" if n == 29 else "R"
            if side not in rig.eyes:
                raise InputError(f"FAP {n} ({fap.name}) dilates the pupil of part '{_LIDS[side]['part']}', "
                                 "which the head lacks")
            samples = {}
            for s in signs:
                rig.actions[(n, s)] = FapAction("pupil", params={f"pupil_{side}": s * 0.5 * unit})
                samples[s * value] = _diff(rig.deform(None, {f"pupil_{side}": s * 0.5 * value * unit}), neutral)
            fat.add(_table(head, n, samples, unit))
            report.append(FapFit(n, "pupil"))
            continue
        if n == 47:  # tongue roll: the author module's lift of the tongue's sides
            table, fit = _special(head, n, value)
            fat.add(table)
            rig.fallback.add(table)
            report.append(fit)
            continue
        goal_axis = fap.axis_vector
        k = ids.index(fp_id)
        bad = unrelated(fp_id, ids)
        samples, route, err_all, leak_all, weights = {}, None, 0.0, 0.0, None
        for s in signs:
            goal = s * value * unit * goal_axis
            g = float(np.linalg.norm(goal))
            if n in (3, 14, 15):
                action, moved = _fit_jaw(rig, n, s, value, unit, goal)
            elif n in (19, 20, 21, 22):
                action, moved = _fit_lid(rig, n, s, value, unit, goal)
            elif n in _FALLOFF_FAPS:
                action, moved = None, None
            else:
                if a_matrix is None:
                    a_matrix = _muscle_matrix(rig, ids)
                action, moved = _fit_muscles(rig, a_matrix, ids, k, bad, goal, value)
            if moved is not None:
                motion = _fp_motion(head, moved, neutral, ids)
                along = motion[k] @ goal / g
                err = abs(along - g) / g if n in (3, 14, 15) else float(np.linalg.norm(motion[k] - goal) / g)
                leak = float(np.linalg.norm(motion[bad], axis=1).max(initial=0) / g)
            if moved is None or err > tol or leak > leak_tol:
                disp = _falloff(head, fp_id, goal)
                moved = {p: neutral[p] + d.dense(head.parts[p].n_vertices) for p, d in disp.items()}
                motion = _fp_motion(head, moved, neutral, ids)
                err = float(np.linalg.norm(motion[k] - goal) / g)
                leak = float(np.linalg.norm(motion[bad], axis=1).max(initial=0) / g)
                action, this_route = None, "falloff"
            else:
                this_route = action.route
                rig.actions[(n, s)] = action
                if s > 0 and action.muscles:
                    weights = {m: x * value for m, x in action.muscles.items()}
            route = this_route if route in (None, this_route) else f"{route}+{this_route}"
            samples[s * value] = _diff(moved, neutral)
            if n == 3 and action is not None:  # the jaw follows its arc: a second interval to twice the value
                samples[2 * value] = _diff(rig.deform(None, {"jaw": 2 * value * action.params["jaw"]}), neutral)
            err_all, leak_all = max(err_all, err), max(leak_all, leak)
        transforms = _jaw_transforms(rig, n, signs, unit) if route in ("jaw",) else ()
        if transforms:  # the rigid jaw parts turn exactly; their meshes go
            for b in samples:
                for part in _JAW_PARTS:
                    samples[b].pop(part, None)
        table = _table(head, n, samples, unit, transforms=transforms)
        fat.add(table)
        if "falloff" in route:
            rig.fallback.add(_falloff_only(table, rig, n, signs, head, value, unit, samples))
        report.append(FapFit(n, route, err_all, leak_all, weights))
    return fat, report


def _falloff_only(table, rig, n, signs, head, value, unit, samples):
    """The part of a FAP's table the model does not produce (its falloff side(s))."""
    if all((n, s) not in rig.actions for s in signs):
        return table
    keep = {b: d for b, d in samples.items() if (n, 1 if b > 0 else -1) not in rig.actions}
    return _table(head, n, keep, unit)


def _muscle_matrix(rig: MuscleRig, ids: list[str]) -> np.ndarray:
    """(3 K, M): motion of each FP under each muscle at contraction 1 (summed model)."""
    head = rig.head
    a = np.zeros((3 * len(ids), len(rig.names)))
    pos = {int(v): j for j, v in enumerate(rig.support)}
    for k, i in enumerate(ids):
        b = head.feature_points[i]
        if b.part != "skin":
            continue
        for v, w in zip(b.vertices, b.weights):
            j = pos.get(int(v))
            if j is not None:
                a[3 * k:3 * k + 3] += w * rig.fields[:, j, :].T
    return a


def _fit_muscles(rig, a, ids, k, bad, goal, value):
    """Non-negative contractions moving FP k to ``goal`` with unrelated FPs still; the
    combination rule then applied and the result scaled so the motion along the axis is exact."""
    weights = np.where(bad, 1.0, 0.1)
    weights[k] = 3.0
    row_w = np.repeat(weights, 3)
    target = np.zeros(3 * len(ids))
    target[3 * k:3 * k + 3] = goal
    useful = np.abs(a[3 * k:3 * k + 3]).max(axis=0) > 0
    if not useful.any():
        return None, None
    c = np.zeros(a.shape[1])
    c[useful], _ = nnls(a[:, useful] * row_w[:, None], target * row_w, maxiter=2000)
    if not c.any():
        return None, None
    head = rig.head
    neutral = {n: p.vertices for n, p in head.parts.items()}
    g = float(np.linalg.norm(goal))
    along = _fp_motion(head, rig.deform(c), neutral, [ids[k]])[0] @ goal / g ** 2
    if along <= 1e-9:
        return None, None
    c = c / along  # the combination rule is homogeneous: scaling c scales the motion
    action = FapAction("muscles", muscles={rig.names[j]: float(x) / value for j, x in enumerate(c) if x > 0})
    return action, rig.deform(c)


def _solve_scalar(fn, target: float, hi: float) -> float:
    """The smallest x in (0, hi] with fn(x) = target, for fn rising from fn(0) = 0 (the
    bracket grows from hi/64 so that arcs past their turning point are not taken)."""
    lo, x = 0.0, hi / 64
    while x <= hi:
        if fn(x) >= target:
            return brentq(lambda t: fn(t) - target, lo, x, xtol=1e-12)
        lo, x = x, 2 * x
    raise InputError(f"the model cannot reach the authoring value (at most {fn(hi):.4g} m of {target:.4g} m)",
                     fix="author at a smaller value")


def _fit_jaw(rig: MuscleRig, n: int, s: int, value: float, unit: float, goal: np.ndarray):
    head = rig.head
    g = float(np.linalg.norm(goal))
    axis = goal / g
    if n == 3:
        def drop(angle):
            return float((head.fp_position("2.1", rig.deform(None, {"jaw": angle})) - head.fp_position("2.1")) @ axis)
        angle = _solve_scalar(drop, g, 1.2)
        params = {"jaw": angle / value}
    elif n == 14:
        w = float(np.asarray(head.feature_points["2.1"].weights) @ rig.jaw_weights[list(head.feature_points["2.1"].vertices)])
        params = {"jaw_thrust": unit / max(w, 1e-9)}
    else:
        w = float(np.asarray(head.feature_points["2.1"].weights) @ rig.jaw_weights[list(head.feature_points["2.1"].vertices)])
        params = {"jaw_shift": s * unit / max(w, 1e-9)}
    if head.feature_points["2.1"].part != "skin" or not rig.jaw_weights[list(head.feature_points["2.1"].vertices)].any():
        raise InputError("the chin (2.1) lies outside the jaw's sector: the jaw would not move it",
                         where="fmc/data/muscles.toml [jaw]", fix="check the jaw pivot and the neck point")
    action = FapAction("jaw", params=params)
    return action, rig.deform(None, {k: value * x for k, x in params.items()})


def _jaw_transforms(rig: MuscleRig, n: int, signs, unit: float) -> list:
    parts = [p for p in _JAW_PARTS if p in rig.head.parts]
    if not parts:
        return []
    action = rig.actions.get((n, 1)) or rig.actions.get((n, -1))
    if n == 3:
        amount = action.params["jaw"] / unit
        return [FaceDefTransform(p, "rotation", rig.jaw_centre, rig.jaw_axis, amount) for p in parts]
    key = "jaw_thrust" if n == 14 else "jaw_shift"
    per_unit = abs(action.params[key]) / unit
    direction = np.array([0.0, 0.0, 1.0]) if n == 14 else np.array([-1.0, 0.0, 0.0])
    return [FaceDefTransform(p, "translation", amount=direction * per_unit) for p in parts]


def _fit_lid(rig: MuscleRig, n: int, s: int, value: float, unit: float, goal: np.ndarray):
    fap = FAPS[n]
    side = "L" if "_l_" in fap.name else "R"
    lid = "upper" if "_t_" in fap.name else "lower"
    rig_lid = rig.lids[(side, lid)]
    head = rig.head
    g = float(np.linalg.norm(goal))
    axis = goal / g
    key = f"lid_{side}_{lid}"
    p0 = head.fp_position(rig_lid.margin)

    def along(angle):
        return float((head.fp_position(rig_lid.margin, rig.deform(None, {key: angle})) - p0) @ axis)

    # Closing FAPs (19, 20 down; 21, 22 up) close for positive values.
    closing = s
    angle = closing * _solve_scalar(lambda x: along(closing * x), g, 1.4)
    action = FapAction("eyelid", params={key: angle / value})
    return action, rig.deform(None, {key: angle})


def _author_head_turn(rig: MuscleRig, fat: FAT, n: int, unit: float) -> FapFit:
    """Head rotation: the whole head turns about 7.1 (exact), and the skin below the
    upper neck line carries a correction back towards the still shoulders, sampled at
    :data:`_HEAD_BORDERS`."""
    head = rig.head
    axis = FAPS[n].axis_vector
    name = {48: "head_pitch", 49: "head_yaw", 50: "head_roll"}[n]
    samples = {}
    for b in _HEAD_BORDERS:
        if not b:
            continue
        angle = b * unit
        out = {}
        for part, p in head.parts.items():
            w = rig.neck_weight(p.vertices)
            lag = w < 1
            if lag.any():
                d = np.zeros_like(p.vertices)
                # Before the whole head's turn by `angle`, pull each vertex back by (w - 1) angle.
                d[lag] = _rotate(p.vertices[lag], rig.head_centre, axis, (w[lag] - 1.0) * angle) - p.vertices[lag]
                out[part] = d
        samples[b] = out
    transform = FaceDefTransform(None, "rotation", rig.head_centre, axis, 1.0)
    fat.add(_table(head, n, samples, unit, transforms=[transform]))
    for s in (-1, 1):
        rig.actions[(n, s)] = FapAction("neck", params={name: s * unit})
    return FapFit(n, "neck")


def _load_high_level() -> dict:
    data = tomllib.loads(resources.files("fmc").joinpath("data/high_level_faps.toml").read_text())
    out = {}
    for kind, fap in (("visemes", 1), ("expressions", 2)):
        for key, values in data[kind].items():
            out[(fap, int(key))] = {int(n): float(v) for n, v in values.items()}
    return out


#: (1, viseme) / (2, expression) → low-level FAP → value at full intensity (63), from
#: ``fmc/data/high_level_faps.toml``.
HIGH_LEVEL_FAPS = _load_high_level()


def author_high_level_from_muscles(rig: MuscleRig) -> FAT:
    """FaceDefTables for the 15 visemes and 7 expressions (neutral included): the model
    evaluated on each one's FAP combination (:data:`HIGH_LEVEL_FAPS`) in one state, so
    the combination rule acts across the FAPs; intensity 63 gives the full pose.

    ``rig`` must carry its FAP mapping (run :func:`author_from_muscles` with it first).
    """
    if not rig.actions:
        raise InputError("the muscle model has no FAP mapping yet", fix="run author_from_muscles(head, rig=rig) first")
    head = rig.head
    neutral = {n: p.vertices for n, p in head.parts.items()}
    fat = FAT()
    for (fap, k), values in HIGH_LEVEL_FAPS.items():
        if values:
            moved = rig.deform_faps(values)
            fat.add(_table(head, fap, {63.0: _diff(moved, neutral)}, HIGH_LEVEL_UNIT, high_level=k))
        else:
            fat.add(FaceDefTable(fap, k))
    return fat

