"""How a head's lids sit on its eyes: the opening a front view shows, and lids in the eyeball.

- :func:`visible_opening`: the height of eyeball a front view sees between the lids, on
  the vertical line through the pupil (rays cast along -z against the skin and the
  eyeball), mm. Unlike the lid margins' feature points, which the deformation pins, this
  is what a render shows: a margin pulled into the eyeball leaves the eye looking open.
- :func:`lid_penetration`: how deep the lids' outer surface (skin near the eye facing away
  from the eyeball's centre) goes into the eyeball mesh, mm; 0 when the lids lie on it.

``benchmarks/neutral_lids.py`` and the tests use them on heads built from synthetic photos
whose lids were posed before they were photographed.
"""

from __future__ import annotations

import numpy as np

from mpeg4.head import Head

__all__ = ["EYE_PARTS", "first_hits", "visible_opening", "lid_penetration"]

#: Per eye: its part and its pupil's feature point.
EYE_PARTS = {"left": ("eye_l", "3.5"), "right": ("eye_r", "3.6")}


def first_hits(vertices: np.ndarray, triangles: np.ndarray, x: float, ys: np.ndarray) -> np.ndarray:
    """(Y,) z of the frontmost surface met by rays along -z through (x, y) for each of ``ys``
    (metres); -inf where a ray meets nothing.

    Parameters
    ----------
    vertices : (N, 3) float
    triangles : (M, 3) int
    x : float
    ys : (Y,) float
    """
    ys = np.asarray(ys, dtype=np.float64)
    t = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles)]
    near = ((t[:, :, 0].min(axis=1) <= x) & (t[:, :, 0].max(axis=1) >= x)
            & (t[:, :, 1].max(axis=1) >= ys.min()) & (t[:, :, 1].min(axis=1) <= ys.max()))
    t = t[near]
    a = t[:, 0, :2]
    e1, e2 = (t[:, 1, :2] - a)[None], (t[:, 2, :2] - a)[None]
    q = np.stack([np.full_like(ys, x), ys], axis=1)[:, None] - a[None]
    det = e1[..., 0] * e2[..., 1] - e2[..., 0] * e1[..., 1]
    det = np.where(np.abs(det) < 1e-18, np.nan, det)  # triangles seen edge-on hold no ray
    u = (q[..., 0] * e2[..., 1] - e2[..., 0] * q[..., 1]) / det
    v = (e1[..., 0] * q[..., 1] - q[..., 0] * e1[..., 1]) / det
    inside = (u >= 0) & (v >= 0) & (u + v <= 1)
    z = (1 - u - v) * t[None, :, 0, 2] + u * t[None, :, 1, 2] + v * t[None, :, 2, 2]
    z = np.where(inside, z, -np.inf)
    return z.max(axis=1) if z.shape[1] else np.full(len(ys), -np.inf)


def visible_opening(head: Head, eye: str = "left", step: float = 2e-5, reach: float = 0.012) -> float:
    """The eyeball's visible height through the lids on the vertical line through the pupil,
    from the front, mm (the pupil itself may be hidden, under a low lid).

    Parameters
    ----------
    head : Head
        With ``skin``, the eye's part and its pupil point.
    eye : {"left", "right"}
    step : float
        Ray spacing, metres.
    reach : float
        How far above and below the pupil rays are cast, metres.
    """
    part, pupil_id = EYE_PARTS[eye]
    pupil = head.fp_position(pupil_id)
    ys = pupil[1] + np.arange(-reach, reach + step / 2, step)
    ball = head.parts[part]
    seen = first_hits(ball.vertices, ball.triangles, pupil[0], ys) > \
        first_hits(head.skin.vertices, head.skin.triangles, pupil[0], ys)
    return 1e3 * float(seen.sum() * step)


def lid_penetration(head: Head, eye: str = "left", radius: float = 0.02) -> float:
    """How far the lids' outer surface goes into the eyeball, mm (0 when it stays outside).

    The outer surface: skin vertices within ``radius`` (metres) of the eye's centre whose
    normal points away from it (cosine over 0.2; the lids' inner side and the socket
    behind the eyeball touch it by construction and are not counted). Depth inside the
    eyeball mesh by :func:`trimesh.proximity.signed_distance`.
    """
    import trimesh

    from mpeg4.render import vertex_normals

    part = head.parts[EYE_PARTS[eye][0]]
    centre = part.centre if part.centre is not None else part.vertices.mean(axis=0)
    skin = head.skin
    near = np.flatnonzero(np.linalg.norm(skin.vertices - centre, axis=1) < radius)
    radial = skin.vertices[near] - centre
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    outer = near[(vertex_normals(skin.vertices, skin.triangles)[near] * radial).sum(axis=1) > 0.2]
    if not len(outer):
        return 0.0
    ball = trimesh.Trimesh(part.vertices, part.triangles, process=False)
    depth = trimesh.proximity.signed_distance(ball, skin.vertices[outer])  # positive inside
    return 1e3 * max(float(depth.max()), 0.0)
