"""The muscle rig: muscles plus the parametric jaw, eyelids, eyeballs and neck.

:class:`MuscleRig` deforms a head by muscle contractions and the parametric layer's angles;
:func:`split_lips` separates the lips, :func:`eyeball_centre` finds an eye's rotation centre.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull

from fmc.author import JAW_PARTS
from mpeg4.catalogue import FAPS
from mpeg4.errors import InputError
from mpeg4.fat import FAT, fap_unit
from mpeg4.head import Head
from mpeg4.surface import edge_graph

from .placement import GROUPS, Muscle, _point, load_placement, place_muscles

__all__ = ["split_lips", "eyeball_centre", "FapAction", "MuscleRig"]

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
_JAW_PARTS = JAW_PARTS  # the parts the jaw carries, as the shapes route has them


def _edge_graph(part) -> sp.csr_matrix:
    """The mesh's edges weighted by length, with copies of one vertex (a texture seam stores
    a vertex once per side) joined, so that distances run across seams."""
    return edge_graph(part.vertices, part.triangles)


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
