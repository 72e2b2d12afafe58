"""3D feature points from a front photo alone: the identity model fitted to its points.

A front photo gives each point's x and y but no depth. :func:`fit_front` finds the
identity (:mod:`recon.shape.identity`) and the camera that best explain the marked pixels,
the coefficients kept plausible by their prior (maximum a posteriori: each point's pixel
error over its expected spread, plus the squared coefficients, which are standard
deviations), alternating between the camera (:func:`recon.texture.cameras.fit_camera` on
the current identity's points) and a Gauss–Newton step of the coefficients with the camera
fixed [1]_. The head is then the model's head at the fitted coefficients, and each point the
photo shows is moved across the line of sight onto its marked pixel, keeping the model's
depth: the same 3D points the two-photo calibration gives, for the same DFFD.

Without a focal length the camera is chosen among a pinhole at several 35 mm-equivalent
focal lengths and an orthographic one, by the posterior's cost: the nose and the face's
sides sit at different distances, and a close camera magnifies the nose against them.

References
----------
.. [1] V. Blanz, T. Vetter, "A morphable model for the synthesis of 3D faces", SIGGRAPH
   (1999), section 4 (fitting with a prior on the coefficients).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import Head

from recon.photos import FILM_DIAGONAL_MM

from .calibrate import DEFAULT_IPD_MM
from .core_points import is_core
from .identity import POINT_SD_MM, IdentityModel, load_identity_model

__all__ = ["FrontFit", "fit_front", "FOCAL_35MM_CANDIDATES", "OUTLIER_SDS"]

#: 35 mm-equivalent focal lengths tried when the photo's focal length is unknown (mm; the
#: sensor's diagonal 43.3 mm), besides an orthographic camera.
FOCAL_35MM_CANDIDATES = (24.0, 28.0, 35.0, 50.0, 85.0, 135.0)

#: A detected point the fitted face misses by more than this many spreads is left out.
OUTLIER_SDS = 4.0

_ROUNDS = 10
_STEP = 1e-4  # metres, for the projection's derivatives


@dataclass
class FrontFit:
    """The identity model fitted to a front photo.

    Attributes
    ----------
    head : Head
        The model's head at the fitted coefficients, sized to the interpupillary distance.
    points : dict of str to (3,) float64
        FP id → 3D position, metres (the head's frame): the model's, moved onto the
        marked pixel across the line of sight for the points the photo shows.
    source : dict of str to str
        FP id → ``"front"`` (x, y from the photo, depth from the model) or ``"model"``.
    coefficients : (K,) float64
        Standard deviations of each mode.
    camera : recon.texture.cameras.FittedCamera
        The front photo's camera for ``head``.
    focal_px : float or None
        The focal length used (None: orthographic).
    focal_from : str
        ``"given"``, or ``"estimated"`` (chosen by the fit), or ``"orthographic"``.
    rms_px : float
        Root-mean-square pixel error of the fitted model's points before they were moved.
    cost : float
        The posterior's cost at the solution (lower is better; compares cameras).
    candidates : dict
        Focal length tried (35 mm-equivalent mm, or ``"orthographic"``) → cost over every
        point, each camera's stray points (left out of its fit) counting
        :data:`OUTLIER_SDS` squared (a truncated quadratic).
    dropped : dict of str to dict
        Detected points left out because the fitted face missed them by more than
        :data:`OUTLIER_SDS` times their spread (their place is the model's): FP id →
        ``{"view": "front", "miss_mm": float}``, the record the two-photo route keeps
        (:attr:`recon.shape.calibrate.Calibration.dropped`).
    """

    head: Head
    points: dict[str, np.ndarray]
    source: dict[str, str]
    coefficients: np.ndarray
    camera: object
    focal_px: float | None
    focal_from: str
    rms_px: float
    cost: float
    candidates: dict = field(default_factory=dict)
    dropped: dict = field(default_factory=dict)


def _usable(front: Mapping, head: Head) -> list[str]:
    return [i for i in front if i in head.feature_points and FEATURE_POINTS[i].front != "N"]


def _projection_jacobian(cam, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (n, 2) of X (n, 3) and their derivatives (n, 2, 3) per metre."""
    p0 = cam.project(X)
    J = np.empty((len(X), 2, 3))
    for a in range(3):
        d = np.zeros(3)
        d[a] = _STEP
        J[:, :, a] = (cam.project(X + d) - p0) / _STEP
    return p0, J


class _Fit(NamedTuple):
    """One camera setting's fit: coefficients, camera, the model's points and those moved
    onto their pixels, the RMS pixel error, the posterior's cost, each point's miss (mm)."""

    coefficients: np.ndarray
    camera: object
    points: np.ndarray
    moved: np.ndarray
    rms_px: float
    cost: float
    residual_mm: np.ndarray


def _fit_one(front, ids, weights, generic, model, width, height, focal_px, point_sd_mm, where) -> _Fit:
    from recon.texture.cameras import fit_camera

    pixels = {i: np.asarray(front[i], float) for i in ids}
    u = np.array([pixels[i] for i in ids])
    X0 = np.array([generic.fp_position(i) for i in ids])
    B = model.point_basis(generic, ids)
    c = np.zeros(model.n_modes)
    for k in range(_ROUNDS + 1):
        # The camera for the current identity, and the projection linearised about it.
        X = X0 + B @ c
        cam = fit_camera(dict(zip(ids, X)), pixels, width, height, focal_px=focal_px, where=where)
        p, J = _projection_jacobian(cam.camera, X)
        px_per_m = float(np.median(np.linalg.norm(J[:, 0], axis=1)))
        w = weights / (point_sd_mm * 1e-3 * px_per_m) ** 2
        r = u - p
        if k == _ROUNDS or (k and np.abs(step).max() < 1e-4):
            break
        A = np.einsum("nij,njk->nik", J, B)  # (n, 2, K)
        H = np.einsum("nik,nil,n->kl", A, A, w) + np.eye(len(c))
        g = np.einsum("nik,ni,n->k", A, r, w) - c
        step = np.linalg.solve(H, g)
        c = c + step
    cost = float(np.sum(w * np.sum(r ** 2, axis=1)) + c @ c)
    # Each marked point moved across the line of sight onto its pixel (least-norm move).
    moves = np.einsum("nij,nj->ni", np.linalg.pinv(J), r)
    return _Fit(c, cam, X, X + moves, float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))), cost,
                np.linalg.norm(r, axis=1) / px_per_m * 1e3)


