"""The head's parts found by the feature points and the mesh's connectivity (:func:`find_parts`).

The eyes are the pieces the pupils' rays hit; teeth and tongue the pieces inside the mouth.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import FeaturePointBinding, Head
from mpeg4.io.fdp_json import PartSource

from .lift import Hit, _pieces

__all__ = ["find_parts"]


def _sphere_centre(points: np.ndarray) -> np.ndarray:
    """Centre of the least-squares sphere through (K, 3) points."""
    a = np.c_[2 * points, np.ones(len(points))]
    b = np.sum(points ** 2, axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    return sol[:3]


def find_parts(head: Head, hits: Mapping[str, Hit]) -> tuple[dict[str, PartSource], list[str]]:
    """The head's parts in a mesh: skin, eyes, teeth and tongue, by the points and connectivity.

    - the skin: the piece most face points lie on (with everything in its part that no
      other role takes);
    - ``eye_l``/``eye_r``: the piece each pupil's ray hits, when it is not the skin, and the
      pieces inside it; centred on the sphere fitted to the largest;
    - ``teeth_upper``/``teeth_lower``/``tongue``: the pieces inside the mouth (between the
      mouth corners, from the nose base to the chin, behind the lips), above and below the
      mouth line; the tongue is the piece below that is longest front to back for its width.

    Parameters
    ----------
    head : Head
        In the neutral frame, with the file's parts.
    hits : mapping of str to Hit
        Points on it (:func:`lift`).

    Returns
    -------
    parts : dict of str to PartSource
        Role → where it comes from (skin first).
    notes : list of str
    """
    pieces = {n: _pieces(p) for n, p in head.parts.items()}
    roles: dict[str, list[tuple[str, int]]] = {}
    notes = []
    face = [h for i, h in hits.items() if FEATURE_POINTS[i].group in (2, 4, 5, 8, 9, 11) and h.how != "generic"]
    if not face:
        raise InputError("no feature point landed on the surface", fix="check the mesh is a head facing the viewer")
    votes: dict[tuple[str, int], int] = {}
    for h in face:
        key = (h.part, int(pieces[h.part][head.parts[h.part].triangles[h.triangle][0]]))
        votes[key] = votes.get(key, 0) + 1
    skin = max(votes, key=votes.get)
    taken = {skin}

    def bbox(key):
        n, k = key
        v = head.parts[n].vertices[pieces[n] == k]
        return v.min(axis=0), v.max(axis=0)

    all_keys = [(n, int(k)) for n, lab in pieces.items() for k in np.unique(lab)]
    for role, fp in (("eye_l", "3.5"), ("eye_r", "3.6")):
        h = hits.get(fp)
        if h is None:
            continue
        key = (h.part, int(pieces[h.part][head.parts[h.part].triangles[h.triangle][0]]))
        if key in taken:
            continue
        lo, hi = bbox(key)
        inside = [k for k in all_keys if k not in taken and k != key
                  and (bbox(k)[0] >= lo - 1e-3).all() and (bbox(k)[1] <= hi + 1e-3).all()]
        roles[role] = [key] + inside
        taken.update(roles[role])
    need = ("8.3", "8.4", "9.15", "2.1")
    if all(i in hits for i in need):
        ml, mr = hits["8.3"].point, hits["8.4"].point
        half = 0.75 * abs(ml[0] - mr[0])
        top, bottom = hits["9.15"].point[1], hits["2.1"].point[1]
        lips = max(ml[2], mr[2]) + 0.01
        line = np.mean([hits[i].point[1] for i in ("2.2", "2.3", "8.3", "8.4") if i in hits])
        upper, lower = [], []
        for k in all_keys:
            if k in taken:
                continue
            lo, hi = bbox(k)
            c = 0.5 * (lo + hi)
            ext = hi - lo
            if (abs(c[0]) < half and bottom < c[1] < top and c[2] < lips and ext[0] < 2.5 * half
                    and ext[1] < (top - bottom)):
                (upper if c[1] > line else lower).append(k)
        tongue = None
        if len(lower) >= 2:
            def shape(k):
                lo, hi = bbox(k)
                e = hi - lo
                return abs(0.5 * (lo + hi)[0]), e[2] / max(e[0], 1e-9), float(np.prod(e))
            # On the midline, longer front to back than wide, the biggest such piece.
            midline = [k for k in lower if shape(k)[0] < 0.003 and shape(k)[1] > 1.1]
            if midline:
                tongue = max(midline, key=lambda k: shape(k)[2])
                lower.remove(tongue)
        for role, keys in (("teeth_upper", upper), ("teeth_lower", lower), ("tongue", [tongue] if tongue else [])):
            if keys:
                roles[role] = keys
                taken.update(keys)
    # Whole file parts where a role has all of a part's pieces; vertex lists otherwise.
    out: dict[str, PartSource] = {}
    for role in ("skin", "eye_l", "eye_r", "teeth_upper", "teeth_lower", "tongue"):
        keys = [skin] if role == "skin" else roles.get(role)
        if not keys:
            continue
        names = {n for n, _ in keys}
        if len(names) > 1:  # pieces from several file parts: keep the part with most of them
            n = max(names, key=lambda n: sum(1 for m, _ in keys if m == n))
            keys = [k for k in keys if k[0] == n]
        n = keys[0][0]
        if role == "skin":
            others = [k for r, ks in roles.items() for k in ks if k[0] == n]
            mask = ~np.isin(pieces[n], [k for _, k in others])
        else:
            mask = np.isin(pieces[n], [k for _, k in keys])
        ids = np.flatnonzero(mask)
        centre = None
        if role.startswith("eye_"):
            biggest = max(keys, key=lambda k: int((pieces[k[0]] == k[1]).sum()))
            centre = _sphere_centre(head.parts[n].vertices[pieces[n] == biggest[1]])
        out[role] = PartSource(n, None if len(ids) == head.parts[n].n_vertices else ids, centre)
        notes.append(f"{role}: " + (f"part '{n}'" if len(ids) == head.parts[n].n_vertices
                                    else f"{len(keys) if role != 'skin' else 1} piece(s) of part '{n}' "
                                         f"({len(ids)} vertices)"))
    # A role that would take a whole part another role takes pieces of cannot be: drop it.
    for role in list(out):
        s = out[role]
        if s.vertices is None and any(o.source == s.source for r, o in out.items() if r != role):
            del out[role]
    return out, notes


def _inside_binding(part, point: np.ndarray) -> FeaturePointBinding:
    """An affine combination of four of the part's vertices that is exactly ``point``."""
    from scipy.spatial import cKDTree

    v = part.vertices
    _, near = cKDTree(v).query(point, k=min(64, len(v)))
    near = np.atleast_1d(near)
    # Four vertices spread around the point: the nearest, then the farthest from the span so far.
    chosen = [near[0]]
    for _ in range(3):
        base = v[chosen]
        if len(chosen) == 1:
            score = np.linalg.norm(v[near] - base[0], axis=1)
        else:
            q, _ = np.linalg.qr((base[1:] - base[0]).T)
            d = v[near] - base[0]
            score = np.linalg.norm(d - (d @ q) @ q.T, axis=1)
        chosen.append(near[int(np.argmax(score))])
    a = np.c_[v[chosen], np.ones(4)].T
    w = np.linalg.lstsq(a, np.r_[point, 1.0], rcond=None)[0]
    return FeaturePointBinding(part.name, tuple(int(k) for k in chosen), tuple(float(x) for x in w / w.sum()))
