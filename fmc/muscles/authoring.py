"""Facial Animation Tables authored from the muscle rig.

:func:`author_from_muscles` fits, for each low-level FAP, the contractions and angles that
move its feature point by the FAP's unit along its axis; :func:`author_high_level_from_muscles`
the visemes and expressions from ``fmc/data/high_level_faps.toml``.
"""

from __future__ import annotations

import tomllib
from importlib import resources

import numpy as np
from scipy.optimize import brentq, nnls

from fmc.author import JAW_FAPS, FapFit, _falloff, _special, unfold_report, unrelated
from fmc.bound import bound_tables
from fmc.lip_contours import share_lips
from fmc.puff import PUFF_FAPS, puff_field
from fmc.separate import separate_tables
from mpeg4.catalogue import FAPS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.fat import FAT, HIGH_LEVEL_UNIT, FaceDefMesh, FaceDefTable, FaceDefTransform, fap_unit
from mpeg4.head import Head

from .rig import _JAW_PARTS, _LIDS, FapAction, MuscleRig, _rotate

__all__ = ["author_from_muscles", "HIGH_LEVEL_FAPS", "author_high_level_from_muscles"]

# FAPs the model has no muscle for: the local displacement field of fmc.author moves them
# (the cheek puffs the hat of fmc.puff).
_FALLOFF_FAPS = frozenset({16, 17, 39, 40, 43, 44, 45, 46, 63, 64, 65, 66, 67, 68})

# Head rotation tables: sampled at these values (AU) to follow the neck's faded turn.
_HEAD_BORDERS = (-40000.0, -20000.0, -10000.0, 0.0, 10000.0, 20000.0, 40000.0)


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
    """(K, 3) motion of the feature points ``ids`` from ``neutral`` to ``moved``, metres.

    Both states map part → (N, 3) vertices, as :meth:`MuscleRig.deform` gives them.
    Not :func:`fmc.mesh_tables.fp_motion`: that takes a sparse displacement, and the
    states' difference made into one rounds otherwise (within 1e-17 m), which the
    contractions' scaling (:func:`_fit_muscles`) would carry into the tables.
    """
    return np.array([head.fp_position(i, moved) - head.fp_position(i, neutral) for i in ids])


def _diff(moved: dict, neutral: dict) -> dict:
    return {p: moved[p] - neutral[p] for p in moved if np.abs(moved[p] - neutral[p]).max(initial=0) > 0}


def author_from_muscles(head: Head, value: float = 512.0, tol: float = 0.10, leak_tol: float = 0.20,
                        faps=None, rig: MuscleRig | None = None, separate: bool = True,
                        unfold: bool = True, bound: bool = True) -> tuple[FAT, list[FapFit]]:
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
    separate, unfold, bound : bool
        The steps after the model, as in :func:`fmc.author.author_from_shapes`: each table
        leaves the other FAPs' points, is relaxed where it folds, and its skin is capped;
        all False keep the model's motion as it is.

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
                # The cheek puffs: the smooth hat of fmc.puff (a falloff bump this large folds).
                disp = puff_field(head, fp_id, goal) if n in PUFF_FAPS else _falloff(head, fp_id, goal)
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
    # A muscle moves the whole lip: the lip FAPs share it (fmc.lip_contours); and other FAPs'
    # points: each table leaves them (fmc.separate).
    fat = share_lips(head, fat)
    fat = separate_tables(head, fat, keep=JAW_FAPS) if separate else fat
    fat = unfold_report(head, fat, report) if unfold else fat
    return (bound_tables(head, fat, keep=JAW_FAPS) if bound else fat), report


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
    """:data:`HIGH_LEVEL_FAPS` read from ``fmc/data/high_level_faps.toml``; not
    :func:`fmc.high_level._load_high_level`, which reads shapes' weights from another file."""
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