def fit_front(front: Mapping[str, np.ndarray], width: int, height: int, generic: Head | None = None,
              model: IdentityModel | None = None, ipd_mm: float = DEFAULT_IPD_MM, focal_px: float | None = None,
              estimate_focal: bool = True, confidence: Mapping[str, float] | None = None,
              point_sd_mm: float = POINT_SD_MM, drop_outliers: bool = False, where: str = "front photo",
              under_hair: Collection[str] = ()) -> FrontFit:
    """Fit the identity model to the points marked on a front photo.

    Parameters
    ----------
    front : mapping of str to (2,) float
        FP id → pixel (x right, y down) on the front photo.
    width, height : int
        The photo's size, pixels.
    generic : Head, optional
        The head the model's modes displace (the shipped generic head by default).
    model : IdentityModel, optional
        The shipped model by default.
    ipd_mm : float
        The pupils' distance the head is sized to (photos carry no scale).
    focal_px : float, optional
        The photo's focal length, pixels. Without it, see ``estimate_focal``.
    estimate_focal : bool
        Without ``focal_px``: choose among :data:`FOCAL_35MM_CANDIDATES` and an
        orthographic camera by the fit's cost (True), or take an orthographic camera.
    confidence : mapping of str to float, optional
        Per point in (0, 1]: weights (detected points carry them).
    point_sd_mm : float
        See :data:`recon.shape.identity.POINT_SD_MM`.
    drop_outliers : bool
        Leave out, one at a time and the worst first, points the fit misses by more than
        :data:`OUTLIER_SDS` spreads (weighted by their confidence), except the face's core
        (eyes, nose, mouth, chin): for detected points nobody has checked. Each camera
        setting leaves out its own, and the settings are compared by a truncated cost over
        every point, so that the focal length is chosen by the face, not by a stray point.
    under_hair : collection of str
        Skull points (:data:`recon.shape.hair.UNDER_HAIR`) whose marked place is the
        hair's outline: left out of the fit, then placed under it
        (:func:`recon.shape.hair.skull_offset`; source ``"under hair"``).

    Returns
    -------
    FrontFit
    """
    if generic is None:
        from mpeg4.generic_head import load_generic_head

        generic = load_generic_head()
    model = load_identity_model() if model is None else model
    model.check(generic)
    ids = _usable(front, generic)
    hair = [i for i in ids if i in set(under_hair)]
    ids = [i for i in ids if i not in hair]
    if len(ids) < 8:
        raise InputError(f"only {len(ids)} feature points are marked on the front photo; the identity model needs "
                         f"at least 8 spread over the face", where=where,
                         fix="mark the eyes, nose, mouth and chin (recon annotate), or detect them")
    for i in ("3.5", "3.6"):
        if i not in ids:
            raise InputError(f"feature point {i} (a pupil) is not marked on the front photo", where=where,
                             fix="mark both pupils: they set the head's size")
    conf = confidence or {}
    weights = np.array([max(float(conf.get(i, 1.0)), 0.05) for i in ids])
    diag = float(np.hypot(width, height))
    tries = {}
    if focal_px is not None:
        tries["given"] = float(focal_px)
    else:
        tries["orthographic"] = None
        if estimate_focal:
            tries.update({f"{mm:g}": mm / FILM_DIAGONAL_MM * diag for mm in FOCAL_35MM_CANDIDATES})
    # Each camera setting fitted with its own stray points left out, the settings compared by
    # a truncated cost over every point (a point left out counts as OUTLIER_SDS² spreads): a
    # stray point's miss outweighs what tells one focal length from another, and a point one
    # camera explains (a hairline in a close selfie) need not be stray under another.
    runs = {}
    for key, f in tries.items():
        try:
            runs[key] = _robust_fit(front, ids, weights, generic, model, width, height, f, point_sd_mm, where,
                                    drop_outliers)
        except InputError:
            if len(tries) == 1:
                raise
    if not runs:
        raise InputError("no camera explains the points marked on the front photo", where=where,
                         fix="check the points' labels (recon annotate)")
    score = {key: r[0].cost + OUTLIER_SDS ** 2 * len(r[2]) for key, r in runs.items()}
    best = min(score, key=score.get)
    fit, ids, dropped = runs[best]
    c, cam, _, moved, rms, cost, _ = fit
    head = model.head(generic, c)
    pts = head.fp_positions()
    pos = {i: pts[i] for i in head.feature_points}
    source = {i: "model" for i in pos}
    for i, m in zip(ids, moved):
        pos[i], source[i] = m, "front"
    for i, p in _under_hair(front, hair, pos, cam.camera, generic).items():
        pos[i], source[i] = p, "under hair"
    # Photos carry no scale: the pupils' distance sets it.
    k = ipd_mm * 1e-3 / float(np.linalg.norm(pos["3.5"] - pos["3.6"]))
    head = head.with_vertices({n: p.vertices * k for n, p in head.parts.items()})
    for part in head.parts.values():
        if part.centre is not None:
            part.centre = part.centre * k
    pos = {i: p * k for i, p in pos.items()}
    cam = _scaled_camera(cam, k)
    focal = tries[best]
    focal_from = "given" if best == "given" else ("orthographic" if focal is None else "estimated")
    return FrontFit(head, pos, source, c, cam, focal, focal_from, rms, cost,
                    {key: round(v, 2) for key, v in score.items()}, dropped)


