"""The head's parts found by the feature points and the mesh's connectivity (:func:`find_parts`).

The eyes are the pieces the pupils' rays hit; teeth, gums and tongue the pieces nearest the
generic head's, brought onto the mesh by the face's points. A person may name any part
instead (:func:`given_parts`, ``--part ROLE=PART``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial import cKDTree

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import FeaturePointBinding, Head
from mpeg4.io.fdp_json import PartSource

from .lift import Hit, _pieces

__all__ = ["find_parts", "given_parts", "check_given_parts", "parse_part_options", "MOUTH_ROLES", "MOUTH_MATCH_ES0"]

#: The parts inside the mouth, named as the generic head names them.
MOUTH_ROLES = ("teeth_upper", "teeth_lower", "gums_upper", "gums_lower", "tongue")

#: A piece inside the mouth takes the role of the generic head's part nearest to it when
#: its vertices lie, by their median, within this share of the eye separation (ES0) of
#: that part (the generic head brought onto the mesh by the face's points): about 7 mm on
#: an adult. Teeth, gums and tongue lie 5-15 mm apart; a throat, a mouth bag or hair lies
#: further from all of them and keeps its own name.
MOUTH_MATCH_ES0 = 0.11

# Face points that place the generic head's mouth on a mesh: around the mouth and nose.
_MOUTH_FRAME_GROUPS = (2, 8, 9)


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
    - ``teeth_upper``/``teeth_lower``/``gums_upper``/``gums_lower``/``tongue``: each of the
      other pieces that lies, by the median of its vertices, within
      :data:`MOUTH_MATCH_ES0` of the eye separation of the generic head's part of that name
      (the generic head brought onto the mesh by its points around the mouth and nose);
      the pieces near none (a throat, a mouth bag, hair, lashes) keep their file's names.

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
    for role, keys in _mouth_roles(head, hits, pieces, [k for k in all_keys if k not in taken]).items():
        roles[role] = keys
        taken.update(keys)
    # Whole file parts where a role has all of a part's pieces; vertex lists otherwise.
    out: dict[str, PartSource] = {}
    for role in ("skin", "eye_l", "eye_r") + MOUTH_ROLES:
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


def parse_part_options(options) -> dict[str, str | None]:
    """``--part ROLE=PART`` options as role → the file's part (None for ``ROLE=`` or
    ``ROLE=none``: no part has that role).

    Raises
    ------
    InputError
        An option without ``=``, a role that is no head part's name, a role given twice.
    """
    from mpeg4.head import PART_NAMES

    out: dict[str, str | None] = {}
    for opt in options or ():
        role, eq, name = str(opt).partition("=")
        role, name = role.strip(), name.strip()
        if not eq or not role:
            raise InputError(f"--part {opt!r} is not ROLE=PART", where="--part",
                             fix="e.g. --part teeth_upper=UpperTeeth (the file's part), or --part tongue=none")
        if role not in PART_NAMES:
            raise InputError(f"--part {opt!r}: {role!r} is not a part's role", where="--part",
                             fix=f"use one of {', '.join(PART_NAMES)}")
        if role in out:
            raise InputError(f"--part gives the role {role!r} twice", where="--part", fix="give each role once")
        out[role] = None if name.lower() in ("", "none") else name
    return out


def check_given_parts(head: Head, given: Mapping[str, str | None]) -> None:
    """Refuse given roles (:func:`parse_part_options`) that name a part the mesh ``head``
    (as the file has it) does not have, or one part for two roles."""
    names = [n for n in given.values() if n is not None]
    for role, name in given.items():
        if name is not None and name not in head.parts:
            raise InputError(f"--part {role}={name}: the mesh has no part {name!r}", where="--part",
                             fix=f"its parts are {', '.join(sorted(head.parts))}")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"--part gives the part {twice[0]!r} two roles", where="--part", fix="give each part one role")


def given_parts(head: Head, found: Mapping[str, PartSource], notes: list[str],
                given: Mapping[str, str | None]) -> tuple[dict[str, PartSource], list[str]]:
    """The parts :func:`find_parts` found, with the roles a person gave put in their place.

    Parameters
    ----------
    head : Head
        The mesh in the neutral frame with the file's part names (as :func:`find_parts` had it).
    found, notes : what :func:`find_parts` returned.
    given : mapping of str to str or None
        Role → the file's part that takes it whole (:func:`parse_part_options`); None: no
        part takes the role. A file part given a role is taken from any other role.

    Raises
    ------
    InputError
        A part the file does not have; one part given two roles.
    """
    check_given_parts(head, given)
    names = [n for n in given.values() if n is not None]
    out = {r: p for r, p in found.items() if r not in given and p.source not in names}
    kept = [n for n in notes if n.split(":")[0] in out]
    for role, name in given.items():
        if name is None:
            kept.append(f"{role}: none (given)")
            continue
        centre = _sphere_centre(head.parts[name].vertices) if role.startswith("eye_") else None
        out[role] = PartSource(name, None, centre)
        kept.append(f"{role}: part '{name}' (given)")
    if "skin" not in out:
        raise InputError("no part is the skin", where="--part",
                         fix="give the face's part as the skin: --part skin=PART")
    # The skin first, as find_parts orders them.
    return {"skin": out.pop("skin"), **out}, kept


def _mouth_roles(head: Head, hits: Mapping[str, Hit], pieces: Mapping[str, np.ndarray],
                 candidates: list[tuple[str, int]]) -> dict[str, list[tuple[str, int]]]:
    """Teeth, gums and tongue among ``candidates`` (file part, piece label): each piece takes
    the role of the generic head's mouth part nearest to it (:data:`MOUTH_ROLES`), the
    generic head brought onto the mesh by the similarity that best fits its feature points
    around the mouth and nose to the points found; a piece nearer none of them than
    :data:`MOUTH_MATCH_ES0` of the eye separation takes no role (a throat, hair, a body)."""
    from mpeg4.generic_head import load_generic_head
    from recon.shape.deform import fit_similarity

    generic = load_generic_head()
    gp = generic.fp_positions()
    ids = [i for i, h in hits.items() if i in gp and FEATURE_POINTS[i].group in _MOUTH_FRAME_GROUPS
           and h.how != "generic" and h.confidence > 0]
    if len(ids) < 6 or not candidates:
        return {}
    sim = fit_similarity(np.array([gp[i] for i in ids]), np.array([hits[i].point for i in ids]))
    es0 = sim.scale * float(np.linalg.norm(gp["3.5"] - gp["3.6"]))
    refs = [(role, cKDTree(sim(generic.parts[role].vertices))) for role in MOUTH_ROLES if role in generic.parts]
    out: dict[str, list[tuple[str, int]]] = {}
    for key in candidates:
        n, k = key
        v = head.parts[n].vertices[pieces[n] == k]
        # A piece much bigger than the mouth (a body, a hair cap) cannot be inside it.
        if np.ptp(v, axis=0).max() > 2.5 * es0:
            continue
        near = [(float(np.median(tree.query(v)[0])), role) for role, tree in refs]
        d, role = min(near)
        if d <= MOUTH_MATCH_ES0 * es0:
            out.setdefault(role, []).append(key)
    return out


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