def _robust_fit(front, ids, weights, generic, model, width, height, focal_px, point_sd_mm, where, drop: bool
                ) -> tuple[_Fit, list, dict]:
    """:func:`_fit_one` for one camera setting, and with ``drop`` the points it misses by more
    than :data:`OUTLIER_SDS` spreads left out one at a time, the worst first (never the face's
    core): (fit, ids kept, FP id → record of each point left out)."""
    fit = _fit_one(front, ids, weights, generic, model, width, height, focal_px, point_sd_mm, where)
    dropped = {}
    while drop:
        # A detected point the fitted face misses by far more than its spread is a
        # detection gone astray (a busy background, hair over the ear): pinning the head
        # to it would dent the head, so the model's place for it is kept.
        res = fit.residual_mm
        free = [k for k, i in enumerate(ids) if not is_core(i)]
        worst = max(free, key=lambda k: res[k] * np.sqrt(weights[k]), default=None)
        if worst is None or res[worst] * np.sqrt(weights[worst]) <= OUTLIER_SDS * point_sd_mm or len(ids) <= 8:
            break
        dropped[ids[worst]] = {"view": "front", "miss_mm": round(float(res[worst]), 1)}
        ids, weights = ids[:worst] + ids[worst + 1:], np.delete(weights, worst)
        fit = _fit_one(front, ids, weights, generic, model, width, height, focal_px, point_sd_mm, where)
    return fit, ids, dropped


def _under_hair(front: Mapping, ids: list[str], pos: dict, camera, generic: Head) -> dict[str, np.ndarray]:
    """The skull points ``ids`` under the hair whose outline the photo shows at their marked
    pixels: the fitted model's point, moved across the line of sight as the others are, but
    along the skull's normal only by what hair cannot explain (:mod:`recon.shape.hair`)."""
    from .hair import skull_normals, skull_under

    normals = skull_normals(generic)
    out = {}
    for i in ids:
        if i not in normals:
            continue
        x = pos[i]
        p, J = _projection_jacobian(camera, x[None])
        move = np.linalg.pinv(J[0]) @ (np.asarray(front[i], float) - p[0])
        out[i] = skull_under(x, x + move, normals[i])
    return out


def _scaled_camera(fitted, k: float):
    """The camera that sees the head scaled by ``k`` about the origin as ``fitted`` saw it."""
    from mpeg4.camera import Camera
    from recon.texture.cameras import FittedCamera

    c = fitted.camera
    if c.perspective:
        cam = Camera(c.width, c.height, c.rotation, c.centre * k, focal_px=c.focal_px, principal=c.principal,
                     near=c.near, far=c.far)
    else:
        cam = Camera(c.width, c.height, c.rotation, c.centre * k, scale_px=c.scale_px / k, principal=c.principal,
                     near=c.near, far=c.far)
    return FittedCamera(cam, dict(fitted.residual_px))
